// SPDX-License-Identifier: Apache-2.0
// levelforge_bench_dt: the dense distance transforms of Satherley & Jones, measured
// the way the paper's tables are: every chamfer transform (Table 1), EVDT / EVDT full grid /
// VCVDT (Tables 2, 4, 5) and the 8-pass VCVDT (Table 6), each on a signed field (features =
// transverse voxels, sign by Eq. 5-6) against the exact EDT, plus throughput (Mvoxels/s) of the
// vector transforms and of the exact linear-time EDT.
//
//   levelforge_bench_dt [--repeats 3] [--big 256] [--pawn mesh.stl] [--pawn-res 60]
//                       [--volume path --iso t] [--no-chamfer] [--digest]
//
// --digest prints, instead of the tables, an FNV-1a hash of every output vector (all four
// floats, bit for bit) of each vector method at 1 and 2 lanes on every dataset, plus a
// synthetic anisotropic volume with fractional (sub-voxel) seeds: any change to a kernel must
// leave these digests unchanged.
//
// Datasets: the 80^3 sphere (centre 39.5, radius 29.5 voxels: its exact distance range ends
// at the paper's 39.268); chess_pawn.stl voxelized at 60^3 (inside = the sign of the exact
// reference at each voxel centre, ExactReference.h); a --volume scalar file thresholded at
// --iso (f >= iso is inside, Eq. 2) when given; the 256^3 sphere for throughput only.
// Prints markdown (docs/benchmarks.md, "Volume distance transforms"). Times are the best of --repeats runs.
#include <levelforge/volume/ChamferDistanceTransform.h>
#include <levelforge/volume/ExactDistanceTransform.h>
#include <levelforge/reference/ExactReference.h>
#include <levelforge/io/MeshIO.h>
#include <levelforge/volume/VectorDistanceTransform.h>
#if __has_include(<levelforge/io/VolumeIO.h>)
#include <levelforge/io/VolumeIO.h>
#define LEVELFORGE_BENCH_HAVE_VOLUMEIO 1
#endif

#include <tbb/blocked_range.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <random>
#include <string>
#include <vector>

#include "BenchUtil.h"

using namespace levelforge;
using Clock = std::chrono::steady_clock;
using levelforge_bench::since;

namespace {

struct Dataset
{
    std::string name;  ///< shown in the tables
    std::string paper; ///< key of the paper's numbers ("sphere", "pawn", "cthead") or empty
    MaskVolume inside;
};

std::string loadAverage()
{
    std::ifstream f("/proc/loadavg");
    std::string a, b, c;
    f >> a >> b >> c;
    return a + " " + b + " " + c;
}

Dataset sphere(int n, double centre, double radius)
{
    Dataset d;
    char buf[128];
    std::snprintf(buf, sizeof buf, "sphere %d^3 (centre %.1f, radius %.1f voxels)", n, centre, radius);
    d.name = buf;
    d.paper = n == 80 ? "sphere" : "";
    d.inside = MaskVolume(openvdb::Coord(n), 0);
    tbb::parallel_for(0, n, [&](int k) {
        for (int j = 0; j < n; ++j)
            for (int i = 0; i < n; ++i) {
                const double x = i - centre, y = j - centre, z = k - centre;
                d.inside(i, j, k) = x * x + y * y + z * z <= radius * radius ? 1 : 0;
            }
    });
    return d;
}

/// Voxelizes a closed mesh at res^3 cubic voxels (2 voxels of margin around its bounding box);
/// inside = negative exact signed distance at the voxel centre.
Dataset voxelizeMesh(const std::string& path, int res)
{
    const TriangleMesh mesh = readMesh(path);
    const ExactReference ref(mesh);
    const BBoxd box = mesh.bounds();
    const Vec3d ext = box.extents();
    const double h = std::max({ext[0], ext[1], ext[2]}) / double(res - 4);
    const Vec3d c = box.getCenter();
    Dataset d;
    d.name = std::filesystem::path(path).filename().string() + " " + std::to_string(res) + "^3";
    d.paper = std::filesystem::path(path).filename().string().find("pawn") != std::string::npos ? "pawn" : "";
    d.inside = MaskVolume(openvdb::Coord(res), 0, Vec3d(h), c - Vec3d(0.5 * (res - 1) * h));
    tbb::parallel_for(0, res, [&](int k) {
        for (int j = 0; j < res; ++j)
            for (int i = 0; i < res; ++i)
                d.inside(i, j, k) = ref.signedDistance(d.inside.worldPosition(i, j, k)) <= 0.0 ? 1 : 0;
    });
    return d;
}

// The paper's numbers (Tables 1, 2, 4, 5, 6): time (s, Athlon 800) | error range | average.
const std::map<std::string, std::map<std::string, std::string>>& paperNumbers()
{
    static const std::map<std::string, std::map<std::string, std::string>> p = {
        {"sphere",
         {{"EVDT", "0.284 / -1.659 .. 1.984 / 0.010045"},
          {"EVDTFullGrid", "0.424 / – / 0.005282"},
          {"VCVDT4", "0.204 / – / 0.002734"},
          {"VCVDT8", "0.302 / -0.268 .. 0.268 / 0.000559"},
          {"Euclidean (exact EDT)", "1212.410 (brute force) / 0 / 0"}}},
        {"pawn",
         {{"EVDT", "0.116 / -0.394 .. 1.013 / 0.009697"},
          {"EVDTFullGrid", "0.184 / – / 0.001683"},
          {"VCVDT4", "0.094 / – / 0.001546"},
          {"VCVDT8", "0.134 / -0.310 .. 0.278 / 0.000233"},
          {"Euclidean (exact EDT)", "98.650 (brute force) / 0 / 0"}}},
        {"cthead",
         {{"City-block", "1.320 / -2.000 .. 76.060 / 12.269071"},
          {"Chess board", "3.176 / -26.924 .. 1.243 / 5.356728"},
          {"Quasi-Euclidean 3^3", "3.236 / -0.828 .. 22.428 / 3.365570"},
          {"Complete 3^3", "4.842 / -0.415 .. 11.769 / 2.196785"},
          {"Quasi-Euclidean 5^3", "20.438 / -0.363 .. 5.149 / 0.612223"},
          {"EVDT", "7.540 / -0.518 .. 2.533 / 0.004761"},
          {"EVDTFullGrid", "6.348 / -0.504 .. 1.053 / 0.000786"},
          {"VCVDT4", "3.420 / -0.334 .. 0.446 / 0.000644"},
          {"VCVDT8", "5.470 / -0.334 .. 0.334 / 0.000223"},
          {"Euclidean (exact EDT)", "2.5+ hours (brute force) / 0 / 0"}}}};
    return p;
}

std::string paperFor(const Dataset& d, const std::string& method)
{
    const auto& p = paperNumbers();
    const auto it = p.find(d.paper);
    if (it == p.end()) return "";
    const auto jt = it->second.find(method);
    return jt == it->second.end() ? "" : jt->second;
}

struct Summary
{
    std::string dataset;
    double evdtGridSeconds = 0, vcvdtSeconds = 0, vcvdt8Seconds = 0;
    double evdtGridError = 0, vcvdtError = 0, vcvdt8Error = 0;
};

Summary accuracyTables(const Dataset& d, int repeats, bool chamfer)
{
    const MaskVolume f = transverseFeatures(d.inside);
    uint64_t nf = 0;
    for (auto v : f.data) nf += v;
    std::printf("\n### %s\n\n", d.name.c_str());
    std::printf("%d x %d x %d voxels, spacing %g x %g x %g, %llu feature (transverse) voxels.\n\n",
                d.inside.dims.x(), d.inside.dims.y(), d.inside.dims.z(), d.inside.spacing[0], d.inside.spacing[1],
                d.inside.spacing[2], (unsigned long long)nf);
    DistanceTransformReportOptions o;
    o.chamfer = chamfer;
    o.repeats = repeats;
    const auto rows = distanceTransformReport(d.inside, o);
    const bool withPaper = !d.paper.empty();
    std::printf("| Distance transform | Time (s) | Distance min | max | Error min | max | Average error per voxel |%s\n",
                withPaper ? " Paper: time (s) / error range / average |" : "");
    std::printf("|---|---:|---:|---:|---:|---:|---:|%s\n", withPaper ? "---|" : "");
    Summary s;
    s.dataset = d.name;
    for (const auto& r : rows) {
        std::printf("| %s | %.4f | %.3f | %.3f | %.3f | %.3f | %.6f |", r.method.c_str(), r.seconds, r.minDistance,
                    r.maxDistance, r.minError, r.maxError, r.averageErrorPerVoxel);
        if (withPaper) std::printf(" %s |", paperFor(d, r.method).c_str());
        std::printf("\n");
        if (r.method == "EVDTFullGrid") s.evdtGridSeconds = r.seconds, s.evdtGridError = r.averageErrorPerVoxel;
        if (r.method == "VCVDT4") s.vcvdtSeconds = r.seconds, s.vcvdtError = r.averageErrorPerVoxel;
        if (r.method == "VCVDT8") s.vcvdt8Seconds = r.seconds, s.vcvdt8Error = r.averageErrorPerVoxel;
    }
    std::fflush(stdout);
    return s;
}

/// Throughput of the propagation alone (vectors initialised outside the timing).
void throughput(const Dataset& d, int repeats)
{
    const MaskVolume f = transverseFeatures(d.inside);
    const double voxels = double(f.voxelCount());
    auto best = [&](const auto& fn) {
        double t = 1e30;
        for (int r = 0; r < repeats; ++r) t = std::min(t, fn());
        return t;
    };
    auto row = [&](const char* method, const char* threads, double seconds) {
        std::printf("| %s | %s | %s | %.4f | %.1f |\n", d.name.c_str(), method, threads, seconds, voxels / seconds / 1e6);
        std::fflush(stdout);
    };
    const VectorVolume seeds = initVectorVolume(f);
    for (VectorTransformMethod m : {VectorTransformMethod::VCVDT8, VectorTransformMethod::VCVDT4,
                                    VectorTransformMethod::EVDTFullGrid, VectorTransformMethod::EVDT}) {
        for (int lanes : {1, 0}) {
            if (lanes == 0 && (m == VectorTransformMethod::EVDT || m == VectorTransformMethod::EVDTFullGrid)) continue;
            int used = 1;
            const double t = best([&] {
                VectorVolume v = seeds;
                VectorTransformOptions o;
                o.method = m;
                o.threads = lanes == 0 ? tbb::this_task_arena::max_concurrency() : 1;
                VectorTransformStats st;
                vectorDistanceTransform(v, o, &st);
                used = st.lanes;
                return st.seconds;
            });
            const std::string th = std::to_string(used) + (used > 1 ? " (column lanes)" : "");
            row(vectorTransformMethodName(m), th.c_str(), t);
        }
    }
    // End to end like the EDT row below (mask in, distances out, allocations included): the
    // mask entry point (slice buffers, 16-bit vectors between the sweeps), then the route through
    // a 16-byte vector volume (initVectorVolume, in-place transform, vectorLength).
    for (VectorTransformMethod m : {VectorTransformMethod::VCVDT8, VectorTransformMethod::VCVDT4}) {
        for (int lanes : {1, 0}) {
            int used = 1;
            const double t = best([&] {
                const auto t0 = Clock::now();
                VectorTransformOptions o;
                o.method = m;
                o.threads = lanes == 0 ? tbb::this_task_arena::max_concurrency() : 1;
                VectorTransformStats st;
                const ScalarVolume d = vectorDistanceTransform(f, o, &st);
                used = st.lanes;
                return since(t0);
            });
            const std::string th = std::to_string(used) + (used > 1 ? " (column lanes)" : "");
            row((std::string(vectorTransformMethodName(m)) + " end to end (mask to distances)").c_str(), th.c_str(), t);
        }
    }
    for (int lanes : {1, 0}) {
        int used = 1;
        const double t = best([&] {
            const auto t0 = Clock::now();
            VectorVolume v = initVectorVolume(f);
            VectorTransformOptions o;
            o.threads = lanes == 0 ? tbb::this_task_arena::max_concurrency() : 1;
            VectorTransformStats st;
            vectorDistanceTransform(v, o, &st);
            used = st.lanes;
            const ScalarVolume d = vectorLength(v);
            return since(t0);
        });
        const std::string th = std::to_string(used) + (used > 1 ? " (column lanes)" : "");
        row("VCVDT8 via a vector volume (init, in place, length)", th.c_str(), t);
    }
    for (int threads : {1, 0}) {
        const int n = threads == 0 ? tbb::this_task_arena::max_concurrency() : 1;
        tbb::global_control gc(tbb::global_control::max_allowed_parallelism, size_t(n));
        const double t = best([&] {
            const auto t0 = Clock::now();
            const ScalarVolume e = exactDistanceTransform(f);
            return since(t0);
        });
        row("exact EDT (Felzenszwalb-Huttenlocher)", (std::to_string(n) + " (TBB)").c_str(), t);
    }
    {
        const double t = best([&] {
            const auto t0 = Clock::now();
            const ScalarVolume c = chamferDistanceTransform(f, ChamferMetric::CityBlock);
            return since(t0);
        });
        row("city-block chamfer", "auto", t);
    }
}

uint64_t fnv1a(const void* p, size_t n, uint64_t h = 1469598103934665603ull)
{
    const unsigned char* b = static_cast<const unsigned char*>(p);
    for (size_t i = 0; i < n; ++i) h = (h ^ b[i]) * 1099511628211ull;
    return h;
}

/// Digests of every vector method (1 and 2 lanes) from the given seeds.
void digestRows(const std::string& name, const VectorVolume& seeds)
{
    for (VectorTransformMethod m : {VectorTransformMethod::VCVDT8, VectorTransformMethod::VCVDT4,
                                    VectorTransformMethod::EVDTFullGrid, VectorTransformMethod::EVDT}) {
        for (int lanes : {1, 2}) {
            VectorVolume v = seeds;
            VectorTransformOptions o;
            o.method = m;
            o.threads = lanes;
            VectorTransformStats st;
            vectorDistanceTransform(v, o, &st);
            std::printf("digest | %s | %s | %d lane(s) (%d used) | %016llx |\n", name.c_str(),
                        vectorTransformMethodName(m), lanes, st.lanes,
                        (unsigned long long)fnv1a(v.data.data(), v.data.size() * sizeof(ClosestVector)));
            std::fflush(stdout);
        }
    }
}

/// Digests of the mask entry's distances (every method, 1 and 2 lanes).
void digestMaskRows(const std::string& name, const MaskVolume& features)
{
    for (VectorTransformMethod m : {VectorTransformMethod::VCVDT8, VectorTransformMethod::VCVDT4,
                                    VectorTransformMethod::EVDTFullGrid, VectorTransformMethod::EVDT}) {
        for (int lanes : {1, 2}) {
            VectorTransformOptions o;
            o.method = m;
            o.threads = lanes;
            VectorTransformStats st;
            const ScalarVolume d = vectorDistanceTransform(features, o, &st);
            std::printf("digest | %s | %s, mask entry (distances) | %d lane(s) (%d used) | %016llx |\n",
                        name.c_str(), vectorTransformMethodName(m), lanes, st.lanes,
                        (unsigned long long)fnv1a(d.data.data(), d.data.size() * sizeof(float)));
            std::fflush(stdout);
        }
    }
}

/// Anisotropic volume with odd dims and fractional seeds (sub-voxel shells, Section 4).
VectorVolume fractionalSeeds()
{
    VectorVolume v;
    v.dims = openvdb::Coord(67, 45, 53);
    v.spacing = Vec3d(0.7, 1.3, 1.1);
    const float inf = std::numeric_limits<float>::infinity();
    v.data.assign(size_t(67) * 45 * 53, ClosestVector{inf, inf, inf, inf});
    std::mt19937 rng(12345);
    std::uniform_real_distribution<float> u(-0.5f, 0.5f);
    std::uniform_int_distribution<size_t> pick(0, v.data.size() - 1);
    const openvdb::Vec3f sp(0.7f, 1.3f, 1.1f);
    for (int i = 0; i < 300; ++i) {
        ClosestVector& c = v.data[pick(rng)];
        c.x = u(rng), c.y = u(rng), c.z = u(rng);
        c.d2 = vectorLengthSquared(c.x, c.y, c.z, sp);
    }
    return v;
}

} // namespace

int main(int argc, char** argv)
{
    int repeats = 3, big = 256, pawnRes = 60;
    bool chamfer = true;
    std::string pawn = "/work/shared/data/meshes/watertight/chess_pawn.stl";
    if (const char* env = std::getenv("LEVELFORGE_SHARED_DATA")) pawn = std::string(env) + "/meshes/watertight/chess_pawn.stl";
    std::string volumePath;
    double iso = 0.0;
    bool haveIso = false;
    bool digest = false;
    for (int a = 1; a < argc; ++a) {
        const std::string arg = argv[a];
        auto next = [&]() -> const char* {
            if (a + 1 >= argc) {
                std::fprintf(stderr, "levelforge_bench_dt: %s needs a value\n", arg.c_str());
                std::exit(2);
            }
            return argv[++a];
        };
        if (arg == "--repeats") repeats = std::max(1, std::atoi(next()));
        else if (arg == "--big") big = std::atoi(next());
        else if (arg == "--pawn") pawn = next();
        else if (arg == "--pawn-res") pawnRes = std::atoi(next());
        else if (arg == "--volume") volumePath = next();
        else if (arg == "--iso") iso = std::atof(next()), haveIso = true;
        else if (arg == "--no-chamfer") chamfer = false;
        else if (arg == "--digest") digest = true;
        else {
            std::fprintf(stderr,
                         "usage: levelforge_bench_dt [--repeats 3] [--big 256] [--pawn mesh.stl] [--pawn-res 60]\n"
                         "                           [--volume path --iso t] [--no-chamfer] [--digest]\n");
            return 2;
        }
    }
    std::printf("<!-- levelforge_bench_dt: load average at start %s, %d TBB threads -->\n", loadAverage().c_str(),
                tbb::this_task_arena::max_concurrency());
    try {
        std::vector<Dataset> sets;
        sets.push_back(sphere(80, 39.5, 29.5));
        if (std::filesystem::exists(pawn)) sets.push_back(voxelizeMesh(pawn, pawnRes));
        else std::printf("\n(%s not found: pawn skipped)\n", pawn.c_str());
        if (!volumePath.empty()) {
#ifdef LEVELFORGE_BENCH_HAVE_VOLUMEIO
            if (!haveIso) {
                std::fprintf(stderr, "levelforge_bench_dt: --volume needs --iso\n");
                return 2;
            }
            const ScalarVolume v = readVolume(volumePath);
            Dataset d;
            d.name = std::filesystem::path(volumePath).filename().string() + " (iso " + std::to_string(iso) + ")";
            d.paper = volumePath.find("skull") != std::string::npos ? "cthead" : "";
            d.inside = insideMask(v, float(iso));
            sets.push_back(std::move(d));
#else
            std::fprintf(stderr, "levelforge_bench_dt: built without VolumeIO.h; --volume unavailable\n");
            return 2;
#endif
        }
        if (digest) {
            for (const auto& d : sets) {
                digestRows(d.name, initVectorVolume(transverseFeatures(d.inside)));
                digestMaskRows(d.name, transverseFeatures(d.inside));
            }
            if (big > 0) {
                const Dataset b = sphere(big, 0.5 * (big - 1), 0.37 * big);
                digestRows(b.name, initVectorVolume(transverseFeatures(b.inside)));
                digestMaskRows(b.name, transverseFeatures(b.inside));
            }
            digestRows("fractional seeds 67x45x53 (spacing 0.7 x 1.3 x 1.1)", fractionalSeeds());
            return 0;
        }
        std::vector<Summary> summary;
        for (const auto& d : sets) summary.push_back(accuracyTables(d, repeats, chamfer));

        std::printf("\n### EVDT full grid vs VCVDT (Table 5 analogue; times include init and length)\n\n");
        std::printf("| Dataset | EVDT grid (s) | VCVDT4 (s) | VCVDT8 (s) | EVDT grid avg error | VCVDT4 avg error | VCVDT8 avg error |\n");
        std::printf("|---|---:|---:|---:|---:|---:|---:|\n");
        for (const auto& s : summary)
            std::printf("| %s | %.4f | %.4f | %.4f | %.6f | %.6f | %.6f |\n", s.dataset.c_str(), s.evdtGridSeconds,
                        s.vcvdtSeconds, s.vcvdt8Seconds, s.evdtGridError, s.vcvdtError, s.vcvdt8Error);

        std::printf("\n### Throughput (propagation only, unless the row says end to end)\n\n");
        std::printf("| Volume | Method | Threads | Time (s) | Mvoxels/s |\n|---|---|---|---:|---:|\n");
        throughput(sets[0], repeats);
        if (big > 0) throughput(sphere(big, 0.5 * (big - 1), 0.37 * big), repeats);
    } catch (const std::exception& e) {
        std::fprintf(stderr, "levelforge_bench_dt: %s\n", e.what());
        return 1;
    }
    std::printf("\n<!-- load average at end %s -->\n", loadAverage().c_str());
    return 0;
}
