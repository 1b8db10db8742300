#!/usr/bin/python3
"""Turns the results of benchmarks/paper_table.sh into OUTDIR/paper_table.md (tables like the
paper's Tables 2/3) and the plots OUTDIR/paper_fig5_intermediate.png, paper_fig7_batch.png and
paper_fig9_uncontractible.png (like its Figures 5, 7 and 9).

Usage: paper_table.py RESULTS_DIR OUTDIR --command CMD --sweep "B1 B2 ..." --trace-batches "B1 B2"
                      [--seconds S] [--build-seconds S]
Input files in RESULTS_DIR, per set S, rate R and tool T (written by paper_table.sh):
  sets.txt                      name<TAB>description<TAB>resolution
  S.full.report                 vdb_isosimp --report of the full-resolution run (R = 1)
  S.vdbfull.{out,err}           OpenVDB's volumeToMesh at adaptivity 0 and its distance to ours
  S.R.T.{out,time,err,stats}    tool output (JSON line, or a report for ours), "wall KiB" from
                                /usr/bin/time, mesh_error --json, mesh_stats --json
  S.R.ours.{report,trace}       our report and per-decimation trace (CSV)
  sweep.R.B.{report,trace,err,time}  B sweep on the noise set
"""
import argparse
import csv
import datetime
import json
import os
import platform
import sys

TOOLS = [
    ("ours", "ours (on-the-fly)"),
    ("openmesh", "in-core QSlim (OpenMesh)"),
    ("cascade", "out-of-core cascade"),
    ("meshopt", "meshoptimizer (OpenVDB extraction)"),
    ("meshopt_ours", "meshoptimizer (our extraction)"),
    ("vdbadaptive", "OpenVDB adaptive"),
]
RATES = ["0.2", "0.02"]


def load_json(path):
    with open(path) as f:
        text = f.read().strip()
    return json.loads(text.splitlines()[-1] if text.startswith("{\"tool\"") else text)


def load_time(path):
    with open(path) as f:
        wall, kib = f.read().split()[-2:]
    return float(wall), float(kib) / 1024.0


def load_trace(path):
    with open(path) as f:
        return [{k: int(v) for k, v in row.items()} for row in csv.DictReader(f)]


def fmt_time(s):
    return f"{s:.1f}" if s >= 10 else f"{s:.2f}"


def fmt_pct(p):
    return f"{p:.4f}" if p < 1 else f"{p:.3f}"


def machine():
    cpu = "unknown CPU"
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
        with open("/proc/meminfo") as f:
            mem_gb = int(f.readline().split()[1]) / 1024 / 1024
    except OSError:
        mem_gb = 0
    return f"{cpu}, {os.cpu_count()} cores, {mem_gb:.0f} GB RAM, {platform.system()} {platform.release()}"


def row_for(rd, s, r, tool):
    base = f"{rd}/{s}.{r}.{tool}"
    if not os.path.exists(base + ".err"):
        return None
    wall, rss_time = load_time(base + ".time")
    err = load_json(base + ".err")
    stats = load_json(base + ".stats")
    row = {"wall": wall, "rms": err["a_to_b"]["rms_pct"], "hausdorff": err["hausdorff_pct"],
           "closed": stats["closed"] and stats["manifold"], "stats": stats, "notes": []}
    if tool == "ours":
        rep = load_json(base + ".report")
        row.update(faces=rep["faces_out"], extract=None, simplify=None, rss=rep["peak_rss_mb"],
                   faces_full=rep["faces_full"])
        trace = load_trace(base + ".trace")
        row["notes"].append(f"B = {rep['batch']}, {rep['decimations']} decimations, "
                            f"max {rep['max_intermediate_faces']} faces in memory")
        if rep["faces_out"] > 1.05 * rep["faces_target"]:
            row["notes"].append(f"stopped at {rep['faces_out']} of target {rep['faces_target']}")
        row["trace"] = trace
    else:
        out = load_json(base + ".out")
        row.update(faces=out["faces_out"], extract=out["extract_seconds"], simplify=out["simplify_seconds"],
                   rss=out["peak_rss_mb"], faces_full=out["faces_full"])
        if tool == "cascade":
            row["notes"].append(f"{out['pieces']} pieces (largest {out['largest_piece_faces']} faces), "
                                f"{out['faces_stitched']} faces stitched, {out['disk_bytes'] / 2**20:.0f} MB on disk; "
                                f"peak RSS extract {out['extract_peak_rss_mb']:.0f} / simplify "
                                f"{out['simplify_peak_rss_mb']:.0f} MB")
        if tool == "vdbadaptive":
            row["simplify"] = None
            reach = abs(out["faces_out"] - out["faces_target"]) / out["faces_target"] <= 0.05
            row["notes"].append((f"adaptivity {out['adaptivity']:.4f}" if reach else
                                 f"target {out['faces_target']} out of reach (adaptivity 1)") +
                                f"; {out['runs']} volumeToMesh runs, one run {fmt_time(out['final_run_seconds'])} s")
        if tool.startswith("meshopt") and out["faces_out"] > 1.05 * out["faces_target"]:
            row["notes"].append(f"stopped at {out['faces_out']} of target {out['faces_target']}")
    if not row["closed"]:
        st = stats
        row["notes"].append(f"{st['boundary_edges']} boundary, {st['non_manifold_edges']} non-manifold edges, "
                            f"{st['non_manifold_vertices']} non-manifold vertices")
    return row


def table(rd, sets, r, out):
    out.append(f"\n### R = {r}\n")
    out.append("| set | algorithm | faces | extract s | simplify s | total s | RMS error % | Hausdorff % | "
               "peak RSS MB | closed manifold | ours/this time | ours/this RMS | ours/this RSS | notes |")
    out.append("|---|---|---:|---:|---:|---:|---:|---:|---:|---|---:|---:|---:|---|")
    ratios = {}
    for s, _, _ in sets:
        ours = row_for(rd, s, r, "ours")
        for tool, label in TOOLS:
            row = row_for(rd, s, r, tool)
            if row is None:
                continue
            dash = "—"
            ext = fmt_time(row["extract"]) if row["extract"] is not None else dash
            sim = fmt_time(row["simplify"]) if row["simplify"] is not None else dash
            if tool == "ours" or ours is None:
                rt = rr = rm = dash
            else:
                t, e, m = ours["wall"] / row["wall"], ours["rms"] / row["rms"], ours["rss"] / row["rss"]
                rt, rr, rm = f"{t:.2f}", f"{e:.2f}", f"{m:.2f}"
                if abs(row["faces"] - ours["faces"]) <= 0.05 * ours["faces"]:
                    ratios.setdefault(tool, []).append((s, t, e, m))
                else:  # not the same face count: not comparable, left out of the summary
                    rt, rr, rm = f"({rt})", f"({rr})", f"({rm})"
                    row["notes"].append("face count differs from ours by > 5%: ratios in parentheses not comparable")
            name = f"**{label}**" if tool == "ours" else label
            out.append(f"| {s} | {name} | {row['faces']} | {ext} | {sim} | {fmt_time(row['wall'])} | "
                       f"{fmt_pct(row['rms'])} | {fmt_pct(row['hausdorff'])} | {row['rss']:.0f} | "
                       f"{'yes' if row['closed'] else 'no'} | {rt} | {rr} | {rm} | {'; '.join(row['notes'])} |")
    return ratios


def summary(all_ratios, out):
    out.append("\n## Summary of the ratios (ours / baseline, all sets; < 1 means ours is lower)\n")
    out.append("Only rows with the same face count as ours (within 5%) count.\n")
    out.append("| baseline | R | sets | time ratio | RMS ratio | RSS ratio |")
    out.append("|---|---|---:|---|---|---|")
    labels = dict(TOOLS)
    for tool, _ in TOOLS[1:]:
        for r in RATES:
            v = all_ratios.get(r, {}).get(tool)
            if not v:
                continue
            def rng(i):
                lo, hi = min(x[i] for x in v), max(x[i] for x in v)
                return f"{lo:.2f} – {hi:.2f}"
            out.append(f"| {labels[tool]} | {r} | {len(v)} | {rng(1)} | {rng(2)} | {rng(3)} |")


def plots(rd, outdir, sets, sweep, trace_b):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    files = []
    # Figure 5: intermediate mesh size per decimation, two values of B, same R. The pipeline runs its
    # slabs (trace column "slab") with their own integrators and B/slabs faces per batch, then merges
    # them for a final pass (the last row): one saw-tooth per slab, against faces that slab generated.
    r = "0.1"
    fig, ax = plt.subplots(figsize=(8, 4.5))
    colors = ["tab:blue", "tab:orange", "tab:green", "tab:red"]
    xmax = 0
    peaks = []
    for i, b in enumerate(trace_b):
        p = f"{rd}/sweep.{r}.{b}.trace"
        if not os.path.exists(p):
            continue
        tr = load_trace(p)[:-1]  # the final pass over the merged mesh is not per slab
        slabs = sorted({d.get("slab", 0) for d in tr})
        for j, sl in enumerate(slabs):
            xs, ys = [0], [0]
            for d in (d for d in tr if d.get("slab", 0) == sl):
                xs += [d["faces_generated"], d["faces_generated"]]
                ys += [d["faces_before"], d["faces_after"]]
            xmax = max(xmax, xs[-1])
            ax.plot([x / 1e3 for x in xs], [y / 1e3 for y in ys], lw=0.8, color=colors[i % 4],
                    label=f"B = {b} ({len(slabs)} slabs)" if j == 0 else None)
        rep = load_json(f"{rd}/sweep.{r}.{b}.report")
        peaks.append((b, rep["max_intermediate_faces"], rep["faces_full"]))
    ax.plot([0, xmax / 1e3], [0, float(r) * xmax / 1e3], "k--", lw=0.8, label="R · faces generated")
    ax.set_xlabel("faces generated by the slab so far (thousands)")
    ax.set_ylabel("faces in the slab's mesh (thousands)")
    ax.set_title(f"Intermediate mesh size per decimation, noise set, R = {r} (cf. paper Fig. 5)")
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    files.append("paper_fig5_intermediate.png")
    fig.savefig(os.path.join(outdir, files[-1]), dpi=110)
    plt.close(fig)

    # Figure 7: RMS error and wall time against B for R = 0.1 and 0.01.
    fig, axes = plt.subplots(1, 3, figsize=(13, 4))
    data = {}
    for r in ("0.1", "0.01"):
        rows = []
        for b in sweep:
            p = f"{rd}/sweep.{r}.{b}"
            if os.path.exists(p + ".err"):
                rows.append((int(b), load_json(p + ".err")["a_to_b"]["rms_pct"], load_time(p + ".time")[0]))
        data[r] = rows
    for ax, r, mark in ((axes[0], "0.1", "o-"), (axes[1], "0.01", "s-")):
        ax.plot([x[0] for x in data[r]], [x[1] for x in data[r]], mark, color="tab:blue" if r == "0.1" else "tab:orange")
        ax.set_title(f"RMS error, R = {r}")
        ax.set_ylabel("RMS error (% of bbox diagonal)")
    for r, mark in (("0.1", "o-"), ("0.01", "s-")):
        axes[2].plot([x[0] for x in data[r]], [x[2] for x in data[r]], mark, label=f"R = {r}")
    axes[2].set_title("wall time")
    axes[2].set_ylabel("seconds")
    axes[2].set_ylim(bottom=0)
    axes[2].legend()
    for ax in axes:
        ax.set_xscale("log", base=2)
        ticks = [int(b) for b in sweep]
        ax.set_xticks(ticks)
        ax.set_xticklabels([f"{t // 1000}k" for t in ticks], rotation=45)
        ax.minorticks_off()
        ax.set_xlabel("B (faces extracted between decimations)")
        ax.grid(alpha=0.3)
    fig.suptitle("Error and time against B, noise set (cf. paper Fig. 7)")
    fig.tight_layout()
    files.append("paper_fig7_batch.png")
    fig.savefig(os.path.join(outdir, files[-1]), dpi=110)
    plt.close(fig)

    # Figure 9: uncontractible faces before each decimation (R = 0.2, default B), decimations in the
    # trace's order (slab by slab; the final pass, with none left, is dropped).
    fig, ax = plt.subplots(figsize=(8, 4.5))
    maxima = []
    for s, _, _ in sets:
        p = f"{rd}/{s}.0.2.ours.trace"
        if not os.path.exists(p):
            continue
        tr = load_trace(p)[:-1]
        if not tr:
            continue
        ax.plot(range(1, len(tr) + 1), [d["uncontractible"] for d in tr], lw=1, label=s)
        full = load_json(f"{rd}/{s}.full.report")["faces_full"]
        most = max(d["uncontractible"] for d in tr)
        maxima.append((s, most, 100 * most / full))
    ax.set_xlabel("decimation (slab by slab)")
    ax.set_ylabel("uncontractible faces")
    ax.set_title("Uncontractible faces before each decimation, R = 0.2, default B (cf. paper Fig. 9)")
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    files.append("paper_fig9_uncontractible.png")
    fig.savefig(os.path.join(outdir, files[-1]), dpi=110)
    plt.close(fig)
    return files, maxima, peaks


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("results")
    ap.add_argument("outdir")
    ap.add_argument("--command", required=True)
    ap.add_argument("--sweep", required=True)
    ap.add_argument("--trace-batches", required=True)
    ap.add_argument("--seconds", type=int, default=0)
    ap.add_argument("--build-seconds", type=int, default=0)
    ap.add_argument("--load", default="", help="load averages (1, 5, 15 min) at start / end")
    a = ap.parse_args()
    rd = a.results
    with open(f"{rd}/sets.txt") as f:
        sets = [tuple(line.rstrip("\n").split("\t")) for line in f if line.strip()]

    out = ["# The paper's comparison, reproduced on our machine",
           "",
           f"Produced by `{a.command}` on {datetime.date.today().isoformat()} "
           f"({a.seconds // 60} min {a.seconds % 60} s end to end, of which {a.build_seconds} s building), "
           f"on {machine()}" + (f"; load averages (1/5/15 min) at start / end: {a.load}" if a.load else "") +
           ". Hou & Chen, section 5: Table 3 and Figures 5, 7 and 9.",
           "",
           "## Data sets (cf. Tables 2 and 5)",
           "",
           "| set | volume | resolution | iso | faces, full (our MC) | faces, full (OpenVDB volumeToMesh) | "
           "OpenVDB's full surface vs ours: RMS % |",
           "|---|---|---|---|---:|---:|---:|"]
    for s, desc, res in sets:
        rep = load_json(f"{rd}/{s}.full.report")
        vf = load_json(f"{rd}/{s}.vdbfull.out")
        ve = load_json(f"{rd}/{s}.vdbfull.err")
        out.append(f"| {s} | {desc} | {res} | {rep['iso']:.4g} | {rep['faces_full']} | {vf['faces_full']} | "
                   f"{fmt_pct(ve['a_to_b']['rms_pct'])} |")
    out += ["",
            "The last column is the floor under the errors of the two baselines that mesh with OpenVDB's "
            "`volumeToMesh` (a dual method: one vertex per surface voxel), since every error below is "
            "measured against our Marching Cubes surface.",
            "",
            "## Results (cf. Table 3)",
            "",
            "*faces*: output triangles (target R × full faces). *extract / simplify s*: the tool's own split "
            "(— where extraction and simplification are interleaved, as in the paper). *total s*: wall clock "
            "of the whole process (/usr/bin/time), reading the volume and writing the mesh included. "
            "*RMS error*: mesh_error, the full-resolution surface sampled (area-uniform, ≥ 1M samples) onto "
            "the simplified one, % of the bounding-box diagonal (the paper's metro setting); *Hausdorff*: "
            "symmetric. *peak RSS*: the tool's own peak resident memory. *ours/this*: ratios measured in "
            "the same run (< 1: ours is faster / more accurate / leaner)."]
    all_ratios = {}
    for r in RATES:
        all_ratios[r] = table(rd, sets, r, out)
    summary(all_ratios, out)

    sweep = a.sweep.split()
    trace_b = a.trace_batches.split()
    files, maxima, peaks = plots(rd, a.outdir, sets, sweep, trace_b)
    out += ["", "## Figures", "",
            f"![Intermediate mesh size]({files[0]})", "",
            "Faces held per slab while extracting, for two values of B (cf. Fig. 5). The pipeline cuts the "
            "block order into slabs along z, runs them in parallel with B / slabs faces per batch and merges "
            "them for the final pass; each line is one slab (R sets the slope, B the amplitude). Largest mesh "
            "in memory over the whole run (report): " +
            "; ".join(f"B = {b}: {m} faces ({100 * m / f:.1f}% of the full surface)" for b, m, f in peaks) + ".", "",
            f"![Error and time against B]({files[1]})", "",
            "RMS error and wall time against B at R = 0.1 and 0.01 (cf. Fig. 7).", "",
            f"![Uncontractible faces]({files[2]})", "",
            "Uncontractible faces (faces with a vertex that later blocks may still move) before each decimation "
            "(cf. Fig. 9); with slabs, the vertices on a slab's lower seam count too until the merge. "
            "Largest count per set: " +
            "; ".join(f"{s} {n} ({p:.2f}% of the full surface)" for s, n, p in maxima) + "."]
    out += ["", "## B sweep data (noise set)", "",
            "Faces above the target mean the decimator ran out of legal collapses (link condition, fold-overs, "
            "the many small closed components of this set).", "",
            "| R | B | target faces | faces | RMS error % | wall s | peak RSS MB | decimations |",
            "|---|---:|---:|---:|---:|---:|---:|---:|"]
    for r in ("0.1", "0.01"):
        for b in sweep:
            p = f"{rd}/sweep.{r}.{b}"
            if not os.path.exists(p + ".err"):
                continue
            rep = load_json(p + ".report")
            out.append(f"| {r} | {b} | {rep['faces_target']} | {rep['faces_out']} | {fmt_pct(load_json(p + '.err')['a_to_b']['rms_pct'])} | "
                       f"{fmt_time(load_time(p + '.time')[0])} | {rep['peak_rss_mb']:.0f} | {rep['decimations']} |")
    text = "\n".join(out) + "\n"
    with open(os.path.join(a.outdir, "paper_table.md"), "w") as f:
        f.write(text)
    sys.stdout.write(text)


if __name__ == "__main__":
    main()
