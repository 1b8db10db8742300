// vdb_isosimp IN.vdb: parse the command line, run one library call, report. Errors become one line on
// stderr and an exit code: 1 bad input or output, 2 bad usage, 3 no surface at the iso-value.
#include "cli_numbers.h"
#include "cli_parse.h"
#include "json_text.h"
#include "vdb_isosimp/errors.h"
#include "vdb_isosimp/frame_sequence.h"
#include "vdb_isosimp/mesh_writer.h"
#include "vdb_isosimp/mpi_run.h"
#include "vdb_isosimp/temporary_file.h"
#include "vdb_isosimp/vdb_isosimp.h"

#include <CLI/CLI.hpp>

#include <atomic>
#include <malloc.h>
#include <memory>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iostream>
#include <optional>
#include <sstream>
#include <sys/stat.h>
#include <thread>
#include <tuple>
#include <unistd.h>
#include <vector>

namespace {

using namespace vdb_isosimp;

// A one-line bar on a terminal: blocks done, faces kept, elapsed time and an estimate of the rest.
class TerminalProgress final : public Progress {
public:
    bool update(double fraction, uint64_t facesKept) override
    {
        // Called per block batch and, during decimation passes, every few thousand collapses. After
        // the last block the final pass runs ("finishing").
        const double t = elapsed();
        if (!due(t)) return true;
        // The time left comes from extraction's pace alone (a face target counts the blocks first).
        const double spent = t - mExtractStart;
        const double eta = fraction > 0.01 ? spent * (1.0 - fraction) / fraction : 0.0;
        char text[96];
        if (fraction < 1.0)
            std::snprintf(text, sizeof text, "%5.1f%%  %llu faces kept  %.0fs, ~%.0fs left ", 100.0 * fraction,
                          (unsigned long long)facesKept, t, eta);
        else
            std::snprintf(text, sizeof text, "finishing: %llu faces kept  %.0fs          ", (unsigned long long)facesKept, t);
        draw(fraction, text);
        return true;
    }

    // A face target first counts the full-resolution faces, block by block.
    bool counting(double fraction) override
    {
        const double t = elapsed();
        mExtractStart = t;
        if (!due(t)) return true;
        char text[96];
        std::snprintf(text, sizeof text, "%5.1f%%  counting faces for the target  %.0fs ", 100.0 * fraction, t);
        draw(fraction, text);
        return true;
    }

    // Clears the bar's line before the summary or an error is printed.
    void clear()
    {
        if (mShown) std::fprintf(stderr, "\r%*s\r", 90, "");
        mShown = false;
    }

private:
    double elapsed() const { return std::chrono::duration<double>(std::chrono::steady_clock::now() - mStart).count(); }
    // Redraws at most five times a second.
    bool due(double t)
    {
        if (t - mLast < 0.2) return false;
        mLast = t;
        return true;
    }
    void draw(double fraction, const char* text)
    {
        const int width = 30, filled = int(fraction * width);
        std::string bar(size_t(filled), '#');
        bar.resize(width, '.');
        std::fprintf(stderr, "\r[%s] %s", bar.c_str(), text);
        mShown = true;
        std::fflush(stderr);
    }

    std::chrono::steady_clock::time_point mStart = std::chrono::steady_clock::now();
    double mLast = -1.0, mExtractStart = 0.0;
    bool mShown = false;
};

// Interruption. SIGINT/SIGTERM/SIGHUP only record the signal (nothing else is safe in a handler).
// The library sees it through RunProgress at its next progress call, throws Cancelled and unwinds;
// main then exits with 128 + the signal number (130 for Ctrl-C, 143 for SIGTERM). Steps without a
// cancellation point (the final decimation, writing the mesh) are covered by the watchdog thread:
// if the run has not stopped 0.5 s after the signal, or at a second signal, it removes the
// temporary files and ends the process with the same code. Nothing is left under an output name:
// files only reach their names by a rename after a complete write.
std::atomic<int> gSignal{0};
std::atomic<int> gSignalCount{0};

extern "C" void onSignal(int sig)
{
    gSignal.store(sig);
    gSignalCount.fetch_add(1);
}

class Watchdog {
public:
    explicit Watchdog(std::vector<std::string> temporaries) : mTemps(std::move(temporaries))
    {
        for (int sig : {SIGINT, SIGTERM, SIGHUP}) {
            struct sigaction sa {};
            sa.sa_handler = onSignal;
            sigemptyset(&sa.sa_mask);
            ::sigaction(sig, &sa, nullptr);
        }
        mThread = std::thread([this] { watch(); });
    }
    ~Watchdog()
    {
        mDone.store(true);
        mThread.join();
    }

private:
    void watch()
    {
        using Clock = std::chrono::steady_clock;
        Clock::time_point since{};
        while (!mDone.load()) {
            std::this_thread::sleep_for(std::chrono::milliseconds(10));
            const int sig = gSignal.load();
            if (!sig) continue;
            if (since == Clock::time_point{}) since = Clock::now();
            if (gSignalCount.load() > 1 || Clock::now() - since > std::chrono::milliseconds(500)) {
                for (const std::string& t : mTemps) ::unlink(t.c_str());
                static const char msg[] = "vdb_isosimp: interrupted\n";
                if (::write(STDERR_FILENO, msg, sizeof msg - 1) < 0) {}
                ::_exit(128 + sig);
            }
        }
    }

    std::vector<std::string> mTemps;
    std::atomic<bool> mDone{false};
    std::thread mThread;
};

// What the library is given: the bar when there is one, and a stop when a signal came.
class RunProgress final : public Progress {
public:
    explicit RunProgress(Progress* bar) : mBar(bar) {}
    bool update(double fraction, uint64_t facesKept) override
    {
        if (gSignal.load()) return false;
        return mBar ? mBar->update(fraction, facesKept) : true;
    }
    bool counting(double fraction) override
    {
        if (gSignal.load()) return false;
        return mBar ? mBar->counting(fraction) : true;
    }

private:
    Progress* mBar;
};

// Existing special files (FIFOs, devices such as /dev/stdout or /dev/full) are written in place: a
// temporary file and a rename would replace the device node itself.
bool isSpecialFile(const std::string& path)
{
    struct stat st {};
    return ::stat(path.c_str(), &st) == 0 && !S_ISREG(st.st_mode) && !S_ISDIR(st.st_mode);
}

std::string stemOf(const std::string& path)
{
    const auto slash = path.find_last_of('/');
    std::string name = slash == std::string::npos ? path : path.substr(slash + 1);
    const auto dot = name.find_last_of('.');
    return dot == std::string::npos || dot == 0 ? name : name.substr(0, dot);
}

// STEM_lodI.EXT for OUT = STEM.EXT (the folder kept): level I of a LOD chain.
std::string levelPath(const std::string& output, size_t level)
{
    const auto slash = output.find_last_of('/');
    const auto dot = output.find_last_of('.');
    const bool hasExt = dot != std::string::npos && (slash == std::string::npos || dot > slash + 1);
    const std::string stem = hasExt ? output.substr(0, dot) : output, ext = hasExt ? output.substr(dot) : "";
    return stem + "_lod" + std::to_string(level) + ext;
}

std::string reportJson(const Report& r, const std::string& output, const Options& o)
{
    std::ostringstream j;
    j.precision(10);
    j << "{\n";
    const std::vector<ReportField> fields = reportFields(r, o);
    for (size_t i = 0; i < fields.size(); ++i) {
        const ReportField& f = fields[i];
        j << "  \"" << f.name << "\": ";
        if (f.kind == ReportField::Kind::Text) j << jsonString(f.text);
        else if (f.kind == ReportField::Kind::Integer) j << f.integer;
        else if (f.kind == ReportField::Kind::Reals) {
            j << '[';
            for (size_t k = 0; k < f.reals.size(); ++k) j << (k ? ", " : "") << f.reals[k];
            j << ']';
        }
        else j << f.real;
        j << (i + 1 < fields.size() ? ",\n" : "\n");
        if (f.name == "input") j << "  \"output\": " << jsonString(output) << ",\n";
    }
    j << "}\n";
    return j.str();
}

std::string traceCsv(const Report& r)
{
    std::ostringstream c;
    c << "decimation,faces_generated,faces_before,faces_after,uncontractible,target,slab\n";
    for (size_t i = 0; i < r.trace.size(); ++i) {
        const DecimationRecord& d = r.trace[i];
        c << i + 1 << ',' << d.facesGenerated << ',' << d.facesBefore << ',' << d.facesAfter << ','
          << d.uncontractible << ',' << d.target << ',' << d.slab << '\n';
    }
    return c.str();
}

// Text files (the report, the trace) also go through a temporary file and a rename.
void writeText(const std::string& path, const std::string& text)
{
    if (isSpecialFile(path)) {
        std::FILE* f = std::fopen(path.c_str(), "wb");
        if (!f) throw OutputError(path + ": cannot write report (" + std::strerror(errno) + ")");
        const bool bad = std::fwrite(text.data(), 1, text.size(), f) != text.size() || std::fflush(f) != 0;
        const int err = errno;
        if (std::fclose(f) != 0 || bad) throw OutputError(path + ": cannot write report (" + std::strerror(bad ? err : errno) + ")");
        return;
    }
    const std::string tmp = temporaryPathFor(path);
    {
        std::ofstream f(tmp, std::ios::binary);
        f << text;
        f.flush();
        if (!f) {
            std::remove(tmp.c_str());
            throw OutputError(path + ": cannot write report (" + std::strerror(errno) + ")");
        }
    }
    if (std::rename(tmp.c_str(), path.c_str()) != 0) {
        std::remove(tmp.c_str());
        throw OutputError(path + ": cannot write report (" + std::strerror(errno) + ")");
    }
}

// Fails fast, before the long run, when the output cannot be created where asked.
void probeWritable(const std::string& path)
{
    struct stat st {};
    if (::stat(path.c_str(), &st) == 0) {
        if (S_ISDIR(st.st_mode)) throw OutputError(path + ": cannot create output file (" + std::strerror(EISDIR) + ")");
        if (!S_ISREG(st.st_mode)) {  // written in place: it must be open for writing
            if (::access(path.c_str(), W_OK) != 0)
                throw OutputError(path + ": cannot write to it (" + std::strerror(errno) + ")");
            return;
        }
    }
    const std::string tmp = temporaryPathFor(path);
    std::FILE* f = std::fopen(tmp.c_str(), "wb");
    if (!f) throw OutputError(path + ": cannot create output file (" + std::strerror(errno) + ")");
    std::fclose(f);
    std::remove(tmp.c_str());
}

// What one run reads and writes; a sequence has one per frame.
struct RunPaths {
    std::string input, output, report, trace;
    int frame = -1;  // the frame of a sequence, -1 for a single file
};

struct OutputChoices {
    bool ascii = false, normals = false, quiet = false;
    MpiRun* mpi = nullptr;  // under mpirun: this process's share of each run; rank 0 alone writes
};

// A face target the surface cannot reach (within 1 %): the edges left would each change the surface's
// topology or fold a face over. The mesh is closed, so its Euler characteristic is V - F/2: at most 0
// means a genus of at least 1 - chi/2, above 0 at least chi/2 closed pieces.
void noteMissedTarget(const std::string& who, const Report& r)
{
    if (r.stoppedBy != "topology" || r.facesTarget == 0) return;  // the bound alone asks for no count
    const long long chi = (long long)r.vertsOut - (long long)(r.facesOut / 2);
    const std::string shape = chi <= 0 ? "genus " + std::to_string(1 - chi / 2) + " or more"
                                       : std::to_string((chi + 1) / 2) + " or more closed pieces";
    std::fprintf(stderr,
                 "%s%llu faces, not the %llu asked for: the surface has %s (Euler characteristic %lld), and every "
                 "collapse left would change that or fold faces over\n",
                 who.c_str(), (unsigned long long)r.facesOut, (unsigned long long)r.facesTarget, shape.c_str(), chi);
}

// One input to one mesh (and its report and trace): the summary line or one error line, and the exit
// code (0 done, 1 bad input or output, 3 no surface, 128 + signal when interrupted). `done` gets the
// report of a successful run.
int meshOne(const RunPaths& p, const Options& opt, const OutputChoices& out, TerminalProgress& bar, Report* done)
{
    // In a sequence, errors say which frame failed; the message names the file too.
    const std::string who = p.frame >= 0 ? "vdb_isosimp: frame " + std::to_string(p.frame) + ": " : "vdb_isosimp: ";
    const std::string& input = p.input;
    const std::string& output = p.output;
    const std::string& reportPath = p.report;
    const std::string& tracePath = p.trace;
    const bool quiet = out.quiet;
    const bool writer = !out.mpi || out.mpi->rank() == 0;
    // The levels of a chain are written beside the output name: STEM_lod0.EXT, ...
    std::vector<std::string> levelPaths;
    for (size_t i = 0; i < opt.lods.size(); ++i) levelPaths.push_back(levelPath(output, i));
    try {
        formatForPath(output, out.ascii);  // an unsupported extension fails before the long run
        std::vector<std::string> temporaries;
        for (const std::string& t : levelPaths.empty() ? std::vector<std::string>{output} : levelPaths) {
            if (writer) probeWritable(t);
            temporaries.push_back(temporaryPathFor(t));
        }
        for (const std::string* t : {&reportPath, &tracePath})
            if (!t->empty()) temporaries.push_back(temporaryPathFor(*t));
        Watchdog watchdog(temporaries);
        const bool showBar = writer && !quiet && ::isatty(STDERR_FILENO);
        RunProgress progress(showBar ? &bar : nullptr);
        WriteOptions wo;
        wo.ascii = out.ascii;
        wo.normals = out.normals;
        Options run = opt;
        // Each level is written as soon as it is made, so only one level's mesh is held at a time.
        if (writer && !levelPaths.empty())
            run.onLevel = [&](const LevelOfDetail& level) {
                wo.objectName = level.run.grid;
                wo.comment = "vdb_isosimp grid " + level.run.grid + " level " + std::to_string(level.index);
                writeMesh(level.mesh, levelPaths[level.index], wo);
                if (!quiet) {
                    bar.clear();
                    std::fprintf(stderr, "vdb_isosimp: level %zu: R=%.4g, %llu faces, %llu vertices, at %.2f s -> %s\n",
                                 level.index, level.report.ratio, (unsigned long long)level.report.facesOut,
                                 (unsigned long long)level.report.vertsOut, level.report.seconds,
                                 levelPaths[level.index].c_str());
                }
            };
        Result res = out.mpi ? out.mpi->simplifyFile(input, run, &progress) : simplifyFile(input, run, &progress);
        bar.clear();
        if (gSignal.load()) throw Cancelled("interrupted");
        const Report& r = res.report;
        if (!writer) {
            if (done) *done = r;  // the next frames' iso-value, as on rank 0
            return 0;
        }
        if (r.isoDefaulted && !quiet && p.frame < 0)
            std::fprintf(stderr, "vdb_isosimp: no --iso given for %s grid '%s': using the midpoint of its value range, %g\n",
                         r.gridClass.c_str(), r.grid.c_str(), r.iso);
        else if (r.isoDefaulted && !quiet)
            std::fprintf(stderr, "vdb_isosimp: no --iso given for %s grid '%s': iso-value %g (the midpoint of its value range) from frame %d, used for every frame\n",
                         r.gridClass.c_str(), r.grid.c_str(), r.iso, p.frame);
        wo.objectName = r.grid;
        wo.comment = "vdb_isosimp grid " + r.grid;
        if (levelPaths.empty()) writeMesh(res.mesh, output, wo);
        if (!reportPath.empty()) writeText(reportPath, reportJson(r, output, opt));
        if (!tracePath.empty()) writeText(tracePath, traceCsv(r));
        if (!quiet)
            std::fprintf(stderr, "vdb_isosimp: %s, grid '%s': %llu -> %llu faces (R=%.4g), %llu vertices, %.2f s, peak %.0f MB -> %s\n",
                         input.c_str(), r.grid.c_str(), (unsigned long long)r.facesFull, (unsigned long long)r.facesOut, r.ratio,
                         (unsigned long long)r.vertsOut, r.seconds, r.peakRssMb,
                         levelPaths.empty() ? output.c_str() : levelPaths.back().c_str());
        if (!quiet) noteMissedTarget(who, r);
        if (done) *done = r;
        return 0;
    } catch (const MemoryBudgetError& e) {
        bar.clear();
        std::cerr << who << e.what() << " (--ratio, --faces, --batch, --max-memory)\n";
        return 1;
    } catch (const EmptySurfaceError& e) {
        bar.clear();
        std::cerr << who << e.what() << "\n";
        return 3;
    } catch (const Cancelled&) {
        bar.clear();
        std::cerr << "vdb_isosimp: interrupted\n";
        const int sig = gSignal.load();
        return 128 + (sig ? sig : SIGINT);
    } catch (const std::exception& e) {
        bar.clear();
        std::cerr << who << e.what() << "\n";
        return 1;
    }
}

// Every frame with the same settings: a fog grid's default iso-value comes from the first frame meshed
// and is given to the others, so the frames' surfaces match. A failed frame is one line and the rest
// still run; the exit code is 1 if any failed (an interruption stops the whole sequence).
int meshSequence(const std::string& input, const FramePattern& out, const std::optional<FramePattern>& report,
                 const std::optional<FramePattern>& trace, const std::vector<Frame>& frames, Options opt,
                 const OutputChoices& choices)
{
    int failed = 0;
    for (const Frame& f : frames) {
        const RunPaths p{f.path, out.path(f.number), report ? report->path(f.number) : "",
                         trace ? trace->path(f.number) : "", f.number};
        TerminalProgress bar;  // a frame's own clock: the time left is the frame's
        Report r;
        const int code = meshOne(p, opt, choices, bar, &r);
        if (code >= 128) return code;
        if (code != 0) ++failed;
        else if (!opt.iso) opt.iso = r.iso;  // level sets too: 0 then, the same for every frame
    }
    if (!choices.quiet)
        std::fprintf(stderr, "vdb_isosimp: %s: %zu of %zu frames meshed\n", input.c_str(),
                     frames.size() - size_t(failed), frames.size());
    return failed ? 1 : 0;
}

// A usage error: one line, exit code 2.
int usageError(const std::string& what)
{
    std::cerr << "vdb_isosimp: " << what << " (see --help)\n";
    return 2;
}

// "A-B" or "A" (frame numbers >= 0).
bool parseFrameRange(const std::string& text, int& first, int& last)
{
    const size_t dash = text.find('-', 1);
    const auto number = [](const std::string& t, int& v) {
        if (t.empty() || t.size() > 9 || t.find_first_not_of("0123456789") != std::string::npos) return false;
        v = std::stoi(t);
        return true;
    };
    if (dash == std::string::npos) return number(text, first) && number(text, last);
    return number(text.substr(0, dash), first) && number(text.substr(dash + 1), last) && first <= last;
}

} // namespace

int main(int argc, char** argv)
{
    // Return freed memory to the system past 8 MiB of slack. glibc's default threshold grows with the
    // largest block freed (up to 64 MiB per arena), and block meshes, voxel leaves and merged slab
    // arrays are freed all run long: that slack would be a sixth of the peak (docs/perf.md).
    mallopt(M_TRIM_THRESHOLD, 8 << 20);
    // Under mpirun every rank runs this program: each makes its part of the merge tree, rank 0 writes.
    std::unique_ptr<MpiRun> mpi;
    if (startedByMpirun()) try {
        mpi = std::make_unique<MpiRun>(argc, argv);
    } catch (const std::exception& e) {
        std::cerr << "vdb_isosimp: " << e.what() << "\n";
        return 1;
    }
    const bool writer = !mpi || mpi->rank() == 0;
    CLI::App app{"vdb_isosimp: extract the iso-surface of an OpenVDB grid with Marching Cubes and simplify it\n"
                 "with quadric edge collapse while extracting (the full-resolution surface is never stored).\n"
                 "Output: world space, triangles counter-clockwise seen from outside; the format follows the\n"
                 "extension: .ply (binary; --ascii for text), .obj, .stl (binary), .glb (glTF 2.0 binary).\n"
                 "Exit codes: 0 done, 1 bad input or output, 2 bad usage, 3 no surface at the iso-value."};
    std::string input, output, reportPath, tracePath;
    Options opt;
    double iso = 0.0;
    bool quiet = false, normals = false, ascii = false;

    app.add_option("input", input,
                   "Input .vdb file, or a frame sequence: a run of # (smoke.####.vdb, Houdini's $F4) or a printf\n"
                   "number (smoke.%04d.vdb) in the file name; then -o (and --report, --trace) need a frame\n"
                   "pattern too, and every frame is meshed with the same settings (a fog grid's default\n"
                   "iso-value is taken from the first frame)")
        ->required();
    app.add_option("-o,--output", output,
                   "Output mesh: .ply, .obj, .stl or .glb (by extension). Default: <input stem>.ply in the\n"
                   "current directory");
    app.add_flag("--normals", normals, "Add area-weighted vertex normals (PLY, OBJ, glTF; STL always has face normals)");
    app.add_flag("--ascii", ascii, "Write ASCII PLY instead of binary (.ply only)");
    app.add_option("--grid", opt.gridName, "Grid to mesh (float or double). Default: the first level-set grid of the file, else the grid\n"
                   "named density, else the first float or double grid");
    auto* isoOpt = app.add_option("--iso", iso,
                                  "Iso-value. Default: 0 for level sets (inside: value < iso); for fog and other\n"
                                  "grids (inside: value > iso) the midpoint of the value range, which is printed");
    auto* ratioOpt = app.add_option("-r,--ratio", opt.ratio, "Decimation rate R in (0,1]: faces kept / full faces. R = 1 is the exact Marching Cubes surface,\n"
                   "with its zero-area faces where voxels sit exactly at the iso-value (below 1 none is left)")
                         ->default_val(opt.ratio)
                         ->check(CLI::Range(0.0, 1.0));
    auto* facesOpt = app.add_option("-f,--faces", opt.targetFaces,
                                    "Keep this many faces instead of a ratio (a counting pass finds R: exact, or on\n"
                                    "volumes of more than 2 x --count-sample runs of 64 blocks a sample, see there)")
                         ->check(CLI::PositiveNumber);
    ratioOpt->excludes(facesOpt);
    app.add_option("-b,--batch", opt.batchFaces,
                   "B: room for new faces between two decimations (half holds collapses deferred to a later pass); larger is slower but closer to in-core quality")
        ->default_val(opt.batchFaces)
        ->check(CLI::Range(uint64_t(1000), uint64_t(1) << 40));
    app.add_option("-j,--threads", opt.threads, "Worker threads, 0 = all cores; the output is the same for any count")
        ->default_val(opt.threads)
        ->check(CLI::Range(0, 1024));
    app.add_option("--slab-blocks", opt.blocksPerSlab,
                   "Most blocks (8^3 cells) a slab holds: the volume is cut into a power of two of slabs of equal\n"
                   "block counts, the fewest that hold at most this many (at most 1024 slabs), the independent\n"
                   "pieces threads and MPI ranks share, joined by a fixed merge tree. Changes the output slightly\n"
                   "(more slabs, more seams); threads and ranks never do")
        ->default_val(opt.blocksPerSlab)
        ->check(CLI::Range(uint64_t(1), uint64_t(1) << 40));
    app.add_option("--retire-above", opt.retireAboveFaces,
                   "Faces of a node of the merge tree from which its pass goes to the rate without deferral room;\n"
                   "where two such nodes join, the faces far from every seam are written out and leave the\n"
                   "decimator, so memory holds bands around the seams instead of the whole decimated surface.\n"
                   "Smaller: less memory, a little less quality on large runs. 0: never. Every level of --lods retires")
        ->default_val(opt.retireAboveFaces)
        ->check(CLI::Range(uint64_t(0), uint64_t(1) << 40));
    app.add_option("--count-sample", opt.countSampleRuns,
                   "For --faces on a large volume: count at least this many runs of 64 blocks, one of each run of\n"
                   "consecutive ones, instead of every block, once the volume has twice as many; R is then raised\n"
                   "by three standard errors of the estimate and the final pass takes the rest off. 0: count every block")
        ->default_val(opt.countSampleRuns)
        ->check(CLI::Range(uint64_t(0), uint64_t(1) << 40));
    app.add_option("--report", reportPath, "Also write a JSON report (faces, decimations, memory, time) to this file");
    app.add_option("--trace", tracePath,
                   "Also write one CSV row per decimation: decimation,faces_generated,faces_before,faces_after,\n"
                   "uncontractible,target,slab (for plots of the intermediate mesh size; faces_generated counts\n"
                   "per slab, the last row is the final pass over the merged slabs)");
    app.add_flag("-q,--quiet", quiet, "Print errors only (no progress bar, no summary)");
    std::string framesText;
    auto* framesOpt = app.add_option("--frames", framesText,
                                     "Frames A-B (or one frame A) of a frame sequence; missing files in the range are errors.\n"
                                     "Default: every frame whose file exists in the input's folder");
    auto* minComponentOpt = app.add_option("--min-component", opt.minComponentArea,
                                           "Drop closed components whose area is below A world units squared (floaters),\n"
                                           "after the final decimation; the report counts them (components_pruned)");
    std::string maxMemory = "machine";
    app.add_option("--max-memory", maxMemory,
                   "Refuse to start when the estimated peak memory (from the grid's topology, before any voxel\n"
                   "is read) exceeds SIZE: bytes or K/M/G/T (powers of 1024), 0 for no limit. Default: the\n"
                   "machine's physical memory, or the container's limit when lower")
        ->default_val(maxMemory);

    auto* maxErrorOpt = app.add_option("--max-error", opt.maxError,
                   "E, in world units: no collapse may move the surface by more than E, in the passes during\n"
                   "extraction as in the final one. Alone, E decides the face count; with --ratio or --faces,\n"
                   "whichever stops first. A collapse's displacement is estimated as the larger of\n"
                   "sqrt(cost / weight), the area-weighted RMS distance of the new vertex from the planes of\n"
                   "the faces merged into it (each face weighs its area, at least 0.25 voxel faces), and the\n"
                   "surface's local change (corners, centroids and edge midpoints of the faces around the\n"
                   "edge, before against after and back) added to the drift either end already carries.\n"
                   "The report gives the largest accepted (max_error_accepted)");
    std::vector<double> lods;
    auto* lodsOpt = app.add_option("--lods", lods,
                   "R1,R2,...: a chain of levels of detail from one run, rates decreasing in (0,1]. Writes\n"
                   "STEM_lod0.EXT, STEM_lod1.EXT, ... (STEM and EXT from -o): level 0 is the --ratio R1 mesh;\n"
                   "each slab continues from it to R2, from that to R3, ... Not with --ratio or --faces")
                        ->delimiter(',');
    std::vector<std::string> attributes;
    app.add_option("--attributes", opt.attributes,
                   "NAME[,NAME...]: grids of the input (float, double, vec3) sampled trilinearly at every\n"
                   "output vertex, each in its own index space (its own transform). PLY: vertex properties\n"
                   "NAME (vec3: NAME_x NAME_y NAME_z); glTF: custom attributes _NAME. Not for .obj or .stl")
        ->delimiter(',');
    auto* weightOpt = app.add_option("--attribute-weight", opt.attributeWeight,
                   "W > 0: the simplification also keeps the detail of the first --attributes grid (float or\n"
                   "double): a collapse costs its geometric error plus W^2 times the attribute's error\n"
                   "(Hoppe 1999 attribute quadrics), W in attribute units per world unit");
    lodsOpt->excludes(facesOpt);
    lodsOpt->excludes(ratioOpt);

    if (!writer) {  // rank 0 alone speaks (usage errors, help, the run's errors)
        std::cerr.setstate(std::ios::failbit);
        std::cout.setstate(std::ios::failbit);
    }
    if (const int code = parseCommandLine(app, argc, argv, "vdb_isosimp"); code >= 0) return code;
    if (*maxErrorOpt && !(opt.maxError > 0.0 && std::isfinite(opt.maxError))) {
        std::cerr << "vdb_isosimp: --max-error must be a finite number greater than 0 (see --help)\n";
        return 2;
    }
    if (*weightOpt && (!(opt.attributeWeight > 0.0 && std::isfinite(opt.attributeWeight)) || opt.attributes.empty())) {
        std::cerr << "vdb_isosimp: --attribute-weight must be a finite number greater than 0, with --attributes (see --help)\n";
        return 2;
    }
    // E alone: no face target.
    if (*maxErrorOpt && !*ratioOpt && !*facesOpt && !*lodsOpt) opt.ratio = 0.0;
    for (size_t i = 0; i < lods.size(); ++i)
        if (!(lods[i] > 0.0 && lods[i] <= 1.0) || (i > 0 && !(lods[i] < lods[i - 1]))) {
            std::cerr << "vdb_isosimp: --lods: rates must decrease and lie in (0,1], got '" << lods[i] << "' at position "
                      << i + 1 << " (see --help)\n";
            return 2;
        }
    opt.lods = lods;
    if (*isoOpt) opt.iso = iso;
    if (*isoOpt && !std::isfinite(iso)) {
        std::cerr << "vdb_isosimp: --iso must be a finite number (see --help)\n";
        return 2;
    }
    if (!(opt.ratio > 0.0) && !(opt.ratio == 0.0 && opt.maxError > 0.0 && !*ratioOpt)) {  // also NaN, which CLI11's range check lets through
        std::cerr << "vdb_isosimp: --ratio must be greater than 0 (see --help)\n";
        return 2;
    }
    if (*minComponentOpt && !(opt.minComponentArea > 0.0 && std::isfinite(opt.minComponentArea)))  // NaN, inf
        return usageError("--min-component must be a finite area greater than 0");
    int firstFrame = 0, lastFrame = 0;
    if (*framesOpt && !parseFrameRange(framesText, firstFrame, lastFrame))
        return usageError("--frames: '" + framesText + "' is not a frame range A-B with A <= B (e.g. 1-100), or one frame");
    if (output.empty()) output = stemOf(input) + ".ply";  // a sequence's stem keeps its pattern
    // Checked by the pipeline on the grid it opens (opening it here too cost a second topology read).
    if (maxMemory == "machine") opt.maxMemoryBytes = machineMemoryBytes();
    else if (!parseMemorySize(maxMemory, opt.maxMemoryBytes)) {
        std::cerr << "vdb_isosimp: --max-memory: '" << maxMemory << "' is not a size (e.g. 8G, 512M, 0) (see --help)\n";
        return 2;
    }
    if (!opt.attributes.empty()) {
        try {
            if (!formatHoldsAttributes(formatForPath(output, ascii))) {
                std::cerr << "vdb_isosimp: --attributes: " << output
                          << ": OBJ and STL have no vertex attributes; write .ply or .glb (see --help)\n";
                return 2;
            }
        } catch (const std::exception&) {
        }  // an unsupported extension is reported below, as without attributes
    }
    if (ascii) {
        try {
            formatForPath(output, true);
        } catch (const std::exception& e) {
            std::cerr << "vdb_isosimp: --ascii: " << e.what() << " (see --help)\n";
            return 2;
        }
    }

    const OutputChoices choices{ascii, normals, quiet, mpi.get()};
    const std::optional<FramePattern> inPattern = parseFramePattern(input), outPattern = parseFramePattern(output);
    if (!inPattern) {
        if (*framesOpt) return usageError("--frames: '" + input + "' is not a frame sequence (put # or %04d in its file name)");
        if (outPattern) return usageError("-o '" + output + "' names a frame sequence but the input '" + input + "' does not");
        TerminalProgress bar;
        return meshOne({input, output, reportPath, tracePath}, opt, choices, bar, nullptr);
    }
    if (!outPattern) return usageError("the input '" + input + "' is a frame sequence: -o needs a frame pattern too (# or %04d), got '" + output + "'");
    std::optional<FramePattern> reportPattern, tracePattern;
    for (auto [path, pattern, flag] : {std::make_tuple(&reportPath, &reportPattern, "--report"), std::make_tuple(&tracePath, &tracePattern, "--trace")}) {
        if (path->empty()) continue;
        *pattern = parseFramePattern(*path);
        if (!*pattern) return usageError(std::string(flag) + " '" + *path + "': a frame sequence writes one file per frame, so it needs a frame pattern (# or %04d)");
    }
    std::vector<Frame> frames;
    try {
        frames = *framesOpt ? framePaths(*inPattern, firstFrame, lastFrame) : framePaths(*inPattern);
    } catch (const std::exception& e) {
        std::cerr << "vdb_isosimp: " << input << ": " << e.what() << "\n";
        return 1;
    }
    if (frames.empty()) {
        std::cerr << "vdb_isosimp: " << input << ": no file matches the frame pattern\n";
        return 1;
    }
    return meshSequence(input, *outPattern, reportPattern, tracePattern, frames, opt, choices);
}
