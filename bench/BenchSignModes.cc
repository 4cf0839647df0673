// SPDX-License-Identifier: Apache-2.0
// levelforge_bench_sign — the sign modes of the exact band (issue 16): sign errors against the
// exact winding number, and the cost of the winding sign and of fill interior.
//
//   levelforge_bench_sign [--res N] [--error-res N] [--repeat N] [--samples N] [--holes K]
//                         [--subdivide L] [--no-openvdb] [--no-errors] [--no-timing] [--fill] mesh...
//
// For each mesh (optionally Loop-subdivided L times, which keeps its holes, then with K holes
// punched: the triangles within 2 % of the bounding-box diagonal of K vertices picked by a fixed
// generator are removed):
//  - errors (at --error-res, default 128, band half-width 3): about --samples points on the band
//    (active voxels of the winding-signed band, by a fixed coordinate hash) and as many voxel
//    centres drawn uniformly in the bounding box grown by 10 %; at each the exact winding number
//    (ExactReference::windingNumber(), every triangle's solid angle) decides inside (|w| > 1/2)
//    where it is decisive (||w| - 1/2| > 0.25, the criterion); each method's grid says
//    inside where its value (active or not, tiles included) is negative (a value of exactly 0, a
//    voxel centre on a triangle, has no sign and is not counted: e.g. on the shared face of
//    trimesh_joined_tetrahedra, where w = 1 but the distance is 0). Methods: levelforge
//    pseudonormal, levelforge winding, and openvdb::tools::meshToLevelSet (default flags: the
//    band's signs from its own inside/outside test, then a signed flood fill). "band missing":
//    band samples inactive in OpenVDB's grid;
//  - timing (at --res, default 512, best of --repeat): meshToLevelSet with SignMode::Pseudonormal
//    and SignMode::Winding, and with --fill the auto sign with and without fillInterior; the
//    ratios are the cost of the winding sign and of the fill;
//  - --png out.png (with the errors): a picture of the last mesh's middle z slice at --error-res,
//    pseudonormal | winding | OpenVDB | the exact winding number side by side (slicePicture()).
// Output: one line per mesh and measurement, then a markdown table.

#include <levelforge/core/MeshValidation.h>
#include <levelforge/io/MeshIO.h>
#include <levelforge/mesh/MeshToLevelSet.h>
#include <levelforge/reference/ExactReference.h>

#include <openvdb/openvdb.h>
#include <openvdb/tools/MeshToVolume.h>

#include "BenchLoop.h"
#include "BenchPng.h"
#include "BenchUtil.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <iostream>
#include <random>
#include <string>
#include <vector>

using namespace levelforge;
using levelforge_bench::since;
using Clock = std::chrono::steady_clock;

namespace {

struct Args
{
    int res = 512, errorRes = 128, repeat = 3;
    uint64_t samples = 3000;
    int holes = 0, subdivide = 0;
    bool openvdb = true, errors = true, timing = true, fill = false;
    std::string png; // the slice picture of the last mesh (with the errors)
    std::vector<std::string> meshes;
};

[[noreturn]] void usage(const char* msg)
{
    std::fprintf(stderr, "levelforge_bench_sign: %s\nusage: levelforge_bench_sign [--res N] [--error-res N] [--repeat N] "
                         "[--samples N] [--holes K] [--subdivide L] [--no-openvdb] [--no-errors] [--no-timing] [--fill] [--png out.png] mesh...\n", msg);
    std::exit(2);
}

/// The slice picture (--png): the plane z = middle of the mesh's bounding box at the error
/// resolution, four panels left to right: levelforge pseudonormal, levelforge winding, OpenVDB
/// (flood fill), and the exact winding number. Inside (value < 0, or |w| > 1/2 for the last
/// panel) blue, outside light grey, darker with the distance to the surface; a pixel whose sign
/// disagrees with the exact winding number where it is decisive (||w| - 1/2| > 0.25) red.
void slicePicture(const std::string& path, const TriangleMesh& mesh, const openvdb::FloatGrid* grids[3],
                  const ExactReference& ref)
{
    const openvdb::FloatGrid& g = *grids[1];
    const BBoxd b = mesh.bounds();
    const Vec3d grow = (b.max() - b.min()) * 0.08;
    const openvdb::Coord lo = openvdb::Coord::floor(g.worldToIndex(b.min() - grow));
    const openvdb::Coord hi = openvdb::Coord::ceil(g.worldToIndex(b.max() + grow));
    const int z = openvdb::Coord::round(g.worldToIndex(0.5 * (b.min() + b.max()))).z();
    const int nx = hi.x() - lo.x() + 1, ny = hi.y() - lo.y() + 1;
    const int scale = std::max(1, 360 / std::max(nx, ny)), gap = 6;
    const int W = 4 * nx * scale + 3 * gap, H = ny * scale;
    std::vector<double> w(size_t(nx) * ny);
    tbb::parallel_for(tbb::blocked_range<int>(0, ny), [&](const tbb::blocked_range<int>& r) {
        for (int y = r.begin(); y != r.end(); ++y)
            for (int x = 0; x < nx; ++x)
                w[size_t(y) * nx + x] = ref.windingNumber(g.indexToWorld(openvdb::Coord(lo.x() + x, lo.y() + y, z)));
    });
    const double bg = std::abs(double(g.background()));
    std::vector<unsigned char> img(size_t(W) * H * 3, 255);
    for (int panel = 0; panel < 4; ++panel) {
        const openvdb::FloatGrid* grid = panel < 3 ? grids[panel] : nullptr;
        if (panel < 3 && !grid) continue;
        for (int y = 0; y < ny; ++y)
            for (int x = 0; x < nx; ++x) {
                const double wx = w[size_t(y) * nx + x];
                const bool truth = std::abs(wx) > 0.5, decisive = std::abs(std::abs(wx) - 0.5) > 0.25;
                double v = 0.0;
                bool inside;
                if (grid) {
                    v = grid->tree().getValue(openvdb::Coord(lo.x() + x, lo.y() + y, z));
                    inside = v < 0.0;
                } else {
                    inside = truth;
                    v = inside ? -bg : bg;
                }
                const double t = std::min(1.0, std::abs(v) / std::max(bg, 1e-300)); // 0 on the surface
                unsigned char c[3];
                if (grid && v != 0.0 && decisive && inside != truth) { c[0] = 220; c[1] = 30; c[2] = 30; }
                else if (inside) { c[0] = (unsigned char)(40 + 60 * t); c[1] = (unsigned char)(90 + 60 * t); c[2] = (unsigned char)(170 + 60 * t); }
                else { c[0] = c[1] = c[2] = (unsigned char)(150 + 90 * t); }
                for (int sy = 0; sy < scale; ++sy)
                    for (int sx = 0; sx < scale; ++sx) {
                        const int px = panel * (nx * scale + gap) + x * scale + sx, py = (ny - 1 - y) * scale + sy;
                        unsigned char* o = &img[(size_t(py) * W + px) * 3];
                        o[0] = c[0]; o[1] = c[1]; o[2] = c[2];
                    }
            }
    }
    levelforge_bench::writePng(path, W, H, img);
    std::printf("wrote %s: slice z = %d (index), %d x %d voxels, panels pseudonormal | winding | OpenVDB | exact winding number\n",
                path.c_str(), z, nx, ny);
}

Args parse(int argc, char** argv)
{
    Args a;
    for (int i = 1; i < argc; ++i) {
        const std::string s = argv[i];
        auto next = [&]() -> const char* {
            if (i + 1 >= argc) usage(("missing value after " + s).c_str());
            return argv[++i];
        };
        if (s == "--res") a.res = std::atoi(next());
        else if (s == "--error-res") a.errorRes = std::atoi(next());
        else if (s == "--repeat") a.repeat = std::max(1, std::atoi(next()));
        else if (s == "--samples") a.samples = uint64_t(std::atoll(next()));
        else if (s == "--holes") a.holes = std::atoi(next());
        else if (s == "--subdivide") a.subdivide = std::atoi(next());
        else if (s == "--no-openvdb") a.openvdb = false;
        else if (s == "--no-errors") a.errors = false;
        else if (s == "--no-timing") a.timing = false;
        else if (s == "--fill") a.fill = true;
        else if (s == "--png") a.png = next();
        else if (s.rfind("--", 0) == 0) usage(("unknown option " + s).c_str());
        else a.meshes.push_back(s);
    }
    if (a.meshes.empty()) usage("no mesh given");
    return a;
}

/// Removes the triangles within 2 % of the bounding-box diagonal of `holes` vertices (a fixed
/// generator picks them): a broken copy with holes.
TriangleMesh punchHoles(const TriangleMesh& in, int holes)
{
    const BBoxd b = in.bounds();
    const double r = 0.02 * (b.max() - b.min()).length(), r2 = r * r;
    std::mt19937_64 rng(20261203);
    std::vector<Vec3d> centres;
    for (int k = 0; k < holes; ++k) centres.push_back(in.points[in.triangles[rng() % in.triangles.size()][0]]);
    TriangleMesh out;
    out.points = in.points;
    for (const Vec3I& t : in.triangles) {
        const Vec3d c = (in.points[t[0]] + in.points[t[1]] + in.points[t[2]]) / 3.0;
        bool cut = false;
        for (const Vec3d& h : centres) cut = cut || (c - h).lengthSqr() < r2;
        if (!cut) out.triangles.push_back(t);
    }
    out.source = in.source + " (" + std::to_string(holes) + " holes)";
    return out;
}

openvdb::FloatGrid::Ptr openvdbLevelSet(const TriangleMesh& mesh, double h, float halfWidth)
{
    std::vector<openvdb::Vec3s> pts(mesh.points.size());
    for (size_t i = 0; i < pts.size(); ++i) pts[i] = openvdb::Vec3s(mesh.points[i] / h);
    std::vector<openvdb::Vec3I> tris(mesh.triangles.size());
    for (size_t i = 0; i < tris.size(); ++i) tris[i] = openvdb::Vec3I(mesh.triangles[i][0], mesh.triangles[i][1], mesh.triangles[i][2]);
    const auto xform = openvdb::math::Transform::createLinearTransform(h);
    // points already in index space: meshToLevelSet with an identity transform, then ours
    auto grid = openvdb::tools::meshToLevelSet<openvdb::FloatGrid>(*openvdb::math::Transform::createLinearTransform(1.0),
                                                                   pts, tris, halfWidth);
    grid->setTransform(xform);
    return grid;
}

double bestOf(int repeat, const std::function<void()>& f)
{
    double best = 1e300;
    for (int i = 0; i < repeat; ++i) {
        const auto t = Clock::now();
        f();
        best = std::min(best, since(t));
    }
    return best;
}

struct ErrorRow
{
    uint64_t bandDecisive = 0, volumeDecisive = 0;
    uint64_t bandErr[3] = {0, 0, 0}, volumeErr[3] = {0, 0, 0}; // pseudonormal, winding, openvdb
    uint64_t bandMissingOpenvdb = 0, bandSamples = 0;
};

} // namespace

int main(int argc, char** argv)
{
    openvdb::initialize();
    const Args args = parse(argc, argv);
    struct Row
    {
        std::string name;
        uint64_t tris = 0, boundaryEdges = 0;
        bool closed = false;
        ErrorRow err;
        bool haveErr = false, haveTime = false, haveFill = false;
        double pn = 0, wn = 0, band = 0, filled = 0;
        uint64_t evals = 0, active = 0;
    };
    std::vector<Row> rows;
    for (const std::string& path : args.meshes) {
        TriangleMesh mesh = readMesh(path);
        if (args.subdivide > 0) mesh = levelforge_bench::loopSubdivide(withoutDegenerateTriangles(mesh), args.subdivide);
        if (args.holes > 0) mesh = punchHoles(mesh, args.holes);
        Row row;
        row.name = path.substr(path.find_last_of('/') + 1) +
                   (args.subdivide > 0 ? " Loop x" + std::to_string(args.subdivide) : std::string()) +
                   (args.holes > 0 ? " (" + std::to_string(args.holes) + " holes)" : "");
        const MeshReport report = validateMesh(mesh);
        row.tris = mesh.triangles.size();
        row.boundaryEdges = report.boundaryEdges;
        row.closed = report.closed();
        std::printf("== %s: %llu triangles, %llu boundary, %llu non-manifold, %llu inconsistent edges, %s\n", row.name.c_str(),
                    (unsigned long long)row.tris, (unsigned long long)report.boundaryEdges,
                    (unsigned long long)report.nonManifoldEdges, (unsigned long long)report.inconsistentlyOrientedEdges,
                    row.closed ? "closed" : "not closed");
        std::fflush(stdout);

        if (args.errors) {
            MeshToLevelSetOptions o;
            o.voxelCount = args.errorRes;
            o.sign = SignMode::Winding;
            const auto wn = meshToLevelSet(mesh, o);
            o.sign = SignMode::Pseudonormal;
            const auto pn = meshToLevelSet(mesh, o);
            const double h = wn->voxelSize()[0];
            openvdb::FloatGrid::Ptr ov;
            if (args.openvdb) ov = openvdbLevelSet(mesh, h, 3.0f);
            const ExactReference ref(mesh);
            // samples: band voxels (hash) and uniform voxel centres in the grown box
            std::vector<openvdb::Coord> band, volume;
            const uint64_t stride = std::max<uint64_t>(1, wn->activeVoxelCount() / std::max<uint64_t>(1, args.samples));
            for (auto it = wn->tree().cbeginValueOn(); it; ++it) {
                const openvdb::Coord c = it.getCoord();
                if ((uint64_t(c.x() * 73856093u ^ c.y() * 19349663u ^ c.z() * 83492791u) % stride) == 0) band.push_back(c);
            }
            const BBoxd b = mesh.bounds();
            const Vec3d grow = (b.max() - b.min()) * 0.1;
            std::mt19937_64 rng(7);
            for (uint64_t i = 0; i < args.samples; ++i) {
                Vec3d p;
                for (int k = 0; k < 3; ++k)
                    p[k] = std::uniform_real_distribution<double>(b.min()[k] - grow[k], b.max()[k] + grow[k])(rng);
                volume.push_back(openvdb::Coord::round(wn->worldToIndex(p)));
            }
            ErrorRow& e = row.err;
            e.bandSamples = band.size();
            const openvdb::FloatGrid* grids[3] = {pn.get(), wn.get(), ov.get()};
            for (int set = 0; set < 2; ++set) {
                const std::vector<openvdb::Coord>& pts = set == 0 ? band : volume;
                std::vector<double> w(pts.size());
                tbb::parallel_for(tbb::blocked_range<size_t>(0, pts.size(), 16), [&](const tbb::blocked_range<size_t>& r) {
                    for (size_t i = r.begin(); i != r.end(); ++i) w[i] = ref.windingNumber(wn->indexToWorld(pts[i]));
                });
                for (size_t i = 0; i < pts.size(); ++i) {
                    if (!(std::abs(std::abs(w[i]) - 0.5) > 0.25)) continue;
                    const bool inside = std::abs(w[i]) > 0.5;
                    (set == 0 ? e.bandDecisive : e.volumeDecisive)++;
                    for (int m = 0; m < 3; ++m) {
                        if (!grids[m]) continue;
                        const float v = grids[m]->tree().getValue(pts[i]);
                        if (v == 0.0f) continue; // a voxel centre on a triangle: distance 0, no sign
                        if ((v < 0.0f) != inside) (set == 0 ? e.bandErr[m] : e.volumeErr[m])++;
                    }
                    if (set == 0 && ov && !ov->tree().isValueOn(pts[i])) ++e.bandMissingOpenvdb;
                }
            }
            row.haveErr = true;
            std::printf("errors at %d: band %llu decisive of %llu samples: pseudonormal %llu, winding %llu, openvdb %s "
                        "(openvdb band missing %llu); volume %llu decisive of %llu: pseudonormal %llu, winding %llu, openvdb %s\n",
                        args.errorRes, (unsigned long long)e.bandDecisive, (unsigned long long)band.size(),
                        (unsigned long long)e.bandErr[0], (unsigned long long)e.bandErr[1],
                        ov ? std::to_string(e.bandErr[2]).c_str() : "-", (unsigned long long)e.bandMissingOpenvdb,
                        (unsigned long long)e.volumeDecisive, (unsigned long long)volume.size(), (unsigned long long)e.volumeErr[0],
                        (unsigned long long)e.volumeErr[1], ov ? std::to_string(e.volumeErr[2]).c_str() : "-");
            std::fflush(stdout);
            if (!args.png.empty() && &path == &args.meshes.back()) slicePicture(args.png, mesh, grids, ref);
        }
        if (args.timing) {
            MeshToLevelSetOptions o;
            o.voxelCount = args.res;
            MeshToLevelSetStats ws;
            // alternate the two modes, best of each
            double pn = 1e300, wn = 1e300;
            for (int i = 0; i < args.repeat; ++i) {
                o.sign = SignMode::Pseudonormal;
                pn = std::min(pn, bestOf(1, [&] { meshToLevelSet(mesh, o); }));
                o.sign = SignMode::Winding;
                wn = std::min(wn, bestOf(1, [&] { meshToLevelSet(mesh, o, &ws); }));
            }
            row.pn = pn;
            row.wn = wn;
            row.evals = ws.windingEvaluations;
            row.active = ws.activeVoxels;
            row.haveTime = true;
            std::printf("time at %d (best of %d): pseudonormal %.3f s, winding %.3f s (%.2fx; %llu evaluations, %llu of them "
                        "alone, %llu active voxels)\n",
                        args.res, args.repeat, pn, wn, wn / pn, (unsigned long long)ws.windingEvaluations,
                        (unsigned long long)ws.windingIndividual, (unsigned long long)ws.activeVoxels);
            std::printf("  winding stages: fast winding number %.3f s, hierarchy %.3f s, candidates %.3f s, distances and "
                        "leaf signs %.3f s, tree and tile signs %.3f s; %llu current edges\n",
                        ws.secondsWinding, ws.secondsHierarchy, ws.secondsCandidates, ws.secondsDistance, ws.secondsFinish,
                        (unsigned long long)ws.currentEdges);
            std::fflush(stdout);
            if (args.fill) {
                o.sign = SignMode::Auto;
                o.validation = &report;
                double band = 1e300, filled = 1e300;
                MeshToLevelSetStats fs;
                for (int i = 0; i < args.repeat; ++i) {
                    o.fillInterior = false;
                    band = std::min(band, bestOf(1, [&] { meshToLevelSet(mesh, o); }));
                    o.fillInterior = true;
                    filled = std::min(filled, bestOf(1, [&] { meshToLevelSet(mesh, o, &fs); }));
                }
                row.band = band;
                row.filled = filled;
                row.haveFill = true;
                std::printf("fill at %d (auto sign: %s): band %.3f s, filled %.3f s (%.2fx; %llu voxels activated, %llu inside tiles)\n",
                            args.res, toString(fs.sign), band, filled, filled / band, (unsigned long long)fs.filledVoxels,
                            (unsigned long long)fs.insideTiles);
                std::fflush(stdout);
            }
        }
        rows.push_back(row);
    }
    // markdown summary
    if (args.errors) {
        std::printf("\n| mesh (triangles, boundary edges) | band samples decisive | pseudonormal wrong | winding wrong | OpenVDB wrong (band missing) "
                    "| volume samples decisive | pseudonormal wrong | winding wrong | OpenVDB wrong |\n|---|---|---|---|---|---|---|---|---|\n");
        for (const Row& r : rows) {
            if (!r.haveErr) continue;
            const ErrorRow& e = r.err;
            std::printf("| %s (%llu, %llu) | %llu | %llu | %llu | %s (%llu) | %llu | %llu | %llu | %s |\n", r.name.c_str(),
                        (unsigned long long)r.tris, (unsigned long long)r.boundaryEdges, (unsigned long long)e.bandDecisive,
                        (unsigned long long)e.bandErr[0], (unsigned long long)e.bandErr[1],
                        args.openvdb ? std::to_string(e.bandErr[2]).c_str() : "-", (unsigned long long)e.bandMissingOpenvdb,
                        (unsigned long long)e.volumeDecisive, (unsigned long long)e.volumeErr[0], (unsigned long long)e.volumeErr[1],
                        args.openvdb ? std::to_string(e.volumeErr[2]).c_str() : "-");
        }
    }
    if (args.timing) {
        std::printf("\n| mesh, %d | pseudonormal s | winding s | winding / pseudonormal |%s\n|---|---|---|---|%s\n", args.res,
                    args.fill ? " band s (auto) | filled s | filled / band |" : "", args.fill ? "---|---|---|" : "");
        for (const Row& r : rows) {
            if (!r.haveTime) continue;
            std::printf("| %s | %.3f | %.3f | %.2fx |", r.name.c_str(), r.pn, r.wn, r.wn / r.pn);
            if (r.haveFill) std::printf(" %.3f | %.3f | %.2fx |", r.band, r.filled, r.filled / r.band);
            std::printf("\n");
        }
    }
    return 0;
}
