// SPDX-License-Identifier: Apache-2.0
// levelforge_bench_expand: widening an exact narrow band (half-width 3) to 20 and 60 voxels,
// levelforge::expandLevelSet (fast sweeping on sparse topology) side by side with
// openvdb::tools::dilateSdf, both measured against the exact reference.
//
//   levelforge_bench_expand [--res 256,512] [--widths 20,60] [--stride 31] [--no-openvdb]
//                           [--methods sweep,vector] [--repeat N] [--no-accuracy] [--threads N]
//                           mesh.obj [mesh2.off ...]
//
// --repeat N: seconds are the best of N runs (the machine is shared); stderr also gives the best
// user+system CPU seconds, the result digest and the sweep counters. --no-accuracy skips the
// comparison with the exact reference (timing only).
// With dilateSdf, each levelforge row is also printed as one machine-readable line
// (SPEED label=<mesh>@<res>/w<width>/<method> ... anchor=openvdb_dilateSdf ..., BenchUtil.h),
// from the same best-of-N times, for scripts/bench --smoke.
//
// Prints one markdown table row per (mesh, resolution, width, method): seconds, active voxels,
// missing voxels (every inactive face-neighbour of the result is checked against the exact
// distance: a voxel with |d| < width that is not active is missing), mean / max error over the
// active voxels (every `stride`-th one, in voxels), sign errors, and for levelforge the sweep
// rounds, the final max change and the sweep time per million voxels (paper Table 4; the swept
// voxels are the candidate domain, whole leaf nodes for the sweep).
#include <levelforge/reference/ExactReference.h>
#include <levelforge/expand/ExpandLevelSet.h>
#include <levelforge/io/MeshIO.h>
#include <levelforge/mesh/MeshToLevelSet.h>

#include <openvdb/openvdb.h>
#include <openvdb/tools/FastSweeping.h>
#include <openvdb/tree/LeafManager.h>

#include <tbb/enumerable_thread_specific.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>

#include <chrono>
#include <memory>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <sstream>
#include <string>
#include <vector>

using namespace levelforge;
#include "BenchUtil.h"
using levelforge_bench::parseList;
using Clock = std::chrono::steady_clock;

namespace {

/// user + system CPU time of the process (all threads)
double cpuSeconds()
{
    timespec ts;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return double(ts.tv_sec) + 1e-9 * double(ts.tv_nsec);
}

struct Accuracy
{
    uint64_t checked = 0, missing = 0, signErrors = 0, extra = 0;
    double mean = 0, max = 0;
};

/// Errors over every `stride`-th active voxel; coverage over every inactive face-neighbour.
Accuracy measure(const openvdb::FloatGrid& g, const ExactReference& ref, double w, uint64_t stride,
                 const openvdb::FloatGrid* common = nullptr)
{
    using openvdb::Coord;
    struct A { uint64_t n = 0, miss = 0, sign = 0, extra = 0; double sum = 0, mx = 0; };
    tbb::enumerable_thread_specific<A> tls;
    openvdb::tree::LeafManager<const openvdb::FloatTree> lm(g.tree());
    const double h = g.voxelSize()[0];
    tbb::parallel_for(tbb::blocked_range<size_t>(0, lm.leafCount(), 8), [&](const tbb::blocked_range<size_t>& r) {
        A& a = tls.local();
        openvdb::tree::ValueAccessor<const openvdb::FloatTree> acc(g.tree());
        std::unique_ptr<openvdb::tree::ValueAccessor<const openvdb::FloatTree>> cacc;
        if (common) cacc.reset(new openvdb::tree::ValueAccessor<const openvdb::FloatTree>(common->tree()));
        static const Coord nb[6] = {Coord(1, 0, 0), Coord(-1, 0, 0), Coord(0, 1, 0),
                                    Coord(0, -1, 0), Coord(0, 0, 1), Coord(0, 0, -1)};
        for (size_t l = r.begin(); l != r.end(); ++l) {
            for (auto it = lm.leaf(l).cbeginValueOn(); it; ++it) {
                const Coord c = it.getCoord();
                const uint64_t hsh = uint64_t(uint32_t(c.x() * 73856093u ^ c.y() * 19349663u ^ c.z() * 83492791u));
                if (common) {
                    if (hsh % stride != 0 || !cacc->isValueOn(c)) continue;
                }
                if (hsh % stride == 0) {
                    const double d = ref.signedDistance(g.indexToWorld(c)) / h;
                    const double v = *it / h;
                    const double e = std::abs(v - d);
                    ++a.n;
                    a.sum += e;
                    a.mx = std::max(a.mx, e);
                    if (std::abs(d) > 1e-6 && (d < 0) != (v < 0)) ++a.sign;
                    if (std::abs(d) >= w) ++a.extra;
                }
                for (const Coord& o : nb) {
                    if (common) break;
                    const Coord q = c + o;
                    if (acc.isValueOn(q)) continue;
                    // count each missing voxel once: from its smallest active neighbour only
                    bool first = true;
                    for (const Coord& o2 : nb) {
                        const Coord p = q + o2;
                        if (p < c && acc.isValueOn(p)) { first = false; break; }
                    }
                    if (!first) continue;
                    if (std::abs(ref.signedDistance(g.indexToWorld(q)) / h) < w - 1e-6) ++a.miss;
                }
            }
        }
    });
    Accuracy r;
    double sum = 0;
    for (const A& a : tls) {
        r.checked += a.n;
        r.missing += a.miss;
        r.signErrors += a.sign;
        r.extra += a.extra;
        sum += a.sum;
        r.max = std::max(r.max, a.mx);
    }
    r.mean = r.checked ? sum / double(r.checked) : 0;
    return r;
}

} // namespace

int main(int argc, char** argv)
{
    std::vector<double> resolutions{256, 512}, widths{20, 60};
    uint64_t stride = 31;
    bool withOpenVdb = true, withAccuracy = true;
    int repeat = 1, threads = 0;
    std::vector<std::string> methods{"sweep", "vector"};
    std::vector<std::string> meshes;
    for (int i = 1; i < argc; ++i) {
        if (!std::strcmp(argv[i], "--res") && i + 1 < argc) resolutions = parseList(argv[++i]);
        else if (!std::strcmp(argv[i], "--widths") && i + 1 < argc) widths = parseList(argv[++i]);
        else if (!std::strcmp(argv[i], "--stride") && i + 1 < argc) stride = std::stoull(argv[++i]);
        else if (!std::strcmp(argv[i], "--no-openvdb")) withOpenVdb = false;
        else if (!std::strcmp(argv[i], "--no-accuracy")) withAccuracy = false;
        else if (!std::strcmp(argv[i], "--threads") && i + 1 < argc) threads = std::max(1, std::atoi(argv[++i]));
        else if (!std::strcmp(argv[i], "--repeat") && i + 1 < argc) repeat = std::max(1, std::atoi(argv[++i]));
        else if (!std::strcmp(argv[i], "--methods") && i + 1 < argc) {
            methods.clear();
            std::string list = argv[++i];
            for (size_t p = 0; p <= list.size();) {
                const size_t q = std::min(list.find(',', p), list.size());
                methods.push_back(list.substr(p, q - p));
                p = q + 1;
            }
        }
        else meshes.push_back(argv[i]);
    }
    if (meshes.empty()) {
        std::fprintf(stderr, "usage: levelforge_bench_expand [--res 256,512] [--widths 20,60] "
                             "[--stride 31] [--no-openvdb] [--methods sweep,vector] [--repeat N] [--no-accuracy] [--threads N] mesh...\n");
        return 2;
    }
    openvdb::initialize();
    std::unique_ptr<tbb::global_control> threadLimit;
    if (threads > 0) {
        threadLimit.reset(new tbb::global_control(tbb::global_control::max_allowed_parallelism, size_t(threads)));
    }
    std::printf("| mesh | res | width | method | seconds | active voxels | missing | mean / max err | "
                "mean / max err, common voxels | sign err | rounds | s / M swept voxels |\n"
                "|---|---|---|---|---|---|---|---|---|---|---|---|\n");
    std::string speedLines; // printed after the table
    for (const std::string& path : meshes) {
        const TriangleMesh mesh = readMesh(path);
        const ExactReference ref(mesh);
        const std::string name = std::filesystem::path(path).stem().string();
        for (double res : resolutions) {
            MeshToLevelSetOptions mo;
            mo.voxelCount = int(res);
            auto t0 = Clock::now();
            // the exact band with its closest points (the Vector method's shell); the level set
            // is bit-identical to meshToLevelSet's
            LevelSetWithClosestPoints shell = meshToLevelSetWithClosestPoints(mesh, mo);
            openvdb::FloatGrid::Ptr band = shell.levelSet;
            const double tBand = std::chrono::duration<double>(Clock::now() - t0).count();
            std::printf("| %s | %d | 3 | exact band + closest points | %.2f | %llu | | | | | | |\n",
                        name.c_str(), int(res), tBand, (unsigned long long)band->activeVoxelCount());
            std::fflush(stdout);
            for (double w : widths) {
                openvdb::FloatGrid::Ptr ov;
                double tOv = 0;
                if (withOpenVdb) {
                    double cpuOv = 1e30;
                    tOv = 1e30;
                    for (int rep = 0; rep < repeat; ++rep) {
                        ov.reset();
                        t0 = Clock::now();
                        const double c0 = cpuSeconds();
                        ov = openvdb::tools::dilateSdf(*band, int(std::ceil(w - 3)));
                        tOv = std::min(tOv, std::chrono::duration<double>(Clock::now() - t0).count());
                        cpuOv = std::min(cpuOv, cpuSeconds() - c0);
                    }
                    std::fprintf(stderr, "  %s dilateSdf w%g: CPU %.2f s (best of %d)\n", name.c_str(), w,
                                 cpuOv, repeat);
                }
                for (const std::string& method : methods) {
                    ExpandLevelSetOptions eo;
                    eo.exteriorWidth = eo.interiorWidth = w;
                    if (method == "vector") {
                        eo.method = ExpansionMethod::Vector;
                        eo.closestPoints = &shell.closestPoints->tree();
                        eo.closestTriangles = &shell.closestTriangles->tree();
                        eo.mesh = &mesh;
                    }
                    ExpandLevelSetStats st;
                    openvdb::FloatGrid::Ptr ours;
                    double tOurs = 1e30, cpuOurs = 1e30;
                    for (int rep = 0; rep < repeat; ++rep) {
                        ours.reset();
                        ExpandLevelSetStats s1;
                        t0 = Clock::now();
                        const double c0 = cpuSeconds();
                        ours = expandLevelSet(*band, eo, &s1);
                        const double t1 = std::chrono::duration<double>(Clock::now() - t0).count();
                        cpuOurs = std::min(cpuOurs, cpuSeconds() - c0);
                        if (t1 < tOurs) { tOurs = t1; st = s1; } // the stage times of the best run
                    }
                    const Accuracy a = withAccuracy ? measure(*ours, ref, w, stride) : Accuracy{};
                    {
                        // digest of the result (active coordinates and value bits, tree order):
                        // equal digests = identical grids
                        uint64_t hsh = 1469598103934665603ull;
                        for (auto it = ours->cbeginValueOn(); it; ++it) {
                            const openvdb::Coord c = it.getCoord();
                            uint32_t bits;
                            const float val = *it;
                            std::memcpy(&bits, &val, 4);
                            for (uint64_t x : {uint64_t(uint32_t(c.x())), uint64_t(uint32_t(c.y())),
                                               uint64_t(uint32_t(c.z())), uint64_t(bits)}) {
                                hsh = (hsh ^ x) * 1099511628211ull;
                            }
                        }
                        std::fprintf(stderr, "  %s %s w%g: digest %016llx, %llu candidate voxels, %llu leaf sweeps, %llu voxel updates, "
                                     "max change %.3g voxel, CPU %.2f s (best of %d), stages %.3f / %.3f / %.3f s\n",
                                     name.c_str(), method.c_str(), w, (unsigned long long)hsh,
                                     (unsigned long long)st.candidateVoxels,
                                     (unsigned long long)st.leafUpdates, (unsigned long long)st.voxelUpdates, st.maxChange, cpuOurs, repeat,
                                     st.secondsTopology, st.secondsSweep, st.secondsFinish);
                    }
                    std::string common = "", ratio = "";
                    if (ov) {
                        const Accuracy c = withAccuracy ? measure(*ours, ref, w, stride, ov.get()) : Accuracy{};
                        char buf[128];
                        std::snprintf(buf, sizeof(buf), "%.3f / %.3f", c.mean, c.max);
                        common = buf;
                        std::snprintf(buf, sizeof(buf), ", %.1fx faster than dilateSdf", tOv / tOurs);
                        ratio = buf;
                    }
                    if (ov) speedLines += levelforge_bench::speedLine(name + "@" + std::to_string(int(res)) + "/w" +
                                                                          levelforge_bench::shortNumber(w) + "/" + method,
                                                                      tOurs, "openvdb_dilateSdf", tOv);
                    std::printf("| %s | %d | %g | levelforge %s | %.2f (topology %.2f, %s %.2f%s) | "
                                "%llu | %llu | %.4f / %.3f | %s | %llu | %d | %.3f |\n",
                                name.c_str(), int(res), w, method.c_str(), tOurs, st.secondsTopology,
                                method == "vector" ? "vectors" : "sweep", st.secondsSweep, ratio.c_str(),
                                (unsigned long long)ours->activeVoxelCount(),
                                (unsigned long long)a.missing, a.mean, a.max, common.c_str(),
                                (unsigned long long)a.signErrors, st.iterations,
                                st.secondsSweep / (double(st.candidateVoxels) * 1e-6));
                    if (method == "vector")
                        std::fprintf(stderr, "  vector: setup %.2f s, passes %.2f s, refine %.2f s; %llu refined, %llu walk steps, "
                                     "%.2f evaluations per refined voxel, %d rounds\n",
                                     st.secondsVectorSetup, st.secondsVectorPasses, st.secondsVectorFinish,
                                     (unsigned long long)st.refinedVoxels, (unsigned long long)st.walkSteps,
                                     double(st.refineEvaluations) / double(std::max<uint64_t>(1, st.refinedVoxels)),
                                     st.refineRounds);
                    std::fflush(stdout);
                }
                if (!ov) continue;
                const Accuracy o = withAccuracy ? measure(*ov, ref, w, stride) : Accuracy{};
                std::printf("| %s | %d | %g | openvdb dilateSdf (NN_FACE, %d) | %.2f | %llu | "
                            "%llu | %.4f / %.3f | | %llu | | |\n",
                            name.c_str(), int(res), w, int(std::ceil(w - 3)), tOv,
                            (unsigned long long)ov->activeVoxelCount(),
                            (unsigned long long)o.missing, o.mean, o.max,
                            (unsigned long long)o.signErrors);
                std::fflush(stdout);
            }
        }
    }
    if (!speedLines.empty()) std::printf("\n%s", speedLines.c_str());
    return 0;
}
