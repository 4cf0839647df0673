// SPDX-License-Identifier: Apache-2.0
// levelforge_bench_adf: adaptively sampled distance fields (Yin, Liu, Wu 2011).
//
//   levelforge_bench_adf [--res 128,256,512] [--subdivide N] [--threads N] [--repeat N]
//                        [--errors N] [--no-bounds] [--bound-stride N] [--png out.png] [--digest] mesh.obj ...
//
// One markdown row per (mesh, resolution) in the layout of the paper's Table 1: stage times
// (voxelization + lists, octree, type-1, type-2, type-3, hanging/finish; seconds, best of
// --repeat) and sample counts of each type; then the memory of the ADF tree (memUsage) against
// a dense float grid of the resolution (res³ × 4 bytes) and against a full narrow band
// expanded to the whole domain (every 8³ block of the domain a float leaf); then the global
// error per level at N random points (half in the domain, half within 3 voxels of the mesh's
// box) against the exact reference, next to the stated bound. The resolution is the number of
// finest voxels along the longest side of the mesh's bounding box, as in the paper.
// --subdivide N: Loop subdivision (OpenMesh LoopT; N levels, each ×4 faces) first.
// stderr also gives the least CPU time (user + system, all threads) of the repeats, a figure
// that other load on the machine disturbs far less than the wall time.
// --digest: a hash of every value of the (best) ADF tree, to check that builder changes keep
// the output bit-identical.
// --png: a Figure 9-style picture of the last (mesh, resolution): the slice at minimum z of the
// mesh box and the slice at middle z, distance colour-coded blue → green → red (negative →
// positive, square-root scale), the zero level black, reconstruction cells of size ≥ 2
// outlined (8³ tiles lighter).
#include <levelforge/adf/AdaptiveDistanceField.h>
#include <levelforge/core/Exceptions.h>
#include <levelforge/reference/ExactReference.h>
#include <levelforge/io/MeshIO.h>

#include <openvdb/openvdb.h>

#include <tbb/global_control.h>

#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <map>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "BenchLoop.h"
#include "BenchPng.h"
#include "BenchUtil.h"

using namespace levelforge;

using levelforge_bench::writePng;

namespace {



/// Generalized winding number of a closed mesh at p (solid angles, Van Oosterom & Strackee):
/// ≈ 1 inside, ≈ 0 outside; robust to pinched vertices and to the pseudonormal's blind spots.
double windingNumber(const TriangleMesh& m, const Vec3d& p)
{
    double w = 0;
    for (const Vec3I& t : m.triangles) {
        const Vec3d a = m.points[t[0]] - p, b = m.points[t[1]] - p, c = m.points[t[2]] - p;
        const double la = a.length(), lb = b.length(), lc = c.length();
        const double num = a.dot(b.cross(c));
        const double den = la * lb * lc + a.dot(b) * lc + b.dot(c) * la + c.dot(a) * lb;
        w += 2.0 * std::atan2(num, den);
    }
    return w / (4.0 * M_PI);
}

/// Blue → green → red for t in [0, 1].
void ramp(double t, unsigned char* c)
{
    t = std::max(0.0, std::min(1.0, t));
    double r, g, b;
    if (t < 0.5) { r = 0; g = 2 * t; b = 1 - 2 * t; }
    else { r = 2 * t - 1; g = 2 - 2 * t; b = 0; }
    c[0] = (unsigned char)(255 * r);
    c[1] = (unsigned char)(255 * g);
    c[2] = (unsigned char)(255 * b);
}

void slicePicture(const AdaptiveDistanceField& adf, const BBoxd& meshBox, const std::string& path)
{
    const openvdb::BBoxd dom = adf.worldDomain();
    const double h = adf.voxelSize();
    // the mesh box ± 10%, one pixel per finest voxel (at most 600 px)
    BBoxd box = meshBox;
    const Vec3d ext = box.extents();
    box = BBoxd(box.min() - ext * 0.1, box.max() + ext * 0.1);
    for (int k = 0; k < 3; ++k) {
        box.min()[k] = std::max(box.min()[k], dom.min()[k]);
        box.max()[k] = std::min(box.max()[k], dom.max()[k]);
    }
    const double px = std::max(h, std::max(box.extents()[0], box.extents()[1]) / 600.0);
    const int W = int(box.extents()[0] / px), H = int(box.extents()[1] / px);
    const double zs[2] = {meshBox.min()[2], 0.5 * (meshBox.min()[2] + meshBox.max()[2])};
    double dmax = 0;
    for (int k = 0; k < 3; ++k) dmax = std::max(dmax, ext[k]);
    dmax *= 0.3;
    const int gap = 8;
    std::vector<unsigned char> img(size_t(3) * (2 * W + gap) * H, 255);
    for (int panel = 0; panel < 2; ++panel) {
        std::vector<double> d(size_t(W) * H);
        std::vector<int> lv(size_t(W) * H);
        std::vector<long long> cellId(size_t(W) * H);
        for (int j = 0; j < H; ++j)
            for (int i = 0; i < W; ++i) {
                const Vec3d p(box.min()[0] + (i + 0.5) * px, box.max()[1] - (j + 0.5) * px, zs[panel]);
                d[size_t(j) * W + i] = adf.distance(p);
                const int l = adf.level(p);
                lv[size_t(j) * W + i] = l;
                const long long s = l >= 0 ? kAdfCellSize[l] : 1;
                const long long cx = (long long)std::floor(p[0] / h / double(s)), cy = (long long)std::floor(p[1] / h / double(s));
                cellId[size_t(j) * W + i] = (cx * 1000003LL + cy) * 8 + l;
            }
        for (int j = 0; j < H; ++j)
            for (int i = 0; i < W; ++i) {
                unsigned char* c = &img[3 * (size_t(j) * (2 * W + gap) + size_t(panel) * (W + gap) + i)];
                const double v = d[size_t(j) * W + i];
                ramp(0.5 + 0.5 * (v < 0 ? -1.0 : 1.0) * std::sqrt(std::min(1.0, std::abs(v) / dmax)), c); // sqrt: contrast near 0
                const bool edgeCell = (i + 1 < W && cellId[size_t(j) * W + i] != cellId[size_t(j) * W + i + 1]) ||
                                      (j + 1 < H && cellId[size_t(j) * W + i] != cellId[size_t(j + 1) * W + i]);
                if (edgeCell && lv[size_t(j) * W + i] >= 1) { // outline cells of size >= 2
                    const double f = lv[size_t(j) * W + i] >= 3 ? 0.8 : 0.55;
                    for (int k = 0; k < 3; ++k) c[k] = (unsigned char)(c[k] * f);
                }
                const bool zero = (i + 1 < W && (v < 0) != (d[size_t(j) * W + i + 1] < 0)) ||
                                  (j + 1 < H && (v < 0) != (d[size_t(j + 1) * W + i] < 0));
                if (zero) c[0] = c[1] = c[2] = 0;
            }
    }
    writePng(path, 2 * W + gap, H, img);
    std::printf("wrote %s (%d x %d: z = %.4g (min z) | z = %.4g (middle))\n", path.c_str(), 2 * W + gap, H, zs[0], zs[1]);
}

/// FNV-1a over every value of the ADF tree (voxels and tiles, with their coordinates, levels and
/// active states): equal digests = bit-identical trees (--digest; used to check that
/// optimisations of the builder do not change its output).
uint64_t treeDigest(const openvdb::FloatTree& tree)
{
    uint64_t h = 1469598103934665603ull;
    auto mix = [&h](const void* p, size_t n) {
        const unsigned char* c = static_cast<const unsigned char*>(p);
        for (size_t i = 0; i < n; ++i) { h ^= c[i]; h *= 1099511628211ull; }
    };
    for (auto it = tree.cbeginValueAll(); it; ++it) {
        const openvdb::Coord c = it.getCoord();
        const float v = *it;
        const int meta[5] = {c.x(), c.y(), c.z(), int(it.getDepth()), int(it.isValueOn())};
        mix(meta, sizeof(meta));
        mix(&v, sizeof(v));
    }
    return h;
}

/// CPU seconds (user + system, all threads) of this process so far: the build's CPU time is
/// robust against other load on the machine, unlike its wall time.
double cpuSeconds()
{
    rusage u{};
    getrusage(RUSAGE_SELF, &u);
    return double(u.ru_utime.tv_sec + u.ru_stime.tv_sec) + 1e-6 * double(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

std::string fmtBytes(double b)
{
    char buf[64];
    std::snprintf(buf, sizeof(buf), "%.1f MB", b / 1e6);
    return buf;
}

} // namespace

int main(int argc, char** argv)
{
    std::vector<double> res = {128, 256, 512};
    int subdivide = 0, threads = 0, repeat = 1, errors = 20000, boundStride = 1;
    bool bounds = true, digest = false;
    std::string png;
    std::vector<std::string> meshes;
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        auto next = [&]() -> const char* {
            if (i + 1 >= argc) { std::fprintf(stderr, "%s needs a value\n", a.c_str()); std::exit(2); }
            return argv[++i];
        };
        if (a == "--res") res = levelforge_bench::parseList(next());
        else if (a == "--subdivide") subdivide = std::atoi(next());
        else if (a == "--threads") threads = std::atoi(next());
        else if (a == "--repeat") repeat = std::max(1, std::atoi(next()));
        else if (a == "--errors") errors = std::atoi(next());
        else if (a == "--no-bounds") bounds = false;
        else if (a == "--bound-stride") boundStride = std::max(1, std::atoi(next()));
        else if (a == "--png") png = next();
        else if (a == "--digest") digest = true;
        else if (a == "-h" || a == "--help") {
            std::printf("usage: levelforge_bench_adf [--res 128,256,512] [--subdivide N] [--threads N] [--repeat N] "
                        "[--errors N] [--no-bounds] [--bound-stride N] [--png out.png] [--digest] mesh ...\n");
            return 0;
        } else meshes.push_back(a);
    }
    if (meshes.empty()) { std::fprintf(stderr, "no mesh given (--help)\n"); return 2; }
    std::unique_ptr<tbb::global_control> gc;
    if (threads > 0) gc.reset(new tbb::global_control(tbb::global_control::max_allowed_parallelism, size_t(threads)));
    openvdb::initialize();

    struct Row { std::string table1, memory, error; };
    std::vector<Row> rows;
    try {
        for (const std::string& path : meshes) {
            TriangleMesh mesh = readMesh(path);
            if (subdivide > 0) mesh = levelforge_bench::loopSubdivide(mesh, subdivide);
            std::string name = path.substr(path.find_last_of('/') + 1);
            name = name.substr(0, name.find_last_of('.'));
            if (subdivide) name += " Loop×" + std::to_string(subdivide);
            // warm-up (thread pool, pages)
            {
                AdaptiveDistanceFieldOptions w;
                w.voxelCount = 32;
                w.computeBounds = false;
                meshToAdaptiveDistanceField(mesh, w);
            }
            for (double r : res) {
                AdaptiveDistanceFieldOptions opt;
                opt.voxelCount = int(r);
                opt.computeBounds = false;
                AdaptiveDistanceFieldStats best;
                AdaptiveDistanceField adf;
                double bestTotal = 1e300, bestCpu = 1e300;
                for (int k = 0; k < repeat; ++k) {
                    AdaptiveDistanceFieldStats st;
                    const double c0 = cpuSeconds();
                    const auto t0 = std::chrono::steady_clock::now();
                    AdaptiveDistanceField a = meshToAdaptiveDistanceField(mesh, opt, &st);
                    const double wall = levelforge_bench::since(t0);
                    bestCpu = std::min(bestCpu, cpuSeconds() - c0);
                    if (wall < bestTotal) { bestTotal = wall; best = st; adf = a; }
                }
                if (digest)
                    std::fprintf(stderr, "%s %d: digest %016llx, samples %llu / %llu / %llu, hanging %llu\n", name.c_str(), int(r),
                                 (unsigned long long)treeDigest(adf.grid()->tree()), (unsigned long long)best.type1,
                                 (unsigned long long)best.type2, (unsigned long long)best.type3, (unsigned long long)best.hanging);
                // the stated bound (a separate pass, timed separately)
                AdaptiveDistanceFieldStats bst = best;
                if (bounds) {
                    opt.computeBounds = true;
                    opt.boundStride = boundStride;
                    adf = meshToAdaptiveDistanceField(mesh, opt, &bst);
                }
                char buf[1024];
                std::snprintf(buf, sizeof(buf),
                              "| %s (%zu tris) | %d³ | %.3f | %.3f | %llu | %.3f | %llu | %.3f | %llu | %.3f | %llu | %.3f | **%.3f** |",
                              name.c_str(), mesh.triangles.size(), int(r), best.secondsVoxelize, best.secondsOctree,
                              (unsigned long long)best.type1, best.secondsType1, (unsigned long long)best.type2, best.secondsType2,
                              (unsigned long long)best.type3, best.secondsType3, (unsigned long long)best.hanging,
                              best.secondsFinish, bestTotal);
                Row row;
                row.table1 = buf;
                const double dense = r * r * r * 4.0;
                const double domainBlocks = double(best.domainVoxels) / 512.0;
                const double fullBand = domainBlocks * (512 * 4 + 2 * 64 + 64) + domainBlocks / 4096.0 * (4096 * 8 + 1024);
                std::snprintf(buf, sizeof(buf), "| %s | %d³ | %llu / %llu / %llu | %s | %s (%.1f %%) | %s (%.1f %%) |", name.c_str(),
                              int(r), (unsigned long long)best.leaves, (unsigned long long)best.level1Tiles,
                              (unsigned long long)best.level2Tiles, fmtBytes(double(best.memoryBytes)).c_str(),
                              fmtBytes(dense).c_str(), 100.0 * double(best.memoryBytes) / dense, fmtBytes(fullBand).c_str(),
                              100.0 * double(best.memoryBytes) / fullBand);
                row.memory = buf;
                if (errors > 0) {
                    ExactReference ref(mesh);
                    std::mt19937_64 rng(1);
                    std::uniform_real_distribution<double> u(0, 1);
                    const openvdb::BBoxd dom = adf.worldDomain();
                    BBoxd nearBox = mesh.bounds();
                    const double h = adf.voxelSize();
                    nearBox = BBoxd(nearBox.min() - Vec3d(3 * h), nearBox.max() + Vec3d(3 * h));
                    std::array<double, kAdfLevels> mx{}, sum{};
                    std::array<uint64_t, kAdfLevels> n{};
                    uint64_t signErr = 0, signErrRefWrong = 0;
                    for (int i = 0; i < errors; ++i) {
                        const Vec3d lo = (i % 2) ? dom.min() : nearBox.min(), hi = (i % 2) ? dom.max() : nearBox.max();
                        const Vec3d p(lo[0] + u(rng) * (hi[0] - lo[0]), lo[1] + u(rng) * (hi[1] - lo[1]), lo[2] + u(rng) * (hi[2] - lo[2]));
                        const int l = adf.level(p);
                        if (l < 0) continue;
                        const double d = adf.distance(p);
                        double e = ref.signedDistance(p);
                        if ((d < 0) != (e < 0) && std::abs(e) > 1.0 * h) {
                            ++signErr;
                            // which one is right? the winding number decides; where it sides with
                            // the ADF (a mesh defect fools the reference's pseudonormal), the
                            // error is measured against the corrected sign
                            const bool inside = windingNumber(mesh, p) > 0.5;
                            if (inside == (d < 0)) { ++signErrRefWrong; e = -e; }
                        }
                        const double err = std::abs(d - e) / h;
                        mx[size_t(l)] = std::max(mx[size_t(l)], err);
                        sum[size_t(l)] += err;
                        ++n[size_t(l)];
                    }
                    std::string cells;
                    for (int l = 0; l < kAdfLevels; ++l) {
                        if (!n[size_t(l)]) { cells += " – |"; continue; }
                        std::snprintf(buf, sizeof(buf), " %.3f / %.3f (%s) |", sum[size_t(l)] / double(n[size_t(l)]), mx[size_t(l)],
                                      bst.levelBoundVoxels[size_t(l)] >= 0 ? (std::to_string(bst.levelBoundVoxels[size_t(l)]).substr(0, 5)).c_str() : "–");
                        cells += buf;
                    }
                    std::snprintf(buf, sizeof(buf), "| %s | %d³ |%s %llu (%llu) | %.2f |", name.c_str(), int(r), cells.c_str(),
                                  (unsigned long long)signErr, (unsigned long long)signErrRefWrong, bst.secondsBounds);
                    row.error = buf;
                }
                rows.push_back(row);
                std::fprintf(stderr, "%s %d: %.3f s (CPU %.3f s, least of %d), %s, type-2 beyond the gather radius %llu, type-2 certificate <= %.3f voxels\n", name.c_str(), int(r), bestTotal, bestCpu, repeat,
                             fmtBytes(double(best.memoryBytes)).c_str(), (unsigned long long)best.type2Wide, best.type2MaxBoundVoxels);
                if (!png.empty() && &path == &meshes.back() && r == res.back()) slicePicture(adf, mesh.bounds(), png);
            }
        }
    } catch (const std::exception& e) {
        std::fprintf(stderr, "levelforge_bench_adf: %s\n", e.what());
        return 1;
    }
    std::printf("\n| mesh | res | voxelize + lists (s) | octree (s) | type-1 | (s) | type-2 | (s) | type-3 | (s) | hanging | finish (s) | total (s) |\n");
    std::printf("|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
    for (const Row& r : rows) std::printf("%s\n", r.table1.c_str());
    std::printf("\n| mesh | res | leaves / level-1 tiles / level-2 tiles | ADF tree | dense float grid (ADF share) | full band over the domain (ADF share) |\n");
    std::printf("|---|---|---|---|---|---|\n");
    for (const Row& r : rows) std::printf("%s\n", r.memory.c_str());
    if (errors > 0) {
        std::printf("\n| mesh | res | level 0 (1³) mean / max (bound) | level 1 (2³) | level 2 (4³) | level 3 (8³ tile) | level 4 (128³ tile) | sign differences (|d| > 1 voxel) vs reference (where the winding number sides with the ADF) | bound pass (s) |\n");
        std::printf("|---|---|---|---|---|---|---|---|---|\n");
        for (const Row& r : rows) std::printf("%s\n", r.error.c_str());
    }
    return 0;
}
