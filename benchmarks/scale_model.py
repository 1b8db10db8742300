#!/usr/bin/env python3
"""Scaling model of the merge tree (docs/scale.md), from the measured seconds of one run.

Input: the --report JSON of a single-process run (threads 1 gives clean per-node seconds: tree_first_slab,
tree_end_slab, tree_seconds for every slab and every join) and the run's wall seconds (GNU time).
Model, for W workers (ranks of one thread; the tree's rank shares of pipeline/slabs.cpp):
  setup    : opening the file, the topology and the block list, the cut into slabs (seconds_open, _blocks,
             _cut; and what no field times); every rank repeats it (serial). The block list, the cut, the
             walk of the file's leaf records (seconds_check, of seconds_open) and the read of the topology's
             lower nodes (seconds_topology, of seconds_open) run on all of a process's threads: in the
             threads' model and the bound, all but their serial share (BLOCKS_SERIAL, CUT_SERIAL,
             CHECK_SERIAL, TOPOLOGY_SERIAL) is divided among the threads. The ranks share the walk of the
             leaf records (LeafWalkShare): each walks its Nth before OpenVDB reads the tree and, after the
             cut, the records of the leaves it keeps that another rank walked, so a rank walks about 2/R of
             them (R ranks; all of them on one or two); the topology's walk (CHECK_SERIAL) each repeats. For
             a face target, counting the faces: each rank counts its own slabs (divided by W). Laying
             out the leaves (seconds_layout): each rank its own slabs' (divided by W; the pass that
             deletes the other leaves, which every rank makes, is not in the model: not timed apart,
             about 0.05 s a rank on the 2 GB gyroid by difference, docs/perf.md). Counting which of its
             blocks read which leaf (seconds_samplers): each rank its own (divided by W).
  tree     : node [l, r) on ranks [a, b): one rank -> the sum of its nodes' seconds (it makes them one
             after another); more -> max(left, right + transfer) + the join's own seconds.
  final    : final pass on rank 0 (seconds_final) plus writing the file (wall - report seconds). Its
             zero-area scan over every face and the output mesh's collection (seconds_final_parallel) run
             on all of a process's threads: divided among them in the threads' model and the bound, whole
             for ranks of one thread.
  measured set-up: where an mpirun report of the same run lists each rank's set-up (rank_setup_cpu_seconds:
             its CPU seconds until its leaves are laid out, less those spent in the ranks' collectives; each
             rank reads its share of the topology and lists its share of the blocks, pipeline.cpp), the
             ranks' set-up is the line S(W) = a + b / W through the one process's set-up and layout (W = 1)
             and the largest rank's at each measured rank count, least squares in 1 / W; it replaces the
             set-up, leaf walk and layout terms above for ranks of one thread (the count and the samplers
             stay divided by W). Ranks of RANK_THREADS threads keep the terms above.
The transfer of a node between ranks is taken at BANDWIDTH bytes/s. Its bytes: with --messages, the
line through the messages of an mpirun run of many ranks on the same volume and options (each rank > 0
sends its top node to its parent: rank_bytes_sent against that node's slab count, least squares: a
message carries the subtree's decimated mesh, about proportional to its slabs, and its two open seams at
full resolution, the same whatever its size); without, MESSAGE_BYTES_PER_FACE bytes per output face of
the subtree.
Threads (one process, `-j W`), modelled as pipeline.cpp's localSubtree runs them: the slabs start in order,
each on the first free thread; the thread that finishes a node's second child joins the node at once and climbs
on; a thread whose node waits for its sibling takes the next slab. The set-up runs once (the count and the
layout divided among the threads), then the final pass and the write. The node seconds of a `-j 1` run carry
no contention between threads (memory bandwidth, allocator): compare the model at 2 threads with the wall of
a measured `-j 2` run.
Ranks of RANK_THREADS threads (W / RANK_THREADS ranks, as mpirun runs one rank a machine): the ranks split the tree
as above; each rank's subtree runs as the threads' model runs a whole tree, on its own threads, after a set-up
whose threaded parts and a final pass whose scan and collection divide among those threads. Below RANK_THREADS
workers it is one process, the threads' model.
Bound: no schedule of the same node seconds on W workers ends the tree sooner than every node but the root
spread evenly over the workers and then the root, nor sooner than its longest chain (a slab and the joins
above it), nor sooner than every slab spread evenly and then the joins above the last slab to finish (at
least the cheapest such path): what a better schedule could still gain, and what only cheaper (or parallel)
joins can.
Prints a table of W -> modelled seconds and speed-up (ranks, threads, the bound, ranks of RANK_THREADS threads) and
the critical paths at 16 workers,
the speed-up if every slab took the mean of the slabs' seconds (slabs cut by work instead of by block count),
and writes an SVG plot.
Several runs: REPORT.json,REPORT_B.json,... with WALL,WALL_B,... (the same volume and options, so the same tree):
each node's seconds, each part of the set-up and the final pass, and the write (wall less the report's seconds) are
the least over the runs, the best of each part; a shared host only ever adds to a part's seconds, and adds to
different nodes in different runs (the gyroid's per-slab seconds of two runs correlate at 0.18, docs/scale.md).
Usage: scale_model.py [--messages MPI_REPORT.json] [--setup MPI_REPORT.json ...] REPORT.json[,...] WALL_SECONDS[,...] LABEL
                      [[--messages MPI_REPORT2.json] ... REPORT2.json WALL2 LABEL2 ...] OUT.svg
(--messages's report gives set-up points too where it lists them; --setup adds more rank counts.)
"""
import heapq
import json
import sys

BANDWIDTH = 1.0e9          # bytes/s between ranks (10 GbE); on one machine shared memory is faster
MESSAGE_BYTES_PER_FACE = 100.0  # without --messages: an early build's figure (29-172 measured since, docs/scale.md)
# Shares of seconds_blocks, seconds_cut and seconds_check that one thread makes whatever the thread count
# (Amdahl's serial share, 2 T2 / T1 - 1): from the 1024^3 gyroid's set-up at -j 1 and -j 2 (block list
# 0.41 -> 0.29 s, cut 0.28 -> 0.175 s, check 0.55 -> 0.39 s: docs/scale.md).
BLOCKS_SERIAL = 0.41
CUT_SERIAL = 0.25
CHECK_SERIAL = 0.42
# The topology's read (root and upper nodes in order, lower nodes on all threads): from the gyroid's open
# at -j 1 and -j 2 (docs/scale.md).
TOPOLOGY_SERIAL = 0.15
WORKERS = [1, 2, 4, 8, 16, 32, 64, 128, 256]
RANK_THREADS = 8  # threads of each rank in the mixed schedule: ranks of one machine's cores each
PATH_WORKERS = 16  # the width whose critical path is printed (the target)


def merge_split(l, r):
    return l + (r - l + 1) // 2


def split_ranks(l, r, a, b):
    m = merge_split(l, r)
    ranks = b - a
    share = ranks * (m - l) / (r - l)
    left = min(max(int(share + 0.5), 1), ranks - 1)
    return a + left


def rank_top_nodes(slabs, ranks):
    """The node [l, r) that each rank > 0 sends to its parent (pipeline/slabs.cpp, rankNode)."""
    sent = {}

    def walk(l, r, a, b):
        if b - a < 2 or r - l < 2:
            return
        m = merge_split(l, r)
        c = split_ranks(l, r, a, b)
        sent[c] = (m, r)
        walk(l, m, a, c)
        walk(m, r, c, b)

    walk(0, slabs, 0, ranks)
    return sent


def message_fit(mpi):
    """Bytes of a node's message as (fixed, per slab): the least-squares line through the measured ones."""
    sent = rank_top_nodes(int(mpi["slabs"]), int(mpi["ranks"]))
    measured = mpi.get("rank_bytes_sent", [])
    points = [(r - l, measured[k]) for k, (l, r) in sent.items() if k < len(measured)]
    n = len(points)
    if n == 0:
        sys.exit("--messages: the report lists no messages (a run of one rank?)")
    mx = sum(x for x, _ in points) / n
    my = sum(y for _, y in points) / n
    sxx = sum((x - mx) ** 2 for x, _ in points)
    slope = sum((x - mx) * (y - my) for x, y in points) / sxx if sxx > 0 else my / mx
    return max(0.0, my - slope * mx), slope, points


def setup_fit(points):
    """(a, b) of S(W) = a + b / W, least squares in 1 / W through the (W, seconds) points."""
    xs = [1.0 / w for w, _ in points]
    ys = [y for _, y in points]
    mx, my = sum(xs) / len(xs), sum(ys) / len(ys)
    sxx = sum((x - mx) ** 2 for x in xs)
    b = sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / sxx if sxx > 0 else 0.0
    return my - b * mx, b


def model(report, wall, even=False, messages=None, setup_points=None):
    first = report["tree_first_slab"]
    end = report["tree_end_slab"]
    secs = report["tree_seconds"]
    node = {(int(f), int(e)): s for f, e, s in zip(first, end, secs)}
    slabs = int(report["slabs"])
    if even:
        # What slabs of equal work would give: every slab takes the mean of the measured slabs.
        mean = sum(node[(l, l + 1)] for l in range(slabs)) / slabs
        for l in range(slabs):
            node[(l, l + 1)] = mean
    if messages:  # the fitted line: bytes of a node of n slabs
        fixed, per_slab = messages
    else:  # the early build's bytes per output face, output faces per slab
        fixed, per_slab = 0.0, report["faces_out"] / max(1, slabs) * MESSAGE_BYTES_PER_FACE
    final = report["seconds_final"] + max(0.0, wall - report["seconds"])
    scan = report.get("seconds_final_parallel", 0.0)
    count = report.get("seconds_count", 0.0)  # each rank counts its own slabs' faces
    layout = report.get("seconds_layout", 0.0)  # each rank lays out its own slabs' leaves
    layout += report.get("seconds_samplers", 0.0)  # and counts which of its blocks read which leaf
    setup = max(0.0, report["seconds"] - report["seconds_slabs"] - report["seconds_final"] - count - layout)
    leaf_walk = report.get("seconds_check", 0.0) * (1 - CHECK_SERIAL)
    spread = (report.get("seconds_blocks", 0.0) * (1 - BLOCKS_SERIAL) + report.get("seconds_cut", 0.0) * (1 - CUT_SERIAL) +
              report.get("seconds_topology", 0.0) * (1 - TOPOLOGY_SERIAL) + leaf_walk)

    def walk_share(ranks):
        # Of the leaf records' walk, what one of `ranks` ranks walks: its part, and its kept leaves' records.
        return min(1.0, 2.0 / ranks)

    def serial(l, r):
        if r - l == 1:
            return node[(l, r)]
        m = merge_split(l, r)
        return serial(l, m) + serial(m, r) + node[(l, r)]

    def parallel(l, r, a, b, threads=1):
        # Seconds of node [l, r) on ranks [a, b) of `threads` threads each, and its critical path: the
        # subtree one rank makes alone (one node after another, or on its threads as one process does),
        # then the joins above it.
        if b - a < 2 or r - l < 2:
            if threads > 1:
                alone, path = threads_tree(node, r, threads, first=l)
                return alone, [f"one rank's slabs [{l}, {r}) on {threads} threads {alone:.2f} s"]
            alone = serial(l, r)
            return alone, [f"one rank's slabs [{l}, {r}) {alone:.2f} s"]
        m = merge_split(l, r)
        c = split_ranks(l, r, a, b)
        transfer = (fixed + per_slab * (r - m)) / BANDWIDTH
        (left, left_path), (right, right_path) = parallel(l, m, a, c, threads), parallel(m, r, c, b, threads)
        seconds, below = (left, left_path) if left >= right + transfer else (right + transfer, right_path)
        return seconds + node[(l, r)], below + [f"join [{l}, {r}) {node[(l, r)]:.2f} s"]

    one = setup + count + layout + serial(0, slabs) + final
    fit = None
    if setup_points:
        samplers = report.get("seconds_samplers", 0.0)
        fit = setup_fit([(1, setup + layout - samplers)] + setup_points)
    rows = []
    for w in WORKERS:
        start = setup + (count + layout) / min(w, slabs)
        threads_start = start - spread + spread / w
        ranks, ranks_path = parallel(0, slabs, 0, w)
        threads, threads_path = threads_tree(node, slabs, w)
        threads_final = final - scan + scan / w
        t = start - leaf_walk * (1 - walk_share(w)) + ranks + final
        if fit:
            t = fit[0] + fit[1] / w + (count + report.get("seconds_samplers", 0.0)) / min(w, slabs) + ranks + final
        tt = threads_start + threads + threads_final
        tb = threads_start + schedule_bound(node, slabs, w) + threads_final
        # Ranks of RANK_THREADS threads (fewer workers: one process): the set-up's threaded parts and
        # the final pass's on a rank's threads, each rank's subtree as one process runs it.
        per = min(w, RANK_THREADS)
        hybrid_tree, hybrid_path = parallel(0, slabs, 0, w // per, per)
        th = (start - spread + (spread - leaf_walk) / per + leaf_walk * walk_share(w // per) / per + hybrid_tree + final -
              scan + scan / per)
        rows.append((w, t, one / t, tt, one / tt, tb, one / tb, th, one / th))
        if w == PATH_WORKERS:
            paths = ranks_path, threads_path, hybrid_path
    return setup + count + layout, serial(0, slabs), final, rows, paths, fit


def schedule_bound(node, slabs, workers):
    """Seconds below which no schedule of these nodes on `workers` workers ends the tree: the root waits for
    every other node (at best spread evenly over the workers); for its longest chain of nodes; and for the
    last slab to finish (no sooner than all slabs spread evenly) and then the joins above that slab, at
    least those of the slab whose joins cost least."""
    root = node[(0, slabs)]
    rest = sum(node.values()) - root
    slab_work = sum(node[(l, l + 1)] for l in range(slabs))

    def chain(l, r, joins_only):
        if r - l < 2:
            return 0.0 if joins_only else node[(l, r)]
        m = merge_split(l, r)
        below = (min if joins_only else max)(chain(l, m, joins_only), chain(m, r, joins_only))
        return below + node[(l, r)]

    return max(rest / workers + root, chain(0, slabs, False), slab_work / workers + chain(0, slabs, True))


def threads_tree(node, slabs, workers, first=0):
    """Seconds from the first slab's start to the root's end with `workers` threads (see the docstring),
    and the critical path: the last slab to finish a node that then climbed to the root, and the joins
    on its way. The subtree [first, slabs) of the tree alone when `first` is given (a rank's share)."""
    if slabs - first == 1:
        return node[(first, slabs)], [f"slab {first} 0.00-{node[(first, slabs)]:.2f} s"]
    parent = {}

    def build(l, r):
        if r - l < 2:
            return
        m = merge_split(l, r)
        parent[(l, m)] = parent[(m, r)] = (l, r)
        build(l, m)
        build(m, r)

    build(first, slabs)
    done = {}
    events = []  # (time, node, path): a node finishes on the thread that made it
    nxt = first

    def start(t, si):
        heapq.heappush(events, (t + node[(si, si + 1)], (si, si + 1), [f"slab {si} {t:.2f}-{t + node[(si, si + 1)]:.2f} s"]))

    for _ in range(min(workers, slabs - first)):
        start(0.0, nxt)
        nxt += 1
    while events:
        t, (l, r), path = heapq.heappop(events)
        if (l, r) == (first, slabs):
            return t, path
        p = parent[(l, r)]
        m = merge_split(*p)
        sibling = (m, p[1]) if l == p[0] else (p[0], m)
        if sibling in done:  # this thread joins the parent at once
            heapq.heappush(events, (t + node[p], p, path + [f"join [{p[0]}, {p[1]}) {node[p]:.2f} s"]))
            continue
        done[(l, r)] = t
        if nxt < slabs:  # this thread takes the next slab
            start(t, nxt)
            nxt += 1
    raise RuntimeError("the tree did not reach its root")


def svg(curves, path):
    W, H, L, B = 560, 380, 60, 50
    import math
    xmax = math.log2(WORKERS[-1])
    ymax = max(max(max(row[2], row[4]) for row in rows) for _, rows in curves) * 1.1
    ymax = max(ymax, 16)

    def x(w):
        return L + (W - L - 20) * math.log2(w) / xmax

    def y(s):
        return H - B - (H - B - 20) * s / ymax

    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{H}" font-family="sans-serif" font-size="12">',
           f'<rect width="{W}" height="{H}" fill="white"/>']
    for w in WORKERS:
        out.append(f'<line x1="{x(w):.1f}" y1="{H-B}" x2="{x(w):.1f}" y2="20" stroke="#ddd"/>')
        out.append(f'<text x="{x(w):.1f}" y="{H-B+16}" text-anchor="middle">{w}</text>')
    step = 10 if ymax <= 80 else 20
    for s in range(0, int(ymax) + 1, step):
        out.append(f'<line x1="{L}" y1="{y(s):.1f}" x2="{W-20}" y2="{y(s):.1f}" stroke="#eee"/>')
        out.append(f'<text x="{L-6}" y="{y(s)+4:.1f}" text-anchor="end">{s}</text>')
    out.append(f'<polyline fill="none" stroke="#999" stroke-dasharray="4 3" points="' +
               " ".join(f"{x(w):.1f},{y(min(w, ymax)):.1f}" for w in WORKERS if w <= ymax) + '"/>')
    colours = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd"]
    for i, (label, rows) in enumerate(curves):
        c = colours[i % len(colours)]
        out.append(f'<polyline fill="none" stroke="{c}" stroke-width="2" points="' +
                   " ".join(f"{x(row[0]):.1f},{y(row[2]):.1f}" for row in rows) + '"/>')
        out.append(f'<polyline fill="none" stroke="{c}" stroke-width="2" stroke-dasharray="6 3" points="' +
                   " ".join(f"{x(row[0]):.1f},{y(row[4]):.1f}" for row in rows) + '"/>')
        out.append(f'<text x="{L+10}" y="{36+16*i}" fill="{c}">{label} (solid: ranks, dashed: threads)</text>')
    out.append(f'<text x="{(W+L)/2}" y="{H-12}" text-anchor="middle">workers (ranks of one thread, or threads of one process)</text>')
    out.append(f'<text x="16" y="{H/2}" transform="rotate(-90 16 {H/2})" text-anchor="middle">modelled speed-up</text>')
    out.append('</svg>')
    open(path, "w").write("\n".join(out) + "\n")


def setup_point(mpi, path, report):
    """(ranks, the largest rank's set-up seconds) of an mpirun report of the same run, or None."""
    if int(mpi["slabs"]) != int(report["slabs"]) or mpi["faces_out"] != report["faces_out"]:
        sys.exit(f"{path}: not a run of the same volume and options")
    measured = mpi.get("rank_setup_cpu_seconds", [])
    return (int(mpi["ranks"]), max(measured)) if measured and max(measured) > 0 else None


def best_of_runs(paths, walls):
    """One report and wall from several runs of the same volume and options: every node's seconds and every
    seconds_* part the least over the runs, and the wall the least set-up, parts and write put together."""
    runs = [json.load(open(p)) for p in paths]
    if len(runs) != len(walls):
        sys.exit(f"{','.join(paths)}: {len(runs)} reports but {len(walls)} wall times")
    best = dict(runs[0])
    for path, run in zip(paths[1:], runs[1:]):
        if int(run["slabs"]) != int(best["slabs"]) or run["faces_out"] != best["faces_out"]:
            sys.exit(f"{path}: not a run of the same volume and options as {paths[0]}")
    node = {}
    for run in runs:
        for f, e, sec in zip(run["tree_first_slab"], run["tree_end_slab"], run["tree_seconds"]):
            node[(f, e)] = min(node.get((f, e), sec), sec)
    keys = sorted(node)
    best["tree_first_slab"] = [f for f, _ in keys]
    best["tree_end_slab"] = [e for _, e in keys]
    best["tree_seconds"] = [node[k] for k in keys]

    def unnamed(run):  # the set-up no field times apart (model's `setup` less the named parts it holds)
        return run["seconds"] - run["seconds_slabs"] - run["seconds_final"] - run.get("seconds_count", 0.0) - run.get("seconds_layout", 0.0)

    for key in best:
        if key.startswith("seconds_"):
            best[key] = min(run[key] for run in runs)
    best["seconds_slabs"] = sum(node.values())
    best["seconds"] = (min(unnamed(run) for run in runs) + best["seconds_slabs"] + best["seconds_final"] +
                       best.get("seconds_count", 0.0) + best.get("seconds_layout", 0.0))
    return best, best["seconds"] + min(w - run["seconds"] for run, w in zip(runs, walls))


def main(argv):
    args, groups, messages, setups = argv[1:-1], [], None, []
    while args:
        if args[0] in ("--messages", "--setup") and len(args) > 1:
            if args[0] == "--messages":
                messages = args[1]
            else:
                setups.append(args[1])
            args = args[2:]
            continue
        if len(args) < 3:
            sys.exit(__doc__)
        groups.append((args[0].split(","), [float(w) for w in args[1].split(",")], args[2], messages, setups))
        args, messages, setups = args[3:], None, []
    if not groups or messages or setups:
        sys.exit(__doc__)
    out = argv[-1]
    curves = []
    for paths, walls, label, messages, setups in groups:
        path = paths[0]
        report, wall = best_of_runs(paths, walls)
        if len(paths) > 1:
            print(f"{label}: the best of {len(paths)} runs (walls " + ", ".join(f"{w:.2f}" for w in walls) +
                  f" s), each node and part its least: {wall:.2f} s")
        setup_pts = [p for p in (setup_point(json.load(open(f)), f, report) for f in ([messages] if messages else []) + setups) if p]
        fit = None
        if messages:
            mpi = json.load(open(messages))
            if int(mpi["slabs"]) != int(report["slabs"]) or mpi["faces_out"] != report["faces_out"]:
                sys.exit(f"{messages}: not a run of the same volume and options as {path}")
            fixed, per_slab, points = message_fit(mpi)
            fit = (fixed, per_slab)
            print(f"{label}: messages of {mpi['ranks']} ranks (slabs: MB) " +
                  ", ".join(f"{x}: {y / 1e6:.1f}" for x, y in sorted(points)) +
                  f"; fitted {fixed / 1e6:.2f} MB + {per_slab / 1e6:.3f} MB a slab, at {BANDWIDTH / 1e9:g} GB/s")
        setup, tree, final, rows, (critical, thread_path, hybrid_path), line = model(report, wall, messages=fit,
                                                                                    setup_points=setup_pts)
        if line:
            print(f"{label}: each rank's set-up (the largest of the ranks' CPU seconds until its leaves are laid out): " +
                  ", ".join(f"{w} ranks {y:.2f} s" for w, y in sorted(setup_pts)) + f"; one process {line[0] + line[1]:.2f} s"
                  f" (set-up and layout); fitted {line[0]:.3f} + {line[1]:.3f} / W s")
        print(f"{label}: {report['slabs']} slabs; setup {setup:.2f} s, tree {tree:.2f} s (work), final + write {final:.2f} s"
              f" (of which the zero-area scan and the mesh's collection {report.get('seconds_final_parallel', 0.0):.2f} s, divided among threads)")
        pieces = [(k, report[f"seconds_{k}"]) for k in ("open", "check", "topology", "blocks", "cut", "samplers", "count", "layout") if f"seconds_{k}" in report]
        if pieces:
            print("setup: " + ", ".join(f"{k} {v:.2f} s" for k, v in pieces) + " (count, layout and samplers divided among workers)")
        print(f"| workers | ranks: modelled seconds | speed-up | threads: modelled seconds | speed-up | any schedule: at least | at most |"
              f" ranks of {RANK_THREADS} threads: seconds | speed-up |")
        print("|---|---|---|---|---|---|---|---|---|")
        for w, t, s, tt, ts, tb, bs, th, hs in rows:
            print(f"| {w} | {t:.2f} | {s:.1f}x | {tt:.2f} | {ts:.1f}x | {tb:.2f} | {bs:.1f}x | {th:.2f} | {hs:.1f}x |")
        print(f"critical path at {PATH_WORKERS} ranks: " + ", then ".join(critical))
        print(f"critical path at {PATH_WORKERS} workers as ranks of {RANK_THREADS} threads: " + ", then ".join(hybrid_path))
        print(f"critical path at {PATH_WORKERS} threads (after the set-up): " + ", then ".join(thread_path))
        even = {row[0]: row for row in model(report, wall, even=True, messages=fit, setup_points=setup_pts)[3]}
        print("slabs of equal work instead (each the mean of the measured slabs), ranks / threads: " +
              ", ".join(f"{w} workers {even[w][2]:.1f}x / {even[w][4]:.1f}x" for w in (8, 16, 32, 64)))
        print()
        curves.append((label, rows))
    svg(curves, out)


if __name__ == "__main__":
    main(sys.argv)
