// SPDX-License-Identifier: Apache-2.0
// levelforge_bench — levelforge::meshToLevelSet against openvdb::tools::meshToLevelSet.
//
// For one mesh (optionally Loop-subdivided), one resolution and one band half-width it runs both
// converters in the same process and reports wall time, peak memory, active voxels and the error
// of each grid against the exact reference (levelforge::ExactReference), plus levelforge's own
// counters (distance evaluations per voxel, boundary cells, microtriangles and the paper's
// Table 2 case fractions). See docs/benchmarks.md for how to read the output.
//
//   levelforge_bench mesh.obj --voxel-count 1024 --half-width 3 [--subdivide 2]
//                    [--error-stride N] [--threads N] [--repeat N] [--json out.json] [--skip-openvdb]
//                    [--openvdb-flags both|default|disable-renormalization]
//
// The OpenVDB anchor runs twice by default (--openvdb-flags both): as meshToLevelSet, i.e. with
// its default conversion flags, which renormalize the band (one reinitialization step whose
// minimum with the field lowers values where |grad phi| != 1, so near-surface values move on
// purpose), and as meshToVolume with MeshToVolumeFlags::DISABLE_RENORMALIZATION (the same
// conversion, points transformed the same way, without that step). Both are timed and checked
// against the exact reference; the speed-up is printed against each. Each compared row is also
// printed as one machine-readable line (SPEED label=... levelforge_s=... anchor=... anchor_s=...
// ratio=..., see BenchUtil.h) for scripts/bench --smoke.
//
// Memory: before each method the heap is trimmed (malloc_trim, and tbbmalloc's
// TBBMALLOC_CLEAN_ALL_BUFFERS), VmRSS is read, and the kernel's high-water mark is reset by
// writing "5" to /proc/self/clear_refs. After the method VmHWM is read; "peak" = VmHWM -
// VmRSS(before), i.e. the extra resident memory the method needed at its worst moment,
// including its output grid. The input mesh (and, for OpenVDB, its float copy of the points)
// exists before the measurement starts and is not counted. By default the reported peak comes
// from a fresh process per method (this program re-run with --skip-levelforge/--skip-openvdb),
// because in one process a later run reuses memory the allocators kept from an earlier one;
// the first-run figure of the shared process is printed too. LFB_DEBUG=1 prints the RSS details.

#include <levelforge/core/Exceptions.h>
#include <levelforge/reference/ExactReference.h>
#include <levelforge/io/MeshIO.h>
#include <levelforge/reference/MeshShapes.h>
#include <levelforge/mesh/MeshToLevelSet.h>
#include <levelforge/core/TriangleMesh.h>

#include <openvdb/openvdb.h>
#include <openvdb/tools/MeshToVolume.h>


#include "BenchLoop.h"
#include "BenchUtil.h"

#include <CLI/CLI.hpp>

#include <filesystem>

#include <tbb/global_control.h>
#include <tbb/blocked_range.h>
#include <tbb/info.h>
#include <tbb/parallel_for.h>
#include <tbb/scalable_allocator.h>

#include <fcntl.h>
#include <malloc.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <limits>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

namespace {

using Clock = std::chrono::steady_clock;
double secondsSince(Clock::time_point t0)
{
    return std::chrono::duration<double>(Clock::now() - t0).count();
}

// ------------------------------------------------------------------ memory (Linux /proc)

/// Value of a "Key:   1234 kB" line of /proc/self/status, in kB; -1 if unavailable.
long long procStatusKB(const char* key)
{
    std::ifstream in("/proc/self/status");
    std::string line;
    const size_t n = std::char_traits<char>::length(key);
    while (std::getline(in, line)) {
        if (line.compare(0, n, key) == 0) {
            std::istringstream is(line.substr(n));
            long long v = -1;
            is >> v;
            return v;
        }
    }
    return -1;
}

/// Resets VmHWM to the current RSS (Linux >= 4.0). False if the kernel refused.
bool resetPeakRss()
{
    std::FILE* f = std::fopen("/proc/self/clear_refs", "w");
    if (!f) return false;
    const bool ok = std::fputs("5", f) >= 0;
    return (std::fclose(f) == 0) && ok;
}

struct MemProbe
{
    long long rssBeforeKB = -1;
    bool resetOk = false;
    void start()
    {
        scalable_free(scalable_malloc(16)); // the clean command below crashes if tbbmalloc is not initialised
        // Give freed memory back to the kernel: glibc's heap, and TBB's scalable allocator
        // (libtbbmalloc, used by TBB containers in OpenVDB and levelforge), which keeps its own pools.
        scalable_allocation_command(TBBMALLOC_CLEAN_ALL_BUFFERS, nullptr);
        malloc_trim(0);
        rssBeforeKB = procStatusKB("VmRSS:");
        resetOk = resetPeakRss();
    }
    /// Peak extra RSS since start(), MB; NaN if it could not be measured.
    double peakMB() const
    {
        const long long hwm = procStatusKB("VmHWM:");
        if (!resetOk || hwm < 0 || rssBeforeKB < 0) return std::numeric_limits<double>::quiet_NaN();
        if (const char* dbg = std::getenv("LFB_DEBUG"); dbg && *dbg)
            std::cerr << "  [mem] before rss " << rssBeforeKB << " hwm " << hwm << " now rss " << procStatusKB("VmRSS:")
                      << " anon " << procStatusKB("RssAnon:") << " file " << procStatusKB("RssFile:") << "\n";
        return double(hwm - rssBeforeKB) / 1024.0;
    }
};

std::string selfExe()
{
    std::vector<char> buf(4096);
    const ssize_t n = ::readlink("/proc/self/exe", buf.data(), buf.size() - 1);
    if (n <= 0) throw std::runtime_error("cannot read /proc/self/exe");
    return std::string(buf.data(), size_t(n));
}

/// Runs args[0] with args, stdout to /dev/null (stderr kept); returns its exit status.
int runChild(const std::vector<std::string>& args)
{
    std::vector<char*> argv;
    for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_addopen(&fa, 1, "/dev/null", O_WRONLY, 0);
    pid_t pid = 0;
    const int err = posix_spawn(&pid, argv[0], &fa, nullptr, argv.data(), environ);
    posix_spawn_file_actions_destroy(&fa);
    if (err != 0) return -1;
    int status = 0;
    if (::waitpid(pid, &status, 0) != pid) return -1;
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

// ------------------------------------------------------------------ OpenVDB anchor

/// openvdb::tools::meshToLevelSet with its default flags (renormalize = true), or the same
/// conversion with MeshToVolumeFlags::DISABLE_RENORMALIZATION: meshToLevelSet's own steps for a
/// triangle mesh (points to index space in parallel, QuadAndTriangleDataAdapter, meshToVolume
/// with equal exterior and interior widths), the flag added.
openvdb::FloatGrid::Ptr openVdbLevelSet(const openvdb::math::Transform& xform, const std::vector<openvdb::Vec3s>& points,
                                        const std::vector<openvdb::Vec3I>& triangles, float halfWidth, bool renormalize)
{
    if (renormalize) return openvdb::tools::meshToLevelSet<openvdb::FloatGrid>(xform, points, triangles, halfWidth);
    if (points.empty()) return openvdb::FloatGrid::create(halfWidth);
    std::vector<openvdb::Vec3s> indexPoints(points.size());
    tbb::parallel_for(tbb::blocked_range<size_t>(0, points.size()), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t n = r.begin(); n != r.end(); ++n) {
            const openvdb::Vec3d p = xform.worldToIndex(openvdb::Vec3d(points[n][0], points[n][1], points[n][2]));
            indexPoints[n] = openvdb::Vec3s(float(p[0]), float(p[1]), float(p[2]));
        }
    });
    openvdb::tools::QuadAndTriangleDataAdapter<openvdb::Vec3s, openvdb::Vec3I> adapter(
        indexPoints.data(), indexPoints.size(), triangles.data(), triangles.size());
    return openvdb::tools::meshToVolume<openvdb::FloatGrid>(adapter, xform, halfWidth, halfWidth,
                                                            openvdb::tools::DISABLE_RENORMALIZATION);
}

// ------------------------------------------------------------------ results

struct MethodResult
{
    std::string name;
    bool ran = false;
    std::vector<double> seconds;     // one per repetition
    std::vector<double> peaksMB;     // one per repetition (MB, NaN if unavailable)
    double ownProcessPeakMB = std::numeric_limits<double>::quiet_NaN();  // fresh process, one run
    double ownProcessSeconds = std::numeric_limits<double>::quiet_NaN();
    double gridMB = 0;               // FloatGrid::memUsage() of the output
    uint64_t activeVoxels = 0;
    uint64_t leafNodes = 0;
    levelforge::BandErrorReport err;
    double errorSeconds = 0;
    openvdb::FloatGrid::Ptr grid;
    /// Peak of the first repetition (after the warm-up): nothing of this method's data was retained
    /// by the allocator yet.
    double peakMB() const { return peaksMB.empty() ? std::numeric_limits<double>::quiet_NaN() : peaksMB.front(); }
    double bestSeconds() const { return seconds.empty() ? 0.0 : *std::min_element(seconds.begin(), seconds.end()); }
};

std::string fmt(double v, int prec = 3)
{
    if (std::isnan(v)) return "n/a";
    std::ostringstream os;
    os << std::fixed << std::setprecision(prec) << v;
    return os.str();
}
std::string fmtSci(double v)
{
    if (std::isnan(v)) return "n/a";
    std::ostringstream os;
    os << std::scientific << std::setprecision(2) << v;
    return os.str();
}
std::string fmtInt(uint64_t v)
{
    std::string s = std::to_string(v), o;
    int c = 0;
    for (auto it = s.rbegin(); it != s.rend(); ++it) {
        if (c && c % 3 == 0) o.push_back(',');
        o.push_back(*it);
        ++c;
    }
    return std::string(o.rbegin(), o.rend());
}

std::string jsonEscape(const std::string& s)
{
    std::string o;
    for (char c : s) {
        if (c == '"' || c == '\\') { o.push_back('\\'); o.push_back(c); }
        else if (static_cast<unsigned char>(c) < 0x20) { o += ' '; }
        else o.push_back(c);
    }
    return o;
}
std::string jnum(double v)
{
    if (!std::isfinite(v)) return "null";
    std::ostringstream os;
    os << std::setprecision(10) << v;
    return os.str();
}

} // namespace

int main(int argc, char** argv)
{
    CLI::App app{"levelforge vs openvdb::tools::meshToLevelSet: time, memory, accuracy against the exact reference"};
    std::string meshPath, jsonPath;
    int voxelCount = 1024;
    float halfWidth = 3.0f;
    int subdivide = 0;
    uint64_t errorStride = 0;
    int threads = 0;
    int repeat = 1;
    bool skipOpenVdb = false;
    bool skipLevelforge = false;
    bool openVdbFirst = false;
    bool skipErrors = false;
    app.add_option("mesh", meshPath, "triangle mesh (.obj .off .ply .stl)")->required()->check(CLI::ExistingFile);
    app.add_option("--voxel-count", voxelCount, "voxels along the longest bounding-box axis")->check(CLI::PositiveNumber);
    app.add_option("--half-width", halfWidth, "narrow-band half-width in voxels (both sides)")->check(CLI::PositiveNumber);
    app.add_option("--subdivide", subdivide, "Loop subdivision levels applied to the mesh first (OpenMesh)")->check(CLI::Range(0, 6));
    app.add_option("--error-stride", errorStride,
                   "check every N-th active voxel against the exact reference (0 = auto: at most ~1M voxels)");
    app.add_option("--threads", threads, "TBB threads (0 = all hardware threads)")->check(CLI::NonNegativeNumber);
    app.add_option("--repeat", repeat, "run each method N times; the best time is reported")->check(CLI::Range(1, 100));
    app.add_option("--json", jsonPath, "also write the results as JSON");
    app.add_flag("--skip-openvdb", skipOpenVdb, "run levelforge only");
    std::string openVdbFlags = "both";
    app.add_option("--openvdb-flags", openVdbFlags,
                   "OpenVDB anchor: default (meshToLevelSet, renormalization on), disable-renormalization "
                   "(MeshToVolumeFlags::DISABLE_RENORMALIZATION) or both")
        ->check(CLI::IsMember({"both", "default", "disable-renormalization"}));
    app.add_flag("--skip-levelforge", skipLevelforge, "run OpenVDB only (e.g. to measure its memory in isolation)");
    app.add_flag("--openvdb-first", openVdbFirst, "run OpenVDB before levelforge in each repetition");
    app.add_flag("--skip-errors", skipErrors, "do not compare with the exact reference");
    bool noIsolation = false;
    std::string childOut;
    app.add_flag("--no-memory-isolation", noIsolation,
                 "do not measure each method's peak memory in a fresh process of its own (see docs/benchmarks.md)");
    app.add_option("--memory-child-out", childOut, "internal: run as a measuring child, write results here")->group("");
    CLI11_PARSE(app, argc, argv);
    const bool runOvDefault = !skipOpenVdb && openVdbFlags != "disable-renormalization";
    const bool runOvPlain = !skipOpenVdb && openVdbFlags != "default";

    openvdb::initialize();
    std::unique_ptr<tbb::global_control> threadLimit;
    if (threads > 0)
        threadLimit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, size_t(threads));
    const int usedThreads = int(tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism));

    try {
        // ------------------------------------------------------------ input
        auto t0 = Clock::now();
        levelforge::TriangleMesh mesh = levelforge::readMesh(meshPath);
        const double readSeconds = secondsSince(t0);
        const uint64_t inputFaces = mesh.triangles.size();
        double subdivideSeconds = 0;
        if (subdivide > 0) {
            t0 = Clock::now();
            mesh = levelforge_bench::loopSubdivide(mesh, subdivide);
            subdivideSeconds = secondsSince(t0);
        }

        levelforge::MeshToLevelSetOptions opts;
        opts.voxelCount = voxelCount;
        opts.exteriorWidth = halfWidth;
        opts.interiorWidth = halfWidth;
        const double h = levelforge::resolveVoxelSize(mesh, opts);
        const auto bounds = mesh.bounds();
        const auto ext = bounds.extents();

        std::cout << "mesh          " << meshPath << (subdivide ? " Loop x" + std::to_string(subdivide) : std::string())
                  << "\n              " << fmtInt(mesh.points.size()) << " vertices, " << fmtInt(mesh.triangles.size())
                  << " triangles (input " << fmtInt(inputFaces) << "; read " << fmt(readSeconds, 2) << " s"
                  << (subdivide ? ", subdivision " + fmt(subdivideSeconds, 2) + " s" : std::string()) << ")\n"
                  << "grid          voxel size " << std::setprecision(6) << h << ", " << voxelCount
                  << " voxels along the longest axis (" << int(std::ceil(ext[0] / h)) << " x " << int(std::ceil(ext[1] / h))
                  << " x " << int(std::ceil(ext[2] / h)) << "), half-width " << halfWidth << "\n"
                  << "threads       " << usedThreads << ", repeat " << repeat << " (best time reported)\n"
                  << "versions      OpenVDB " << openvdb::getLibraryAbiVersionString() << ", TBB "
                  << TBB_runtime_version() << "\n" << std::flush;

        // OpenVDB input: float world-space points, Index32 triangles (prepared outside the timing).
        std::vector<openvdb::Vec3s> vdbPoints;
        std::vector<openvdb::Vec3I> vdbTris;
        if (!skipOpenVdb) {
            vdbPoints.reserve(mesh.points.size());
            for (const auto& p : mesh.points) vdbPoints.emplace_back(float(p[0]), float(p[1]), float(p[2]));
            vdbTris.reserve(mesh.triangles.size());
            for (const auto& t : mesh.triangles) vdbTris.emplace_back(t[0], t[1], t[2]);
        }
        // Same index space for both: voxel ijk centred at world ijk*h.
        const openvdb::math::Transform::Ptr xform = openvdb::math::Transform::createLinearTransform(h);

        MethodResult lf, ov, ovp; // ovp: OpenVDB with DISABLE_RENORMALIZATION
        lf.name = "levelforge";
        ov.name = "OpenVDB";
        ovp.name = "OpenVDB no renorm";
        levelforge::MeshToLevelSetStats stats;

        // Start TBB's worker threads (stacks, malloc arenas) before anything is measured, so that
        // neither method is charged for the thread pool.
        tbb::parallel_for(tbb::blocked_range<int>(0, 256, 1), [](const tbb::blocked_range<int>&) {
            std::vector<char> scratch(1 << 16, 1);
            std::this_thread::sleep_for(std::chrono::microseconds(200));
        });

        // Warm-up: one small conversion with each method (an icosphere at 64 voxels), so that the
        // code pages of both libraries are resident and neither method's first run is charged
        // for paging in code (VmHWM counts file-backed pages too).
        {
            const levelforge::TriangleMesh ball = levelforge::makeIcosphere(levelforge::Vec3d(0.0), 1.0, 3);
            levelforge::MeshToLevelSetOptions wo = opts;
            wo.voxelSize = 0.0;
            wo.voxelCount = 64;
            if (!skipLevelforge) (void)levelforge::meshToLevelSet(ball, wo);
            if (!skipOpenVdb) {
                std::vector<openvdb::Vec3s> bp;
                std::vector<openvdb::Vec3I> bt;
                for (const auto& p : ball.points) bp.emplace_back(float(p[0]), float(p[1]), float(p[2]));
                for (const auto& t : ball.triangles) bt.emplace_back(t[0], t[1], t[2]);
                const auto bx = openvdb::math::Transform::createLinearTransform(2.0 / 64);
                if (runOvDefault) (void)openVdbLevelSet(*bx, bp, bt, halfWidth, true);
                if (runOvPlain) (void)openVdbLevelSet(*bx, bp, bt, halfWidth, false);
            }
        }

        auto runLevelforge = [&](int r) {
            lf.grid.reset();
            MemProbe mem;
            mem.start();
            levelforge::MeshToLevelSetStats s;
            const auto t = Clock::now();
            lf.grid = levelforge::meshToLevelSet(mesh, opts, &s);
            lf.seconds.push_back(secondsSince(t));
            lf.peaksMB.push_back(mem.peakMB());
            stats = s;
            lf.ran = true;
            std::cout << "  run " << r + 1 << ": levelforge         " << fmt(lf.seconds.back()) << " s, peak "
                      << fmt(lf.peaksMB.back(), 1) << " MB\n" << std::flush;
        };
        auto runOpenVdbOne = [&](MethodResult& m, bool renormalize, int r) {
            m.grid.reset();
            MemProbe mem;
            mem.start();
            const auto t = Clock::now();
            m.grid = openVdbLevelSet(*xform, vdbPoints, vdbTris, halfWidth, renormalize);
            m.seconds.push_back(secondsSince(t));
            m.peaksMB.push_back(mem.peakMB());
            m.ran = true;
            std::cout << "  run " << r + 1 << ": " << std::left << std::setw(18) << m.name << std::right << " "
                      << fmt(m.seconds.back()) << " s, peak " << fmt(m.peaksMB.back(), 1) << " MB\n" << std::flush;
        };
        auto runOpenVdb = [&](int r) {
            if (runOvDefault) runOpenVdbOne(ov, true, r);
            if (runOvPlain) runOpenVdbOne(ovp, false, r);
        };
        // Peak memory of each method in a fresh process of its own (the same program, one method,
        // one run, no error check). In one process, memory the allocators kept from an earlier
        // run is reused by a later one and hides part of its peak; see docs/benchmarks.md.
        if (childOut.empty() && !noIsolation) {
            for (MethodResult* m : {&lf, &ov, &ovp}) {
                if ((m == &lf && skipLevelforge) || (m == &ov && !runOvDefault) || (m == &ovp && !runOvPlain)) continue;
                const std::string out = "/tmp/levelforge_bench_child_" + std::to_string(::getpid()) + ".txt";
                std::vector<std::string> args = {selfExe(), meshPath, "--voxel-count", std::to_string(voxelCount),
                                                 "--half-width", fmt(halfWidth, 6), "--subdivide", std::to_string(subdivide),
                                                 "--threads", std::to_string(threads), "--repeat", "1", "--skip-errors",
                                                 m == &lf ? "--skip-openvdb" : "--skip-levelforge", "--memory-child-out", out};
                if (m != &lf) {
                    args.push_back("--openvdb-flags");
                    args.push_back(m == &ov ? "default" : "disable-renormalization");
                }
                std::cout << "  own process: " << m->name << " ..." << std::flush;
                const int rc = runChild(args);
                std::ifstream in(out);
                double pk = std::numeric_limits<double>::quiet_NaN(), sec = pk;
                if (rc != 0 || !(in >> pk >> sec))
                    throw std::runtime_error("memory measurement child for " + m->name + " failed (exit " + std::to_string(rc) + ")");
                std::remove(out.c_str());
                m->ownProcessPeakMB = pk;
                m->ownProcessSeconds = sec;
                std::cout << " " << fmt(sec) << " s, peak " << fmt(pk, 1) << " MB\n" << std::flush;
            }
        }

        for (int r = 0; r < repeat; ++r) {
            if (openVdbFirst && !skipOpenVdb) runOpenVdb(r);
            if (!skipLevelforge) runLevelforge(r);
            if (!openVdbFirst && !skipOpenVdb) runOpenVdb(r);
        }
        if (!childOut.empty()) {
            const MethodResult& m = lf.ran ? lf : ov.ran ? ov : ovp;
            std::ofstream out(childOut);
            out << std::setprecision(10) << m.peakMB() << " " << m.bestSeconds() << "\n";
            return out ? 0 : 1;
        }
        for (MethodResult* m : {&lf, &ov, &ovp}) {
            if (!m->ran) continue;
            m->activeVoxels = m->grid->activeVoxelCount();
            m->leafNodes = m->grid->tree().leafCount();
            m->gridMB = double(m->grid->memUsage()) / (1024.0 * 1024.0);
        }

        // ------------------------------------------------------------ accuracy
        uint64_t stride = errorStride;
        double refBuildSeconds = 0;
        if (!skipErrors) {
            if (stride == 0) {
                const uint64_t n = std::max({lf.activeVoxels, ov.ran ? ov.activeVoxels : 0, ovp.ran ? ovp.activeVoxels : 0});
                stride = std::max<uint64_t>(1, (n + 999'999) / 1'000'000);
            }
            t0 = Clock::now();
            levelforge::ExactReference ref(mesh);
            refBuildSeconds = secondsSince(t0);
            for (MethodResult* m : {&lf, &ov, &ovp}) {
                if (!m->ran) continue;
                t0 = Clock::now();
                m->err = levelforge::compareToReference(*m->grid, ref, halfWidth, halfWidth, stride);
                m->errorSeconds = secondsSince(t0);
            }
        }

        // ------------------------------------------------------------ report
        auto speedup = [&](const MethodResult& m) {
            return (lf.ran && m.ran && lf.bestSeconds() > 0) ? m.bestSeconds() / lf.bestSeconds()
                                                            : std::numeric_limits<double>::quiet_NaN();
        };
        const double ratio = speedup(ov), ratioPlain = speedup(ovp);
        const double M = double(std::max<uint64_t>(1, stats.microtriangles));
        const double c12 = double(stats.caseCounts[0] + stats.caseCounts[1]) / M;
        const double c3 = double(stats.caseCounts[2]) / M, c4 = double(stats.caseCounts[3]) / M;
        const std::string na = "n/a";

        // columns: levelforge, OpenVDB (default flags), OpenVDB with DISABLE_RENORMALIZATION (when run)
        struct Row
        {
            std::string label, a, b, c;
            Row(std::string l, std::string x, std::string y, std::string z)
                : label(std::move(l)), a(std::move(x)), b(std::move(y)), c(std::move(z)) {}
            Row(std::string l, std::string x, std::string y) : Row(std::move(l), std::move(x), y, y) {} // c as b
        };
        std::vector<Row> rows;
        auto both = [&](const std::string& label, auto f) {
            rows.push_back({label, lf.ran ? f(lf) : std::string("-"), ov.ran ? f(ov) : std::string("-"),
                            ovp.ran ? f(ovp) : std::string("-")});
        };
        both("time, s (best of " + std::to_string(repeat) + ")", [](const MethodResult& m) { return fmt(m.bestSeconds()); });
        auto fmtRatio = [&](double r) { return std::isnan(r) ? std::string("n/a") : fmt(r, 2) + "x"; };
        rows.push_back({"speed-up (OpenVDB time / levelforge time)", "", fmtRatio(ratio), fmtRatio(ratioPlain)});
        both("peak memory, MB (own process)", [](const MethodResult& m) { return fmt(m.ownProcessPeakMB, 1); });
        both("peak memory, MB (this process, run 1)", [](const MethodResult& m) { return fmt(m.peakMB(), 1); });
        both("output grid memUsage, MB", [](const MethodResult& m) { return fmt(m.gridMB, 1); });
        both("active voxels", [](const MethodResult& m) { return fmtInt(m.activeVoxels); });
        both("leaf nodes", [](const MethodResult& m) { return fmtInt(m.leafNodes); });
        if (!skipErrors) {
            rows.push_back({"error check: every N-th active voxel, N =", std::to_string(stride), ""});
            both("voxels checked", [](const MethodResult& m) { return fmtInt(m.err.checkedVoxels); });
            both("max |error|, voxels", [](const MethodResult& m) { return fmtSci(m.err.maxError); });
            both("mean |error|, voxels", [](const MethodResult& m) { return fmtSci(m.err.meanError); });
            both("sign errors (checked voxels)", [](const MethodResult& m) { return fmtInt(m.err.signErrors); });
            both("missing band voxels (next to checked)", [](const MethodResult& m) { return fmtInt(m.err.missingVoxels); });
            both("extra voxels (exact |d| outside band)", [](const MethodResult& m) { return fmtInt(m.err.extraVoxels); });
        }
        rows.push_back({"distance evaluations / active voxel", fmt(stats.evaluationsPerActiveVoxel(), 3), na});
        rows.push_back({"distance evaluations", fmtInt(stats.distanceEvaluations), na});
        rows.push_back({"bound tests (evaluations avoided)", fmtInt(stats.boundTests), na});
        rows.push_back({"candidate voxels", fmtInt(stats.candidateVoxels), na});
        rows.push_back({"boundary cells (Table 1 B-cell)", fmtInt(stats.boundaryCells), na});
        rows.push_back({"local cells (Table 3 L-cell)", fmtInt(stats.localCells), na});
        rows.push_back({"triangle-list entries / boundary cell",
                        fmt(stats.boundaryCells ? double(stats.triangleListEntries) / double(stats.boundaryCells) : 0.0, 2), na});
        rows.push_back({"microtriangles (Table 2 M-tri)", fmtInt(stats.microtriangles), na});
        rows.push_back({"case fractions C1,2 / C3 / C4", fmt(c12, 3) + " / " + fmt(c3, 3) + " / " + fmt(c4, 3), na});
        rows.push_back({"levelforge stages, s: voxelize/lists/distance/finish",
                        fmt(stats.secondsVoxelize, 2) + "/" + fmt(stats.secondsLists, 2) + "/" +
                            fmt(stats.secondsDistance, 2) + "/" + fmt(stats.secondsFinish, 2), ""});
        if (!skipErrors)
            both("(error check time, s)", [](const MethodResult& m) { return fmt(m.errorSeconds, 1); });

        const bool third = ovp.ran;
        size_t w0 = 0, w1 = 10, w2 = 7;
        for (const Row& r : rows) {
            w0 = std::max(w0, r.label.size());
            w1 = std::max(w1, r.a.size());
            w2 = std::max(w2, r.b.size());
        }
        std::cout << "\n" << std::left << std::setw(int(w0)) << "" << "  " << std::right << std::setw(int(w1))
                  << "levelforge" << "  " << std::setw(int(w2)) << "OpenVDB" << (third ? "  OpenVDB, no renormalization" : "")
                  << "\n";
        for (const Row& r : rows) {
            std::cout << std::left << std::setw(int(w0)) << r.label << "  " << std::right << std::setw(int(w1)) << r.a
                      << "  " << std::setw(int(w2)) << r.b;
            if (third) std::cout << "  " << r.c;
            std::cout << "\n";
        }
        if (ovp.ran)
            std::cout << "(OpenVDB = meshToLevelSet, default flags: renormalization on; no renormalization = meshToVolume "
                         "with MeshToVolumeFlags::DISABLE_RENORMALIZATION)\n";
        if (repeat > 1) {
            for (const MethodResult* m : {&lf, &ov, &ovp}) {
                if (!m->ran) continue;
                std::cout << "all runs, " << m->name << ": seconds";
                for (double s : m->seconds) std::cout << " " << fmt(s);
                std::cout << "; peak MB";
                for (double p : m->peaksMB) std::cout << " " << fmt(p, 1);
                std::cout << "\n";
            }
        }
        if (!skipErrors) std::cout << "(reference BVH built in " << fmt(refBuildSeconds, 2) << " s)\n";
        // machine-readable comparison lines (scripts/bench --smoke): best times of this process
        {
            std::string label = std::filesystem::path(meshPath).stem().string() + "@" + std::to_string(voxelCount) + "/hw" +
                                levelforge_bench::shortNumber(halfWidth);
            if (subdivide) label += "/loop" + std::to_string(subdivide);
            if (threads > 0) label += "/t" + std::to_string(threads);
            if (lf.ran && ov.ran)
                std::cout << levelforge_bench::speedLine(label, lf.bestSeconds(), "openvdb_meshToLevelSet", ov.bestSeconds());
            if (lf.ran && ovp.ran)
                std::cout << levelforge_bench::speedLine(label + "/no-renorm", lf.bestSeconds(),
                                                 "openvdb_meshToVolume_no_renormalization", ovp.bestSeconds());
        }
        std::cout << std::flush;

        // ------------------------------------------------------------ JSON
        if (!jsonPath.empty()) {
            std::ostringstream js;
            auto method = [&](const MethodResult& m) {
                std::ostringstream o;
                o << "{\"ran\": " << (m.ran ? "true" : "false") << ", \"seconds_best\": " << jnum(m.bestSeconds())
                  << ", \"seconds\": [";
                for (size_t i = 0; i < m.seconds.size(); ++i) o << (i ? ", " : "") << jnum(m.seconds[i]);
                o << "], \"peak_mb_own_process\": " << jnum(m.ownProcessPeakMB)
                  << ", \"seconds_own_process\": " << jnum(m.ownProcessSeconds)
                  << ", \"peak_mb\": " << jnum(m.peakMB()) << ", \"peaks_mb\": [";
                for (size_t i = 0; i < m.peaksMB.size(); ++i) o << (i ? ", " : "") << jnum(m.peaksMB[i]);
                o << "]" << ", \"grid_mb\": " << jnum(m.gridMB)
                  << ", \"active_voxels\": " << m.activeVoxels << ", \"leaf_nodes\": " << m.leafNodes;
                if (!skipErrors)
                    o << ", \"checked_voxels\": " << m.err.checkedVoxels << ", \"max_error_voxels\": " << jnum(m.err.maxError)
                      << ", \"mean_error_voxels\": " << jnum(m.err.meanError) << ", \"sign_errors\": " << m.err.signErrors
                      << ", \"missing_voxels\": " << m.err.missingVoxels << ", \"extra_voxels\": " << m.err.extraVoxels;
                o << "}";
                return o.str();
            };
            js << "{\n  \"mesh\": \"" << jsonEscape(meshPath) << "\",\n  \"subdivide\": " << subdivide
               << ",\n  \"vertices\": " << mesh.points.size() << ",\n  \"triangles\": " << mesh.triangles.size()
               << ",\n  \"voxel_count\": " << voxelCount << ",\n  \"voxel_size\": " << jnum(h)
               << ",\n  \"half_width\": " << jnum(halfWidth) << ",\n  \"threads\": " << usedThreads
               << ",\n  \"repeat\": " << repeat << ",\n  \"error_stride\": " << (skipErrors ? 0 : stride)
               << ",\n  \"openvdb_version\": \"" << openvdb::getLibraryAbiVersionString() << "\""
               << ",\n  \"openvdb_flags\": \"" << openVdbFlags << "\""
               << ",\n  \"speedup\": " << jnum(ratio)
               << ",\n  \"speedup_no_renormalization\": " << jnum(ratioPlain)
               << ",\n  \"levelforge\": " << method(lf) << ",\n  \"openvdb\": " << method(ov)
               << ",\n  \"openvdb_no_renormalization\": " << method(ovp)
               << ",\n  \"levelforge_stats\": {\"distance_evaluations\": " << stats.distanceEvaluations
               << ", \"evaluations_per_active_voxel\": " << jnum(stats.evaluationsPerActiveVoxel())
               << ", \"bound_tests\": " << stats.boundTests << ", \"candidate_voxels\": " << stats.candidateVoxels
               << ", \"boundary_cells\": " << stats.boundaryCells << ", \"local_cells\": " << stats.localCells
               << ", \"triangle_list_entries\": " << stats.triangleListEntries
               << ", \"microtriangles\": " << stats.microtriangles << ", \"case_counts\": [" << stats.caseCounts[0]
               << ", " << stats.caseCounts[1] << ", " << stats.caseCounts[2] << ", " << stats.caseCounts[3] << "]"
               << ", \"case_fraction_c12\": " << jnum(c12) << ", \"case_fraction_c3\": " << jnum(c3)
               << ", \"case_fraction_c4\": " << jnum(c4) << ", \"skipped_degenerate\": " << stats.skippedDegenerate
               << ", \"seconds_voxelize\": " << jnum(stats.secondsVoxelize) << ", \"seconds_lists\": "
               << jnum(stats.secondsLists) << ", \"seconds_distance\": " << jnum(stats.secondsDistance)
               << ", \"seconds_finish\": " << jnum(stats.secondsFinish) << "}\n}\n";
            std::ofstream out(jsonPath);
            out << js.str();
            if (!out) throw levelforge::IoError("cannot write " + jsonPath);
        }
    } catch (const std::exception& e) {
        std::cerr << "levelforge_bench: " << e.what() << "\n";
        return 1;
    }
    return 0;
}
