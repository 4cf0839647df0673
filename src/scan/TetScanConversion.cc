// SPDX-License-Identifier: Apache-2.0
// T4 scan conversion (Erleben & Dohlmann). See TetScanConversion.h.
#include "detail/ProgressCheck.h"
#include "detail/Timer.h"
#include "detail/VoxelBudget.h"

#include <levelforge/core/Exceptions.h>
#include <levelforge/mesh/MeshToLevelSet.h>
#include <levelforge/core/Progress.h>
#include <levelforge/scan/TetScanConversion.h>
#include "scan/TetScanInternal.h"
#include <levelforge/core/MeshValidation.h>

#include <openvdb/tools/SignedFloodFill.h>

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_sort.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <memory>
#include <sstream>

namespace levelforge {

namespace scan_internal {

struct Point2
{
    double x, y;
};
/// Slice points of one face's shell on one plane: up to kMaxMergedTets tetrahedra x 16 footprint
/// vertices (a hull of 12 points has at most 20 faces, so every shell here fits).
constexpr int kMaxMergedTets = 24;
constexpr int kMaxSlicePoints = kMaxMergedTets * CrossSection::kMaxVertices;

using detail::Clock;
using detail::secondsSince;

inline int floorDiv(int a, int b) { return (a >= 0) ? a / b : -((-a + b - 1) / b); }

int sliceTetrahedron(const Tetrahedron& tet, double z, double* x, double* y)
{
    std::array<Vec3d, 4> p = tet.p;
    std::sort(p.begin(), p.end(), [](const Vec3d& a, const Vec3d& b) {
        return a[2] < b[2] || (a[2] == b[2] && (a[0] < b[0] || (a[0] == b[0] && a[1] < b[1])));
    });
    if (z < p[0][2] || z > p[3][2]) return 0;
    auto cut = [&](int i, int j, int k) {
        const Vec3d& a = p[i];
        const Vec3d& b = p[j];
        const double dz = b[2] - a[2];
        const double t = dz > 0.0 ? std::clamp((z - a[2]) / dz, 0.0, 1.0) : 0.0;
        x[k] = a[0] + t * (b[0] - a[0]);
        y[k] = a[1] + t * (b[1] - a[1]);
    };
    if (z < p[1][2]) { // case A: below p1
        cut(0, 3, 0); cut(0, 1, 1); cut(0, 2, 2);
        return 3;
    }
    if (z < p[2][2]) { // case B: between p1 and p2 (convex quad in this order)
        cut(0, 3, 0); cut(1, 3, 1); cut(1, 2, 2); cut(0, 2, 3);
        return 4;
    }
    cut(0, 3, 0); cut(1, 3, 1); cut(2, 3, 2); // case C: above p2
    return 3;
}

/// Convex hull (counter-clockwise, collinear points dropped) of n points into cs. False if it has
/// more than CrossSection::kMaxVertices vertices. A hull that degenerates to a segment or a point
/// keeps its 1–2 vertices (crossSectionSpan handles them).
bool convexPolygon(Point2* pts, int n, CrossSection& cs)
{
    std::sort(pts, pts + n, [](const Point2& a, const Point2& b) { return a.x < b.x || (a.x == b.x && a.y < b.y); });
    n = int(std::unique(pts, pts + n, [](const Point2& a, const Point2& b) { return a.x == b.x && a.y == b.y; }) - pts);
    if (n <= 2) {
        cs.count = uint32_t(n);
        for (int i = 0; i < n; ++i) { cs.x[i] = pts[i].x; cs.y[i] = pts[i].y; }
        return n > 0;
    }
    auto cross = [](const Point2& o, const Point2& a, const Point2& b) {
        return (a.x - o.x) * (b.y - o.y) - (a.y - o.y) * (b.x - o.x);
    };
    Point2 h[2 * kMaxSlicePoints + 2];
    int k = 0;
    for (int i = 0; i < n; ++i) {
        while (k >= 2 && cross(h[k - 2], h[k - 1], pts[i]) <= 0.0) --k;
        h[k++] = pts[i];
    }
    for (int i = n - 2, t = k + 1; i >= 0; --i) {
        while (k >= t && cross(h[k - 2], h[k - 1], pts[i]) <= 0.0) --k;
        h[k++] = pts[i];
    }
    k = std::max(k - 1, 1);
    if (k > CrossSection::kMaxVertices) return false;
    cs.count = uint32_t(k);
    for (int i = 0; i < k; ++i) { cs.x[i] = h[i].x; cs.y[i] = h[i].y; }
    return true;
}

bool conservativeFootprint(const Tetrahedron& tet, int z, CrossSection& cs)
{
    double zmin = tet.p[0][2], zmax = zmin;
    for (int k = 1; k < 4; ++k) { zmin = std::min(zmin, tet.p[k][2]); zmax = std::max(zmax, tet.p[k][2]); }
    const double za = std::max(double(z) - 0.5, zmin), zb = std::min(double(z) + 0.5, zmax);
    if (za > zb) return false;
    // Points of the tetrahedron clipped to [za, zb], projected: both slices + corners in between.
    Point2 pts[16];
    int n = 0;
    double sx[4], sy[4];
    for (double zz : {za, zb}) {
        const int m = sliceTetrahedron(tet, zz, sx, sy);
        for (int i = 0; i < m; ++i) pts[n++] = {sx[i], sy[i]};
    }
    for (int k = 0; k < 4; ++k)
        if (tet.p[k][2] >= za && tet.p[k][2] <= zb) pts[n++] = {tet.p[k][0], tet.p[k][1]};
    // Minkowski sum with the cell's square [-1/2, 1/2]^2, then the 2-D convex hull. A convex
    // polygon plus a square has at most (polygon vertices + 4) vertices; the clipped tetrahedron
    // projects to at most 12, so CrossSection's 16 suffice.
    Point2 q[64];
    int nq = 0;
    for (int i = 0; i < n; ++i)
        for (int c = 0; c < 4; ++c) q[nq++] = {pts[i].x + ((c & 1) ? 0.5 : -0.5), pts[i].y + ((c & 2) ? 0.5 : -0.5)};
    return convexPolygon(q, nq, cs);
}


/// The shell of one face: tets[first, first + count) of the face-ordered tetrahedron list.
struct SortedShell
{
    uint32_t triangle, first, count;
    double zmin, zmax;
};


struct Binned
{
    uint64_t key;
    CrossSection cs;
};

} // namespace scan_internal

TetScanConverter::TetScanConverter(const TriangleMesh& mesh, const TetScanOptions& options)
    : mMesh(mesh), mOptions(options)
{
}

openvdb::FloatGrid::Ptr TetScanConverter::run(TetScanStats* statsOut)
{
    using namespace scan_internal;
    using openvdb::Coord;
    using FloatLeaf = openvdb::FloatTree::LeafNodeType;
    openvdb::initialize();
    const TetScanOptions& o = mOptions;
    if (o.slabDepth < 8 || o.slabDepth % 8 || o.slabWidth < 8 || o.slabWidth % 8 || o.slabDepth > 512 ||
        o.slabWidth > 512) {
        std::ostringstream os;
        os << "slab depth and width must be multiples of 8 in [8, 512], got " << o.slabDepth << " and "
           << o.slabWidth;
        throw InvalidArgumentError(os.str());
    }
    requireUsableMesh(mMesh);
    const double h = resolveVoxelSize(mMesh, o);
    // Band limits in voxels, held in float as they always were.
    const float extWf = static_cast<float>(o.widthInVoxels(o.exteriorWidth, h));
    const float intWf = static_cast<float>(o.widthInVoxels(o.interiorWidth, h));
    for (float w : {extWf, intWf})
        if (!std::isfinite(w) || w <= 0.0f) {
            std::ostringstream os;
            os << "band width must be a positive number of voxels, got " << w;
            throw InvalidArgumentError(os.str());
        }
    const double extW = extWf, intW = intWf;
    const double eps = std::max(extW, intW); // voxels
    {
        const BBoxd b = mMesh.bounds();
        for (int k = 0; k < 3; ++k) {
            const double lo = b.min()[k] / h - 4 * eps - 1024, hi = b.max()[k] / h + 4 * eps + 1024;
            if (!(std::abs(lo) < 1.0e9 && std::abs(hi) < 1.0e9)) {
                std::ostringstream os;
                os << "voxel size " << h << " is too small for this mesh: index coordinates would reach "
                   << std::max(std::abs(lo), std::abs(hi)) << " (limit 1e9)";
                throw ResourceLimitError(os.str());
            }
        }
    }
    TetScanStats stats;
    stats.voxelSize = h;
    stats.shell = o.shell;
    stats.coverage = o.coverage;
    auto* interrupter = o.interrupter;
    if (interrupter) interrupter->start("mesh to level set (scan conversion)");
    if (o.maxVoxels > 0) {
        // Memory guard, the one every operator uses: the leaves within the band of the surface
        // (the dilated surface's real volume, not area × width), plus each thread's dense slab.
        std::vector<Vec3d> cellPts(mMesh.points.size());
        for (size_t i = 0; i < cellPts.size(); ++i) cellPts[i] = mMesh.points[i] / h + Vec3d(0.5);
        detail::checkMeshBandBudget("mesh to level set (scan conversion)", cellPts, mMesh.triangles, eps,
                                    double(detail::budgetThreads()) * double(o.slabDepth) * o.slabWidth * o.slabWidth * 8.0,
                                    o.maxVoxels, o.interrupter);
    }

    // ---- 1. shell, in index space (voxel centres at integer coordinates)
    auto t0 = Clock::now();
    PseudoNormals normals(mMesh);
    TriangleMesh indexMesh;
    indexMesh.triangles = mMesh.triangles;
    indexMesh.points.resize(mMesh.points.size());
    for (size_t i = 0; i < mMesh.points.size(); ++i) indexMesh.points[i] = mMesh.points[i] / h;
    TetrahedralShellOptions shellOpt;
    shellOpt.method = o.shell;
    shellOpt.epsilon = eps;
    shellOpt.coverage = o.coverage;
    TetrahedralShellStats shellStats;
    std::vector<Tetrahedron> tets = buildTetrahedralShell(indexMesh, normals, shellOpt, &shellStats);
    stats.triangles = shellStats.faces;
    stats.skippedDegenerate = shellStats.skippedDegenerate;
    stats.tetrahedra = shellStats.tetrahedra;
    stats.limitedExtrusions = shellStats.limitedExtrusions;
    const SlabTriangles tris = SlabTriangles::build(mMesh, normals, h);
    stats.secondsShell = secondsSince(t0);
    progress_internal::check(interrupter, 10);

    // ---- 2. sort by min z (Figure 8), one entry per face: the tetrahedra of a face are
    // contiguous in `tets` (buildTetrahedralShell orders them by face)
    t0 = Clock::now();
    std::vector<SortedShell> sorted;
    for (size_t i = 0; i < tets.size();) {
        size_t j = i + 1;
        while (j < tets.size() && tets[j].triangle == tets[i].triangle) ++j;
        sorted.push_back({tets[i].triangle, uint32_t(i), uint32_t(j - i), 0.0, 0.0});
        i = j;
    }
    tbb::parallel_for(tbb::blocked_range<size_t>(0, sorted.size(), 4096), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t i = r.begin(); i != r.end(); ++i) {
            SortedShell& sh = sorted[i];
            double lo = tets[sh.first].p[0][2], hi = lo;
            for (uint32_t t = sh.first; t < sh.first + sh.count; ++t)
                for (int k = 0; k < 4; ++k) { lo = std::min(lo, tets[t].p[k][2]); hi = std::max(hi, tets[t].p[k][2]); }
            sh.zmin = lo;
            sh.zmax = hi;
        }
    });
    tbb::parallel_sort(sorted.begin(), sorted.end(), [](const SortedShell& a, const SortedShell& b) {
        return a.zmin < b.zmin || (a.zmin == b.zmin && a.triangle < b.triangle);
    });
    stats.secondsSort = secondsSince(t0);

    // ---- 3. sweep over z-slabs (Figure 9), bin polygons into dense slabs, fill, scatter.
    // Each tetrahedron is cut by each plane (cases A, B, C); the cuts of one face's tetrahedra
    // are merged into one convex polygon — the slice of the face's shell, which is convex (a hull
    // from its centre, a box or a prism), so the merge is exact — and rasterized once.
    constexpr double tol = 1e-7; // voxels
    const int D = o.slabDepth, W = o.slabWidth;
    CpuSlabBackend cpu;
    const SlabBackend& backend = o.backend ? *o.backend : cpu;
    auto tree = std::make_shared<openvdb::FloatTree>(float(extW * h));
    const float bg = float(extW * h);
    if (!sorted.empty()) {
        const double reach = o.conservative ? 0.5 : tol; // how far (z) a tetrahedron reaches a plane
        double zlo = sorted.front().zmin, zhi = sorted.front().zmax;
        for (const SortedShell& sh : sorted) zhi = std::max(zhi, sh.zmax);
        const int kLo = int(std::ceil(zlo - reach)), kHi = int(std::floor(zhi + reach));
        const int zStart = floorDiv(kLo, D) * D;
        std::vector<uint32_t> active;
        size_t next = 0;
        double sweepSec = 0, fillSec = 0;
        for (int z0 = zStart; z0 <= kHi; z0 += D) {
            const int z1 = z0 + D - 1;
            auto ts = Clock::now();
            while (next < sorted.size() && sorted[next].zmin <= double(z1) + reach) active.push_back(uint32_t(next++));
            active.erase(std::remove_if(active.begin(), active.end(),
                                        [&](uint32_t i) { return sorted[i].zmax < double(z0) - reach; }),
                         active.end());
            if (active.empty()) continue;
            tbb::enumerable_thread_specific<std::vector<Binned>> tls;
            tbb::enumerable_thread_specific<uint64_t> sections(0);
            tbb::parallel_for(tbb::blocked_range<size_t>(0, active.size(), 64), [&](const tbb::blocked_range<size_t>& r) {
                progress_internal::check(interrupter);
                std::vector<Binned>& bins = tls.local();
                uint64_t& nsec = sections.local();
                Point2 pts[kMaxSlicePoints];
                auto bin = [&](CrossSection& cs, int k, uint32_t triangle) {
                    const int n = int(cs.count);
                    cs.z = k;
                    cs.triangle = triangle;
                    double xmin = cs.x[0], xmax = xmin, ymin = cs.y[0], ymax = ymin;
                    for (int i = 1; i < n; ++i) {
                        xmin = std::min(xmin, cs.x[i]); xmax = std::max(xmax, cs.x[i]);
                        ymin = std::min(ymin, cs.y[i]); ymax = std::max(ymax, cs.y[i]);
                    }
                    const int ix0 = int(std::ceil(xmin - tol)), ix1 = int(std::floor(xmax + tol));
                    const int iy0 = int(std::ceil(ymin - tol)), iy1 = int(std::floor(ymax + tol));
                    if (ix0 > ix1 || iy0 > iy1) return;
                    ++nsec;
                    for (int tx = floorDiv(ix0, W); tx <= floorDiv(ix1, W); ++tx)
                        for (int ty = floorDiv(iy0, W); ty <= floorDiv(iy1, W); ++ty) {
                            const uint64_t key = (uint64_t(uint32_t(tx + (1 << 30))) << 32) | uint32_t(ty + (1 << 30));
                            bins.push_back({key, cs});
                        }
                };
                // One tetrahedron's polygon on plane k (plain slice or conservative footprint).
                auto cut = [&](const Tetrahedron& tet, int k, CrossSection& cs) {
                    if (o.conservative) return conservativeFootprint(tet, k, cs);
                    const int n = sliceTetrahedron(tet, double(k), cs.x.data(), cs.y.data());
                    cs.count = uint32_t(n);
                    return n > 0;
                };
                for (size_t a = r.begin(); a != r.end(); ++a) {
                    const SortedShell& sh = sorted[active[a]];
                    const int ka = std::max(z0, int(std::ceil(sh.zmin - reach)));
                    const int kb = std::min(z1, int(std::floor(sh.zmax + reach)));
                    for (int k = ka; k <= kb; ++k) {
                        CrossSection cs;
                        int np = 0, pieces = 0;
                        for (uint32_t t = sh.first; t < sh.first + sh.count; ++t) {
                            CrossSection piece;
                            if (!cut(tets[t], k, piece)) continue;
                            if (pieces++ == 0) cs = piece;
                            for (uint32_t i = 0; i < piece.count && np < kMaxSlicePoints; ++i)
                                pts[np++] = {piece.x[i], piece.y[i]};
                        }
                        if (pieces == 0) continue;
                        if (pieces == 1 || (sh.count <= uint32_t(kMaxMergedTets) && convexPolygon(pts, np, cs))) {
                            bin(cs, k, sh.triangle);
                            continue;
                        }
                        for (uint32_t t = sh.first; t < sh.first + sh.count; ++t) // unmergeable: one by one
                            if (cut(tets[t], k, cs)) bin(cs, k, sh.triangle);
                    }
                }
            });
            std::vector<Binned> items;
            for (auto& v : tls) items.insert(items.end(), v.begin(), v.end());
            for (uint64_t v : sections) stats.crossSections += v;
            tbb::parallel_sort(items.begin(), items.end(), [](const Binned& a, const Binned& b) { return a.key < b.key; });
            std::vector<size_t> groups;
            for (size_t i = 0; i < items.size(); ++i)
                if (i == 0 || items[i].key != items[i - 1].key) groups.push_back(i);
            groups.push_back(items.size());
            const size_t ng = groups.size() - 1;
            stats.slabItems += items.size();
            stats.slabs += ng;
            sweepSec += secondsSince(ts);

            ts = Clock::now();
            std::vector<std::vector<std::unique_ptr<FloatLeaf>>> leaves(ng); // owned until added
            std::vector<uint64_t> raster(ng, 0), activeCount(ng, 0);
            // slabs go to the backend in batches (a device backend dispatches a batch at once)
            const size_t batch = std::max<size_t>(1, backend.preferredBatch());
            std::vector<DenseSlab> slabs(std::min(batch, ng));
            std::vector<CrossSection> batchItems;
            std::vector<SlabJob> jobs;
            for (size_t g0 = 0; g0 < ng; g0 += batch) {
                progress_internal::check(interrupter);
                const size_t g1 = std::min(ng, g0 + batch);
                batchItems.clear();
                jobs.clear();
                for (size_t g = g0; g < g1; ++g) {
                    const uint64_t key = items[groups[g]].key;
                    const int tx = int(int64_t(key >> 32) - (1 << 30)), ty = int(int64_t(key & 0xffffffffu) - (1 << 30));
                    slabs[g - g0].reset(openvdb::CoordBBox(Coord(tx * W, ty * W, z0), Coord(tx * W + W - 1, ty * W + W - 1, z1)));
                    for (size_t i = groups[g]; i < groups[g + 1]; ++i) batchItems.push_back(items[i].cs);
                }
                for (size_t g = g0, at = 0; g < g1; ++g) {
                    const size_t n = groups[g + 1] - groups[g];
                    jobs.push_back({&slabs[g - g0], batchItems.data() + at, n});
                    at += n;
                }
                backend.fillBatch(jobs.data(), jobs.size(), tris);
                // scatter: one leaf per 8^3 block of the slab
                tbb::parallel_for(tbb::blocked_range<size_t>(g0, g1, 1), [&](const tbb::blocked_range<size_t>& r) {
                    for (size_t g = r.begin(); g != r.end(); ++g) {
                        const DenseSlab& slab = slabs[g - g0];
                        raster[g] = slab.rasterized;
                        const Coord lo = slab.box.min(), hi = slab.box.max();
                        for (int lx = lo.x(); lx <= hi.x(); lx += 8)
                            for (int ly = lo.y(); ly <= hi.y(); ly += 8)
                                for (int lz = lo.z(); lz <= hi.z(); lz += 8) {
                                    std::unique_ptr<FloatLeaf> leaf;
                                    for (int dx = 0; dx < 8; ++dx)
                                        for (int dy = 0; dy < 8; ++dy)
                                            for (int dz = 0; dz < 8; ++dz) {
                                                const Coord c(lx + dx, ly + dy, lz + dz);
                                                const size_t idx = slab.index(c);
                                                if (slab.tri[idx] == DenseSlab::kNone) continue;
                                                const double v = slab.dist[idx] / h;
                                                if (!(v < extW && v > -intW)) continue;
                                                if (!leaf) leaf = std::make_unique<FloatLeaf>(Coord(lx, ly, lz), bg, false);
                                                leaf->setValueOn(c, float(slab.dist[idx]));
                                                ++activeCount[g];
                                            }
                                    // inactive voxels of the leaf get +/- background from the flood fill
                                    if (leaf) leaves[g].push_back(std::move(leaf));
                                }
                    }
                });
            }
            for (size_t g = 0; g < ng; ++g) {
                stats.voxelsRasterized += raster[g];
                stats.activeVoxels += activeCount[g];
                for (auto& l : leaves[g]) {
                    tree->addLeaf(l.get()); // owned here until the tree has it
                    l.release();
                }
            }
            fillSec += secondsSince(ts);
            progress_internal::check(interrupter, 10 + int(85.0 * double(z0 - zStart + D) / double(kHi - zStart + D)));
        }
        stats.secondsSweep = sweepSec;
        stats.secondsFill = fillSec;
    }

    // ---- 4. finish: signed flood fill, grid
    t0 = Clock::now();
    openvdb::tools::signedFloodFill(*tree);
    auto grid = openvdb::FloatGrid::create(tree);
    grid->setTransform(openvdb::math::Transform::createLinearTransform(h));
    grid->setGridClass(openvdb::GRID_LEVEL_SET);
    grid->setName(o.gridName);
    stats.secondsFinish = secondsSince(t0);
    if (interrupter) { interrupter->wasInterrupted(100); interrupter->end(); }
    if (statsOut) *statsOut = stats;
    return grid;
}

openvdb::FloatGrid::Ptr meshToLevelSetScan(const TriangleMesh& mesh, const TetScanOptions& options, TetScanStats* stats)
{
    return TetScanConverter(mesh, options).run(stats);
}

} // namespace levelforge
