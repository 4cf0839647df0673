// SPDX-License-Identifier: Apache-2.0
// Mesh → exact narrow-band level set (Chang, Cha, Ihm 2008): the exact band. See MeshToLevelSet.h.
// This translation unit holds the heavy OpenVDB template work of the main road.
#include "detail/ProgressCheck.h"
#include "detail/VoxelBudget.h"
#include "detail/Timer.h"
#include "mesh/MeshToLevelSetInternal.h"
#include "mesh/PreparedTriangleBox.h"
#include "mesh/SearchLists.h"
#include "mesh/WindingSignInternal.h"

#include <levelforge/core/Exceptions.h>
#include <levelforge/mesh/MeshToLevelSet.h>
#include <levelforge/core/MeshValidation.h>
#include <levelforge/mesh/MicrotriangleVoxelizer.h>
#include <levelforge/core/Progress.h>
#include <levelforge/core/TriangleDistance.h>
#include <levelforge/mesh/FastWindingNumber.h>

#include <openvdb/tools/Prune.h>
#include <openvdb/tools/SignedFloodFill.h>

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif
#include <chrono>
#include <cmath>
#include <limits>
#include <memory>
#include <sstream>
#include <cstdio>
#include <cstdlib>

namespace levelforge {
namespace meshtols_internal {

namespace { // helpers of computeLeaf(), private to this translation unit (direct calls, no PLT)

/// The search state of one voxel (or of a block's centre): the best triangle so far and the
/// pruning radii.
struct VoxelSearch
{
    Vec3d p;
    double best2;
    uint32_t bestT = kNone;
    TriangleClosestPoint bestCp{Vec3d(0.0), 0.0, TriangleFeature::Face};
    double bm2;   // (sqrt(best2) + margin + extra)²: boxes and bounds at or beyond it are pruned
    float bm2f;
    float em2f;   // (sqrt(best2) + margin)²: triangles with bounds below it are evaluated exactly
    double extra = 0.0; // block search: triangles are listed this much beyond the best distance
    bool listing = false; // block search: list them (Scratch::bt*)
    float tauK = 0.0f, tauR = 0.0f; // block search: the separating plane's rounding allowance
    uint32_t seed = kNone;

    void tighten(double margin)
    {
        const double em = std::sqrt(best2) + margin, bm = em + extra;
        bm2 = bm * bm;
        bm2f = float(bm2);
        em2f = float(em * em);
    }
};

inline void evaluate(const Context& ctx, VoxelSearch& v, uint32_t t, Scratch& s)
{
    const Vec3I& tri = ctx.mesh.triangles[t];
    ++s.evaluations;
    const TriangleClosestPoint cp = closestPointOnTriangle(v.p, ctx.cellPts[tri[0]], ctx.cellPts[tri[1]], ctx.cellPts[tri[2]]);
    // ties go to the smaller triangle index (as on a Vulkan device), whatever the search order
    if (cp.distanceSqr < v.best2 || (cp.distanceSqr == v.best2 && v.bestT != kNone && t < v.bestT)) {
        v.best2 = cp.distanceSqr;
        v.bestT = t;
        v.bestCp = cp;
        v.tighten(ctx.margin);
    }
}

/// Bounds of a cluster's triangles, then exact evaluation of the survivors in increasing bound
/// order while the bound is below the best distance. In a block search (v.listing), the
/// triangles with a bound below the enlarged radius are also listed (listTriangles()).
__attribute__((always_inline)) inline void visitCluster(const Context& ctx, uint32_t ci, VoxelSearch& v, Scratch& s)
{
    const TriangleCluster& c = ctx.hierarchy.clusters()[ci];
    const Vec3d q = v.p - c.origin;
    alignas(32) float lb2[kClusterSize];
    s.boundTests += c.count;
    uint32_t mask;
    if (v.listing && s.btCount <= kMaxListed && !s.btClustersOnly) {
        alignas(32) float g[3][kClusterSize];
        mask = clusterBoundsDirections(c, float(q[0]), float(q[1]), float(q[2]), v.bm2f, lb2, g[0], g[1], g[2]);
        listTriangles(c, ci, mask, lb2, g, v.tauK, v.tauR, s);
    } else {
        mask = clusterBounds(c, float(q[0]), float(q[1]), float(q[2]), v.bm2f, lb2);
        if (v.listing && mask) { // a block with too many triangles to list: its clusters only
            s.btLanes += uint32_t(__builtin_popcount(mask));
            if (s.btCount <= kMaxListed) s.btCount = kMaxListed + 1;
        }
    }
    if (v.listing && mask) { // the block's clusters, keyed by their smallest bound
        float lo = lb2[__builtin_ctz(mask)];
        for (uint32_t m = mask; m; m &= m - 1) lo = std::min(lo, lb2[__builtin_ctz(m)]);
        s.blockList.emplace_back(std::sqrt(lo), ci);
    }
    while (mask) {
        uint32_t pick = uint32_t(__builtin_ctz(mask));
        for (uint32_t m = mask & (mask - 1); m; m &= m - 1) {
            const uint32_t lane = uint32_t(__builtin_ctz(m));
            if (lb2[lane] < lb2[pick]) pick = lane;
        }
        mask &= ~(1u << pick);
        if (!(lb2[pick] < v.em2f)) break;
        const uint32_t t = c.ids[pick];
        if (t == v.seed || t == v.bestT) continue; // evaluated already (a seed, or a piece of a split triangle)
        evaluate(ctx, v, t, s);
    }
}

/// Depth-first, nearer child first, from `root`, pruning boxes at or beyond the search radius.
inline void searchSubtree(const Context& ctx, uint32_t root, double rootD2, VoxelSearch& v, Scratch& s)
{
    const auto& nodes = ctx.hierarchy.nodes();
    s.stack.clear();
    s.stack.emplace_back(root, rootD2);
    while (!s.stack.empty()) {
        const auto [ni, d2] = s.stack.back();
        s.stack.pop_back();
        if (d2 >= v.bm2) continue;
        const HierarchyNode& n = nodes[ni];
        if (n.isLeaf()) { visitCluster(ctx, n.left, v, s); continue; }
        const double dl = boxDistanceSqr(nodes[n.left], v.p), dr = boxDistanceSqr(nodes[n.right], v.p);
        s.nodeTests += 2;
        if (dl < dr) {
            if (dr < v.bm2) s.stack.emplace_back(n.right, dr);
            if (dl < v.bm2) s.stack.emplace_back(n.left, dl);
        } else {
            if (dl < v.bm2) s.stack.emplace_back(n.left, dl);
            if (dr < v.bm2) s.stack.emplace_back(n.right, dr);
        }
    }
}

} // namespace

/// Fills one output leaf with origin `origin`; returns nullptr if no voxel is active.
// cpOut / triOut (optional, together): receive leaves of closest-point offsets (voxel units) and
// closest-triangle indices for the active voxels.
LeafResult computeLeaf(const Context& ctx, const Coord& origin, Scratch& s, bool wantClosest)
{
    LeafResult res;
    leafFrontier(ctx, origin, s);
    if (s.order.empty()) return res;
    if (flatLeafDistances(ctx, origin, s, s.leafTri, s.leafCp))
        return finishFromClosest(ctx, origin, s, wantClosest, s.leafTri, s.leafCp);
    const auto& nodes = ctx.hierarchy.nodes();

    // Per voxel (Chang §4.1's culling, with a hierarchy instead of cell layers): the previous
    // voxel's closest triangle gives an upper bound; the frontier's subtrees are searched nearer
    // box first, clusters by their single-precision bounds, survivors exactly in increasing bound
    // order until the bound passes the best distance. The sign is the pseudonormal of the
    // closest feature (§4.2).
    res.sdf.reset(new FloatLeaf(origin, ctx.background, false));
    if (wantClosest) {
        res.cp.reset(new Vec3fLeaf(origin, openvdb::Vec3f(0.0f), false));
        res.tri.reset(new Int32Leaf(origin, -1, false));
    }
    uint64_t active = 0;
    const float bg = ctx.background;
    const bool pseudo = ctx.sign == SignMode::Pseudonormal;
    if (!pseudo) std::fill(s.vd, s.vd + 512, -1.0);
    uint32_t seed = kNone;
    VoxelSearch v;
    // Visits boxes [first, last) (at most 8, first a multiple of 4) of `level` nearest first,
    // descending into the 8 boxes below each one closer than the search radius.
    auto descend = [&](auto&& self, size_t level, size_t first, size_t last, float qx, float qy, float qz) -> void {
        const Scratch::Level& L = s.levels[level];
        alignas(16) float d2[8];
        boxDistances(L.box.data(), L.stride, first, first + 8, qx, qy, qz, d2);
        uint32_t near[8], nn = 0;
        for (size_t i = first; i < last; ++i) {
            ++s.nodeTests;
            if (d2[i - first] < v.bm2f) near[nn++] = uint32_t(i - first);
        }
        sortNearestFirst(near, nn, d2);
        for (uint32_t k = 0; k < nn; ++k) {
            const uint32_t j = near[k];
            if (!(d2[j] < v.bm2f)) continue;
            const size_t i = first + j;
            if (level > 0) {
                const size_t below = s.levels[level - 1].count;
                self(self, level - 1, 8 * i, std::min(8 * i + 8, below), qx, qy, qz);
                continue;
            }
            const uint32_t ni = s.order[i].second;
            const HierarchyNode& n = nodes[ni];
            if (n.isLeaf()) visitCluster(ctx, n.left, v, s);
            else searchSubtree(ctx, ni, double(d2[j]), v, s);
        }
    };
    // Blocks of 2×2×2 voxels first: a block with no triangle within
    // limit + r of its centre c (r = √3/2, the distance of its voxel centres) holds no voxel
    // within the limit (nothing to search, its signs come from the flood fill). Otherwise the
    // block's search finds the distance D of c and lists every triangle T whose bound at c is
    // below D + 2r: a triangle closest to a voxel v of the block has
    // d(c, T) <= d(v, T) + r <= d(v, T_c) + r <= D + 2r. (For a triangle split into pieces, the
    // piece holding v's closest point x is in the leaf's frontier, d(v, x) < limit, and its box
    // is within |c - x| <= D + 2r of c, so the search visits it.) With T its separating plane at
    // c: the closest point x_c of T to c (as the single-precision bound finds it) and the unit
    // vector g = (c - x_c) / d(c, T). T lies beyond that plane, (c - y)·g >= d(c, T) for every
    // y in T (x_c is the projection of c onto the convex T), so for any voxel v
    //     d(v, T) >= (v - y)·g >= d(c, T) + g·(v - c),
    // a bound tight to first order where d(c, T) = D + 2r is not (where x_c lies inside the
    // face it is the plane distance at v, exact). Each voxel takes the larger of the two bounds
    // per listed triangle (one vectorised pass) and evaluates exactly, nearest bound first, the
    // triangles whose bound is below its best distance plus the margin: on armadillo_100k at
    // 256 voxels, band 20, 5 triangles per voxel pass of the 102 listed per block, where the
    // bound d(c, T) - r alone leaves 47. The plane's rounding allowance tauK (1 + tauR / d(c, T))
    // covers the single-precision closest point: a direction error |dx_c| / d(c, T) moves the
    // bound by at most (d(c, T) + diameter(T) + r) times it. (Until 2026-12-07 the block listed
    // clusters and each voxel visited those whose box came closer than its best distance,
    // 92 triangle bounds and 45 boxes per voxel; before that, wide bands, limit >= 8, searched
    // the frontier per voxel: 6x the box tests at band 20.)
    constexpr double kHalfDiagonal = 0.8660254037844387 + 1e-12;
    // narrow bands (limit below this) list clusters only: their voxels bound the clusters' triangles
    // at the voxel itself (half the exact evaluations of the planes at band 3, as fast)
    constexpr double kPlaneListLimit = 4.5;
    constexpr size_t kDirectCandidates = 12; // more candidates at a voxel: bound their clusters at the voxel
    const double blockReach = ctx.limit + kHalfDiagonal + ctx.margin;
    const double radius = ctx.hierarchy.maxClusterRadius();
    const float tauK = float(4e-6 * (ctx.limit + 2.0 * radius + 4.0)), tauR = float(2.0 * radius + 2.0);
    const size_t top = s.nLevels - 1;
    // a frontier of subtrees (more clusters within reach than kMaxFlat: a dense mesh in a few
    // cells) lists clusters only from the first block on
    s.btClustersOnly = !s.flat || ctx.limit < kPlaneListLimit;
    if (ctx.hierarchy.pieces() != 0 && s.btSeen.size() != ctx.mesh.triangles.size()) s.btSeen.assign(ctx.mesh.triangles.size(), 0u);
    for (int bx = 0; bx < 4; ++bx)
        for (int by = 0; by < 4; ++by)
            for (int bz = 0; bz < 4; ++bz) {
                if (s.poller && s.evaluations - s.reported >= WorkPoller::kReportStep) {
                    s.poller->report(s);
                    if (s.poller->stopped()) return LeafResult{};
                }
                v.p = Vec3d(origin.x() + 2 * bx + 1.0, origin.y() + 2 * by + 1.0, origin.z() + 2 * bz + 1.0);
                v.best2 = blockReach * blockReach;
                v.bestT = kNone;
                v.seed = seed;
                v.extra = 2.0 * kHalfDiagonal + ctx.margin;
                v.listing = true;
                v.tauK = tauK;
                v.tauR = tauR;
                s.btCount = 0;
                s.btLanes = 0;
                s.blockList.clear();
                if (!s.btSeen.empty() && ++s.btBlock == 0) { // a new stamp; all clear after 2^32 blocks
                    std::fill(s.btSeen.begin(), s.btSeen.end(), 0u);
                    s.btBlock = 1;
                }
                v.tighten(ctx.margin);
                if (seed != kNone) evaluate(ctx, v, seed, s);
                descend(descend, top, 0, s.levels[top].count, float(2 * bx - 3), float(2 * by - 3), float(2 * bz - 3));
                v.extra = 0.0;
                v.listing = false;
                if (v.bestT == kNone) continue;
                seed = v.bestT;
                {
                    const size_t padded = (s.btCount + 7) & ~size_t(7);
                    if (padded > s.btId.size()) s.growBlockTriangles(padded);
                    for (size_t i = s.btCount; i < padded; ++i) {
                        s.btPlane[i] = -1e30f;
                        s.btBall[i] = 1e30f;
                        s.btX[i] = s.btY[i] = s.btZ[i] = 0.0f;
                    }
                }
                const size_t listed = s.btCount, padded = (listed + 7) & ~size_t(7);
                const bool byClusters = listed > kMaxListed;
                // the next block of the leaf lists only clusters when this one had too many
                // triangles (dense meshes at coarse voxels: their blocks all do)
                s.btClustersOnly = s.btCount + s.btLanes > kMaxListed || ctx.limit < kPlaneListLimit;
                if (byClusters) {
                    std::sort(s.blockList.begin(), s.blockList.end());
                    blockBoxes(ctx, v.p, s);
                }
                for (int corner = 0; corner < 8; ++corner) {
                    const int vx = 2 * bx + (corner >> 2), vy = 2 * by + ((corner >> 1) & 1), vz = 2 * bz + (corner & 1);
                    ++s.candidateVoxels;
                    v.p = Vec3d(origin.x() + vx + 0.5, origin.y() + vy + 0.5, origin.z() + vz + 0.5);
                    v.best2 = ctx.limit2;
                    v.bestT = kNone;
                    v.seed = kNone;
                    v.tighten(ctx.margin);
                    if (byClusters) {
                        // too many triangles for a pass over each: the listed clusters' boxes at
                        // this voxel (one vectorised pass), then by key those whose box is within
                        // the search radius, their triangles' bounds at the voxel itself
                        v.seed = seed;
                        if (seed != kNone) evaluate(ctx, v, seed, s);
                        boxDistances(s.blockBox.data(), s.blockStride, 0, s.blockStride, float(vx & 1) - 0.5f,
                                     float(vy & 1) - 0.5f, float(vz & 1) - 0.5f, s.blockD2.data());
                        s.nodeTests += s.blockList.size();
                        for (size_t i = 0; i < s.blockList.size(); ++i) {
                            const double lo = double(s.blockList[i].first) - kHalfDiagonal - ctx.margin;
                            if (lo > 0.0 && lo * lo >= v.bm2) break;
                            if (s.blockD2[i] < v.bm2f) visitCluster(ctx, s.blockList[i].second, v, s);
                        }
                    } else {
                    // the listed triangles' bounds at this voxel (one vectorised pass); the
                    // smallest first (mostly the closest triangle: the tightest threshold), then
                    // exactly every other one below the best distance plus the margin
                    const float dx = float(vx & 1) - 0.5f, dy = float(vy & 1) - 0.5f, dz = float(vz & 1) - 0.5f;
                    const size_t first = blockTriangleBounds(s, padded, dx, dy, dz, s.btLb.data());
                    s.boundTests += listed;
                    if (listed != 0) evaluate(ctx, v, s.btId[first], s); // (a block that found a triangle lists it)
                    selectBelow(s.btLb.data(), padded, std::nextafter(float(std::sqrt(v.best2) + ctx.margin), 3.0e38f), s.btCand);
                    if (s.btCand.size() <= kDirectCandidates) {
                        for (const auto& [bound, i] : s.btCand) {
                            if (!(double(bound) < std::sqrt(v.best2) + ctx.margin)) continue;
                            const uint32_t t = s.btId[i];
                            if (t == v.bestT) continue;
                            evaluate(ctx, v, t, s);
                        }
                    } else {
                        // Many triangles tie to first order (tiny triangles next to the voxel, a
                        // fan around a vertex): their clusters' bounds at the voxel itself, as the
                        // search does (a cluster's entries are consecutive in the list).
                        uint32_t last = kNone;
                        for (const auto& [bound, i] : s.btCand) {
                            const uint32_t ci = s.btCluster[i];
                            if (ci == last || !(double(bound) < std::sqrt(v.best2) + ctx.margin)) continue;
                            last = ci;
                            visitCluster(ctx, ci, v, s);
                        }
                    }
                    }
                seed = v.bestT;
                if (v.bestT == kNone) continue; // nothing within reach: sign left to the flood fill
                const openvdb::Index offset = openvdb::Index((vx << 6) | (vy << 3) | vz);
                const double d = std::sqrt(v.best2);
                if (!pseudo) { // signed after the leaf's distances (winding), or not at all
                    s.vd[offset] = d;
                    if (wantClosest) {
                        s.vcp[offset] = openvdb::Vec3f(v.bestCp.point - v.p);
                        s.vtri[offset] = int32_t(v.bestT);
                    }
                    continue;
                }
                const bool inside = LazyPseudoNormals::insideOf(v.p, v.bestCp.point, cachedNormal(ctx.normals, s, ctx.mesh, v.bestT, v.bestCp.feature));
                if (inside ? d < ctx.intW : d < ctx.extW) {
                    res.sdf->setValueOn(offset, float((inside ? -d : d) * ctx.voxelSize));
                    if (wantClosest) {
                        res.cp->setValueOn(offset, openvdb::Vec3f(v.bestCp.point - v.p));
                        res.tri->setValueOn(offset, int32_t(v.bestT));
                    }
                    ++active;
                } else {
                    res.sdf->setValueOff(offset, inside ? -bg : bg);
                }
                }
            }
    if (!pseudo) return finishLeaf(ctx, s, res, wantClosest);
    s.activeVoxels += active;
    if (active == 0) return LeafResult{};
    return res;
}

/// The candidate leaves: every leaf whose voxel-centre box comes within the band limit of a
/// triangle (a superset: boxes dilated by the limit stand for balls), as a mask at leaf
/// resolution (coordinate = leaf origin / 8). Nodes whose box is small next to the reach are
/// marked by their dilated box; larger clusters triangle by triangle, by recursive halving of
/// the triangle's dilated bounding block with a conservative triangle–box test, so the work
/// follows the leaves touched whatever the triangles' shape.
class CandidateLeaves
{
public:
    explicit CandidateLeaves(const Context& ctx) : mCtx(ctx), mBlock(std::max(1, int(std::floor(ctx.limit / 8.0)))) {}

    /// Leaf-coordinate range of the cell-space box [lo, hi] dilated by the reach.
    openvdb::CoordBBox leafRange(const Vec3d& lo, const Vec3d& hi) const
    {
        const double r = mCtx.limit + mCtx.margin;
        openvdb::Coord a, b;
        for (int k = 0; k < 3; ++k) {
            a[k] = int(std::ceil((lo[k] - r - 7.5) / 8.0));
            b[k] = int(std::floor((hi[k] + r - 0.5) / 8.0));
        }
        return openvdb::CoordBBox(a, b);
    }

    /// The nodes to rasterize: a cut of the hierarchy where a node's box is at most ~2 reaches
    /// (or 2 leaves) wide, or a cluster.
    std::vector<uint32_t> cut() const
    {
        std::vector<uint32_t> out, stack{0};
        const auto& nodes = mCtx.hierarchy.nodes();
        if (nodes.empty()) return out;
        const double small = mCtx.limit;
        while (!stack.empty()) {
            const uint32_t ni = stack.back();
            stack.pop_back();
            const HierarchyNode& n = nodes[ni];
            const double ext = std::max({n.hi[0] - n.lo[0], n.hi[1] - n.lo[1], n.hi[2] - n.lo[2]});
            if (n.isLeaf() || ext <= small) { out.push_back(ni); continue; }
            stack.push_back(n.right);
            stack.push_back(n.left);
        }
        return out;
    }

    void rasterizeNode(uint32_t ni, openvdb::MaskTree& mask) const
    {
        const HierarchyNode& n = mCtx.hierarchy.nodes()[ni];
        const double ext = std::max({n.hi[0] - n.lo[0], n.hi[1] - n.lo[1], n.hi[2] - n.lo[2]});
        if (!n.isLeaf() || ext <= std::max(8.0, mCtx.limit)) {
            mask.fill(leafRange(Vec3d(n.lo[0], n.lo[1], n.lo[2]), Vec3d(n.hi[0], n.hi[1], n.hi[2])), true, true);
            return;
        }
        const TriangleCluster& c = mCtx.hierarchy.clusters()[n.left];
        for (uint32_t lane = 0; lane < c.count; ++lane) {
            const Vec3I& tri = mCtx.mesh.triangles[c.ids[lane]];
            const Vec3d& a = mCtx.cellPts[tri[0]];
            const Vec3d& b = mCtx.cellPts[tri[1]];
            const Vec3d& cc = mCtx.cellPts[tri[2]];
            // only the part of the triangle inside this cluster's box: a split triangle's other
            // pieces are in other clusters
            Vec3d lo, hi;
            bool empty = false;
            for (int k = 0; k < 3; ++k) {
                lo[k] = std::max(std::min({a[k], b[k], cc[k]}), n.lo[k]);
                hi[k] = std::min(std::max({a[k], b[k], cc[k]}), n.hi[k]);
                empty = empty || lo[k] > hi[k];
            }
            if (!empty) rasterizeTriangle(mesh_internal::PreparedTriangleBox(a, b, cc, 1e-6), leafRange(lo, hi), mask);
        }
    }

private:
    void rasterizeTriangle(const mesh_internal::PreparedTriangleBox& tri, const openvdb::CoordBBox& block,
                           openvdb::MaskTree& mask) const
    {
        if (mBlock == 1) { // single leaves: no halving (a leaf's dilated box lies inside its blocks')
            columns(tri, block, mask);
            return;
        }
        const double r = mCtx.limit + mCtx.margin;
        const openvdb::Coord dim = block.dim();
        const Vec3d lo(block.min().x() * 8.0 + 0.5 - r, block.min().y() * 8.0 + 0.5 - r, block.min().z() * 8.0 + 0.5 - r);
        const Vec3d hi(block.max().x() * 8.0 + 7.5 + r, block.max().y() * 8.0 + 7.5 + r, block.max().z() * 8.0 + 7.5 + r);
        if (!tri.overlaps((lo + hi) * 0.5, (hi - lo) * 0.5)) return;
        int axis = 0;
        for (int k = 1; k < 3; ++k)
            if (dim[k] > dim[axis]) axis = k;
        if (dim[axis] <= mBlock) { mask.fill(block, true, true); return; }
        openvdb::CoordBBox l = block, h = block;
        const int mid = block.min()[axis] + dim[axis] / 2;
        l.max()[axis] = mid - 1;
        h.min()[axis] = mid;
        rasterizeTriangle(tri, l, mask);
        rasterizeTriangle(tri, h, mask);
    }

    /// A block of single leaves: column by column along the normal's dominant axis
    /// w, the leaves whose dilated boxes the triangle's plane crosses (an interval of w from the
    /// plane's extremes over the column's dilated cross-section, widened for rounding), each
    /// then tested on every axis. The same leaves as testing every leaf of the block, in time
    /// proportional to the block's cross-section plus the leaves near the plane (a recursive
    /// halving tests up to 13 axes at every level above each leaf).
    void columns(const mesh_internal::PreparedTriangleBox& tri, const openvdb::CoordBBox& block, openvdb::MaskTree& mask) const
    {
        const double r = mCtx.limit + mCtx.margin;
        const Vec3d& n = tri.normal();
        int w = 0;
        for (int k = 1; k < 3; ++k)
            if (std::abs(n[k]) > std::abs(n[w])) w = k;
        const int u = (w + 1) % 3, v = (w + 2) % 3;
        const Vec3d half(4.0 + r - 0.5);
        auto test = [&](const openvdb::Coord& l) {
            const Vec3d centre(l.x() * 8.0 + 4.0, l.y() * 8.0 + 4.0, l.z() * 8.0 + 4.0);
            if (tri.overlaps(centre, half)) mask.setValueOn(l);
        };
        if (n[w] == 0.0) { // degenerate: every leaf of the block
            for (auto it = block.begin(); it; ++it) test(*it);
            return;
        }
        const Vec3d& o = tri.origin();
        const double pd = n.dot(o);
        openvdb::Coord l;
        for (int iu = block.min()[u]; iu <= block.max()[u]; ++iu)
            for (int iv = block.min()[v]; iv <= block.max()[v]; ++iv) {
                // w of the plane over the column's dilated cross-section: extremes at its corners
                double wlo = std::numeric_limits<double>::max(), whi = -wlo;
                for (int cu = 0; cu < 2; ++cu)
                    for (int cv = 0; cv < 2; ++cv) {
                        const double xu = iu * 8.0 + (cu ? 7.5 + r : 0.5 - r), xv = iv * 8.0 + (cv ? 7.5 + r : 0.5 - r);
                        const double x = (pd - n[u] * xu - n[v] * xv) / n[w];
                        wlo = std::min(wlo, x);
                        whi = std::max(whi, x);
                    }
                const double pad = 1e-6 * (std::abs(wlo) + std::abs(whi) + 1.0);
                // (clamped in double: no conversion of an out-of-range value)
                const double lo = double(block.min()[w]), hi = double(block.max()[w]);
                const int w0 = int(std::clamp(std::ceil((wlo - pad - 7.5 - r) / 8.0), lo, hi + 1.0));
                const int w1 = int(std::clamp(std::floor((whi + pad - 0.5 + r) / 8.0), lo - 1.0, hi));
                l[u] = iu;
                l[v] = iv;
                for (int iw = w0; iw <= w1; ++iw) {
                    l[w] = iw;
                    test(l);
                }
            }
    }

    const Context& mCtx;
    int mBlock; // blocks this many leaves wide (about the reach) are marked whole
};

// onlyLeavesIn (MeshToLevelSetBricks.cc): the boxes as a mask at leaf resolution (coordinate =
// leaf origin / 8), and whether a leaf-resolution box meets it.
void leafBoxMask(const std::vector<openvdb::CoordBBox>& boxes, openvdb::MaskTree& mask);
bool meetsLeafBoxMask(const openvdb::MaskTree& mask, const openvdb::CoordBBox& q);

void checkWidth(const char* name, float w)
{
    if (!std::isfinite(w) || w <= 0.0f) {
        std::ostringstream os;
        os << name << " must be a positive number of voxels, got " << w;
        throw InvalidArgumentError(os.str());
    }
}

} // namespace meshtols_internal


namespace {
LevelSetWithClosestPoints convert(const TriangleMesh& mesh, const MeshToLevelSetOptions& options,
                                  MeshToLevelSetStats* statsOut, bool wantClosest)
{
    using namespace meshtols_internal;
    openvdb::initialize();
    MeshToLevelSetStats stats;
    auto* interrupter = options.interrupter;

    requireUsableMesh(mesh);
    const SignMode mode = resolveSignMode(mesh, options, stats.signReason);
    stats.sign = mode;
    const bool winding = mode == SignMode::Winding, unsignedMode = mode == SignMode::Unsigned;
    if (options.fillInterior && unsignedMode)
        throw InvalidArgumentError("fill interior needs an inside: it cannot be combined with the unsigned sign mode");
    const bool restricted = options.onlyLeavesIn != nullptr;
    if (restricted && (winding || options.fillInterior))
        throw InvalidArgumentError(std::string("a conversion restricted to bricks (onlyLeavesIn) supports the "
                                               "pseudonormal and unsigned sign modes without fill interior, not ") +
                                   (winding ? "the winding number (" + stats.signReason + ")" : "fill interior") +
                                   ": those are passes over the whole tree");
    if (winding && !(options.windingAccuracy > 1.0 && std::isfinite(options.windingAccuracy))) {
        std::ostringstream os;
        os << "the winding accuracy (beta) must be a finite number above 1, got " << options.windingAccuracy;
        throw InvalidArgumentError(os.str());
    }
    const double h = resolveVoxelSize(mesh, options);
    stats.voxelSize = h;
    // Band limits in voxels, held in float as they always were.
    const float extWf = static_cast<float>(options.widthInVoxels(options.exteriorWidth, h));
    const float intWf = static_cast<float>(options.widthInVoxels(options.interiorWidth, h));
    checkWidth("exterior band width", extWf);
    checkWidth("interior band width", intWf);

    const double extW = extWf, intW = intWf;
    // Unsigned: the band is the exterior width. Winding: voxels within 1 voxel of the surface are
    // always computed (active or not), so that a tile never holds surface (the tile signs rely
    // on it); the band itself is unchanged.
    const double limit = unsignedMode ? extW : winding ? std::max({extW, intW, 1.0}) : std::max(extW, intW);

    // Cell space: cell ijk = [i, i+1)^3 holds voxel ijk, whose centre is at world ijk*h.
    const BBoxd bounds = mesh.bounds();
    for (int k = 0; k < 3; ++k) {
        const double lo = bounds.min()[k] / h - limit - 16, hi = bounds.max()[k] / h + limit + 16;
        if (!(std::abs(lo) < 1.0e9 && std::abs(hi) < 1.0e9)) {
            std::ostringstream os;
            os << "voxel size " << h << " is too small for this mesh: index coordinates would reach "
               << std::max(std::abs(lo), std::abs(hi)) << " (limit 1e9)";
            throw ResourceLimitError(os.str());
        }
    }

    if (interrupter) interrupter->start("mesh to level set");
    const auto t0 = Clock::now();

    std::vector<Vec3d> cellPts(mesh.points.size());
    tbb::parallel_for(tbb::blocked_range<size_t>(0, cellPts.size(), 8192), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t i = r.begin(); i != r.end(); ++i) cellPts[i] = mesh.points[i] / h + Vec3d(0.5);
    });
    LazyPseudoNormals normals(mesh);
    std::vector<uint32_t> use;
    use.reserve(mesh.triangles.size());
    // onlyLeavesIn: the triangles within the limit (plus a voxel for the margin) of a box's leaves
    openvdb::MaskTree onlyLeaves;
    if (restricted) leafBoxMask(*options.onlyLeavesIn, onlyLeaves);
    uint64_t usable = 0;
    for (uint32_t t = 0; t < mesh.triangles.size(); ++t) {
        if (normals.isDegenerate(t)) { ++stats.skippedDegenerate; continue; }
        ++usable;
        if (restricted) {
            const Vec3I& tri = mesh.triangles[t];
            openvdb::Coord a, b;
            for (int k = 0; k < 3; ++k) {
                const double lo = std::min({cellPts[tri[0]][k], cellPts[tri[1]][k], cellPts[tri[2]][k]});
                const double hi = std::max({cellPts[tri[0]][k], cellPts[tri[1]][k], cellPts[tri[2]][k]});
                a[k] = int(std::floor((lo - limit - 1.0 - 7.5) / 8.0)); // leaves whose voxel centres
                b[k] = int(std::ceil((hi + limit + 1.0 - 0.5) / 8.0));  // [o + 0.5, o + 7.5] come near
            }
            if (!meetsLeafBoxMask(onlyLeaves, openvdb::CoordBBox(a, b))) continue;
        }
        use.push_back(t);
    }
    stats.triangles = use.size();
    if (usable == 0)
        throw InvalidMeshError((mesh.source.empty() ? std::string("mesh") : mesh.source) +
                               ": every triangle is degenerate (zero area)");
    if (use.empty()) { // restricted to bricks that no triangle's band reaches: no leaves
        auto grid = openvdb::FloatGrid::create(float(extW * h));
        grid->setTransform(openvdb::math::Transform::createLinearTransform(h));
        grid->setGridClass(unsignedMode ? openvdb::GRID_UNKNOWN : openvdb::GRID_LEVEL_SET);
        grid->setName(options.gridName);
        grid->insertMeta(kSignMetadata, openvdb::StringMetadata(toString(mode)));
        LevelSetWithClosestPoints result;
        result.levelSet = grid;
        if (wantClosest) {
            result.closestPoints = openvdb::Vec3fGrid::create(openvdb::Vec3f(0.0f));
            result.closestPoints->setTransform(grid->transform().copy());
            result.closestPoints->setName(options.gridName + "_closest");
            result.closestPoints->setVectorType(openvdb::VEC_CONTRAVARIANT_RELATIVE);
            result.closestTriangles = openvdb::Int32Grid::create(-1);
            result.closestTriangles->setTransform(grid->transform().copy());
            result.closestTriangles->setName(options.gridName + "_triangle");
        }
        if (interrupter) { interrupter->wasInterrupted(100); interrupter->end(); }
        if (statsOut) *statsOut = stats;
        return result;
    }

    // The main memory guard comes after the hierarchy: the candidate leaves below are the band's
    // real volume at leaf resolution. But the hierarchy splits triangles longer than 8 cells
    // into pieces, so its size follows the triangles' extent in cells too: first a guard that
    // needs no hierarchy, from a lower bound of the band (the band of the largest triangle alone,
    // 2 · limit · its area) and the pieces' memory (about 160 bytes a piece).
    {
        double largestBand = 0.0, pieceBytes = 0.0;
        for (uint32_t t : use) {
            const Vec3I& tri = mesh.triangles[t];
            const Vec3d& a = cellPts[tri[0]];
            const Vec3d& b = cellPts[tri[1]];
            const Vec3d& c = cellPts[tri[2]];
            largestBand = std::max(largestBand, 2.0 * limit * 0.5 * (b - a).cross(c - a).length());
            // pieces of at most 8 cells: about area / 64 for a wide triangle, length / 8 for a
            // needle (an oblique one too: its box is large, its pieces are not); 4x that, at
            // ~160 bytes a piece (item, box, its share of a cluster and of the nodes)
            double extent = 0.0;
            for (int k = 0; k < 3; ++k) extent = std::max(extent, std::max({a[k], b[k], c[k]}) - std::min({a[k], b[k], c[k]}));
            if (extent > 8.0) {
                const double area = 0.5 * (b - a).cross(c - a).length();
                const double perimeter = (b - a).length() + (c - b).length() + (a - c).length();
                pieceBytes += 160.0 * (area / 16.0 + perimeter / 4.0 + 1.0);
            }
        }
        detail::VoxelBudgetRequest req;
        req.operation = "mesh to level set";
        req.what = "the band";
        std::ostringstream d;
        d << "at least the band of its largest triangle, within " << limit << " voxels of it";
        req.detail = d.str();
        req.voxels = largestBand;
        req.scratchBytes = pieceBytes;
        req.maxVoxels = options.maxVoxels;
        detail::checkVoxelBudget(req);
    }

    // ---- the closest-triangle hierarchy (replaces the paper's voxelization and cell lists)
    const TriangleHierarchy hierarchy(mesh, cellPts, use, interrupter);
    stats.hierarchyNodes = hierarchy.nodes().size();
    stats.clusters = hierarchy.clusters().size();
    std::unique_ptr<FastWindingNumber> fwn;
    if (winding) {
        const auto tw = Clock::now();
        FastWindingNumberOptions fo;
        fo.accuracy = options.windingAccuracy;
        fo.leafSizeWithoutCurrent = 64; // (without boundary current: a few estimates only)
        int64_t leftOut = -1;
        fwn = winding_internal::signingWindingNumber(mesh, fo, leftOut);
        if (leftOut >= 0) {
            stats.signReason += "; the mesh's only open part, triangle " + std::to_string(mesh.sourceFace(size_t(leftOut))) +
                                ", is left out of the winding number (alone it stays below 1/2)";
        }
        stats.currentEdges = fwn->currentEdges();
        stats.secondsWinding = secondsSince(tw);
    }
    Context ctx{mesh, cellPts, hierarchy, normals, h, extW, intW, limit, limit * limit, 0.0, float(extW * h)};
    ctx.sign = mode;
    ctx.fwn = fwn.get();
    ctx.deferWinding = winding && fwn->currentEdges() == 0;
    // Single-precision bounds are evaluated at |q| <= cluster radius + limit + margin; their
    // rounding is a few ulps of that (covered 8x), and never below the old 1e-4 cell.
    ctx.margin = std::max(1e-4 * std::max(1.0, (limit + 20.0) / 32.0), 2e-6 * (hierarchy.maxClusterRadius() + limit + 2.0));
    stats.secondsHierarchy = secondsSince(t0);
    progress_internal::check(interrupter, 10);

    // ---- candidate leaves, and the voxel budget from their count (the dilated surface's real
    //      volume at leaf resolution, not area × width)
    const auto t1 = Clock::now();
    CandidateLeaves raster(ctx);
    const std::vector<uint32_t> cut = raster.cut();
    tbb::enumerable_thread_specific<openvdb::MaskTree> maskTls;
    tbb::parallel_for(tbb::blocked_range<size_t>(0, cut.size(), 64), [&](const tbb::blocked_range<size_t>& r) {
        auto& m = maskTls.local();
        for (size_t i = r.begin(); i != r.end(); ++i) raster.rasterizeNode(cut[i], m);
    });
    openvdb::MaskTree leafMask;
    for (auto& m : maskTls) leafMask.topologyUnion(m);
    maskTls.clear();
    if (restricted) leafMask.topologyIntersection(onlyLeaves); // this brick set's leaves only
    const uint64_t leafCount = leafMask.activeVoxelCount();
    // output leaves (values + mask + pointers) and each thread's scratch (frontier, box levels,
    // block buffers: about 1 MiB at the largest frontier)
    // (winding signs deferred until all leaves are known keep DeferredWinding per leaf meanwhile)
    detail::checkBandLeafBudget("mesh to level set", leafCount, limit,
                                double(detail::budgetThreads()) * double(1u << 20) +
                                    (ctx.deferWinding ? double(leafCount) * double(sizeof(DeferredWinding)) : 0.0),
                                options.maxVoxels);
    std::vector<Coord> cand;
    cand.reserve(size_t(leafCount));
    for (auto it = leafMask.cbeginValueOn(); it; ++it) {
        if (it.isVoxelValue()) { { const Coord c = it.getCoord(); cand.push_back(Coord(c.x() * 8, c.y() * 8, c.z() * 8)); } continue; }
        const openvdb::CoordBBox bb = it.getBoundingBox();
        for (int x = bb.min().x(); x <= bb.max().x(); ++x)
            for (int y = bb.min().y(); y <= bb.max().y(); ++y)
                for (int z = bb.min().z(); z <= bb.max().z(); ++z) cand.push_back(Coord(x * 8, y * 8, z * 8));
    }
    leafMask.clear();
    std::sort(cand.begin(), cand.end());
    stats.candidateLeaves = cand.size();
    stats.secondsCandidates = secondsSince(t1);
    progress_internal::check(interrupter, 20);

    // ---- §4: distances, leaf by leaf. The interrupter is polled by work (WorkPoller: once per
    //      8192 exact evaluations, also inside a leaf) and by the clock between leaves (about
    //      every 20 ms, for progress on leaves that need few evaluations).
    const auto t1d = Clock::now();
    std::vector<LeafResult> outLeaves(cand.size());
    tbb::enumerable_thread_specific<Scratch> scratchTls;
    WorkPoller poller;
    poller.interrupter = interrupter;
    poller.leaves = std::max<size_t>(cand.size(), 1);
    std::atomic<int64_t> nextPoll{0};
    const int64_t pollEvery = 20'000'000; // ns
    bool onDevice = useDevice(options, cand.size(), stats.deviceNote);
    if (onDevice) {
        try {
            deviceDistances(ctx, options, cand, outLeaves, wantClosest, scratchTls, stats);
        } catch (const DeviceError& e) {
            if (options.device != ComputeDevice::Auto) throw;
            stats.deviceNote = std::string("device auto: ") + e.what() + "; the CPU was used";
            stats.device = "cpu";
            onDevice = false;
            outLeaves.clear();
            outLeaves.resize(cand.size());
            scratchTls.clear();
        }
    }
    if (!onDevice) tbb::parallel_for(tbb::blocked_range<size_t>(0, cand.size(), 1), [&](const tbb::blocked_range<size_t>& r) {
        Scratch& s = scratchTls.local();
        if (interrupter) s.poller = &poller;
        for (size_t i = r.begin(); i != r.end(); ++i) {
            if (poller.stopped()) return;
            outLeaves[i] = computeLeaf(ctx, cand[i], s, wantClosest);
            poller.done.fetch_add(1, std::memory_order_relaxed);
            if (interrupter) {
                poller.report(s);
                const int64_t now = std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now() - t0).count();
                int64_t due = nextPoll.load(std::memory_order_relaxed);
                if (now >= due && nextPoll.compare_exchange_strong(due, now + pollEvery)) poller.poll();
            }
        }
    });
    if (poller.stopped()) throw InterruptedError("interrupted while computing distances");
    for (const Scratch& s : scratchTls) {
        stats.windingEvaluations += s.windingEvaluations;
        stats.windingGroups += s.windingGroups;
        stats.windingIndividual += s.windingIndividual;
        stats.distanceEvaluations += s.evaluations;
        stats.boundTests += s.boundTests;
        stats.nodeTests += s.nodeTests;
        stats.leafPasses += s.leafPasses;
        stats.candidateVoxels += s.candidateVoxels;
        stats.activeVoxels += s.activeVoxels;
    }
    if (ctx.deferWinding)
        resolveDeferred(ctx, cand, outLeaves, wantClosest, stats.windingEvaluations, stats.activeVoxels);
    stats.secondsDistance = secondsSince(t1d);
    stats.secondsVoxelize = stats.secondsHierarchy;
    stats.secondsLists = stats.secondsCandidates;

    // ---- assemble the tree (serial, fixed order), signed flood fill, grid
    const auto t2 = Clock::now();
    auto tree = std::make_shared<openvdb::FloatTree>(float(extW * h));
    // addLeaf takes a leaf only once its parents exist: until it returns the leaf is still ours
    // (a failed allocation of a parent frees it with its unique_ptr).
    for (LeafResult& l : outLeaves)
        if (l.sdf) { tree->addLeaf(l.sdf.get()); (void)l.sdf.release(); }
    openvdb::math::Transform::Ptr xform = openvdb::math::Transform::createLinearTransform(h);
    if (restricted) {
        // the leaves only: the caller finishes the union of all parts (onlyLeavesIn)
    } else if (mode == SignMode::Pseudonormal) {
        openvdb::tools::signedFloodFill(*tree);
    } else if (winding) {
        // the tiles' signs (the leaves are signed); leaves kept only for their inactive signs
        // collapse back into tiles
        WindingSignStats ws;
        winding_internal::signTree(*tree, *xform, *fwn, bounds, false, std::numeric_limits<double>::infinity(), ws,
                                   interrupter);
        openvdb::tools::prune(*tree);
        stats.windingEvaluations += ws.evaluations;
        stats.windingGroups += ws.components;
        stats.windingIndividual += ws.individual;
        stats.insideTiles = ws.insideTiles;
    }
    if (options.fillInterior) stats.filledVoxels = winding_internal::activateInterior(*tree);
    auto grid = openvdb::FloatGrid::create(tree);
    grid->setTransform(xform);
    grid->setGridClass(unsignedMode ? openvdb::GRID_UNKNOWN : openvdb::GRID_LEVEL_SET);
    grid->setName(options.gridName);
    grid->insertMeta(kSignMetadata, openvdb::StringMetadata(toString(mode)));
    if (options.fillInterior) grid->insertMeta(kFillInteriorMetadata, openvdb::BoolMetadata(true));
    LevelSetWithClosestPoints result;
    result.levelSet = grid;
    if (wantClosest) {
        auto cpTree = std::make_shared<openvdb::Vec3fTree>(openvdb::Vec3f(0.0f));
        for (LeafResult& l : outLeaves)
            if (l.cp) { cpTree->addLeaf(l.cp.get()); (void)l.cp.release(); }
        result.closestPoints = openvdb::Vec3fGrid::create(cpTree);
        result.closestPoints->setTransform(grid->transform().copy());
        result.closestPoints->setName(options.gridName + "_closest");
        result.closestPoints->setVectorType(openvdb::VEC_CONTRAVARIANT_RELATIVE);
        auto triTree = std::make_shared<openvdb::Int32Tree>(-1);
        for (LeafResult& l : outLeaves)
            if (l.tri) { triTree->addLeaf(l.tri.get()); (void)l.tri.release(); }
        result.closestTriangles = openvdb::Int32Grid::create(triTree);
        result.closestTriangles->setTransform(grid->transform().copy());
        result.closestTriangles->setName(options.gridName + "_triangle");
    }
    stats.secondsFinish = secondsSince(t2);
    if (interrupter) { interrupter->wasInterrupted(100); interrupter->end(); }
    if (statsOut) *statsOut = stats;
    return result;
}
} // namespace

openvdb::FloatGrid::Ptr meshToLevelSet(const TriangleMesh& mesh, const MeshToLevelSetOptions& options,
                                       MeshToLevelSetStats* statsOut)
{
    return convert(mesh, options, statsOut, false).levelSet;
}

LevelSetWithClosestPoints meshToLevelSetWithClosestPoints(const TriangleMesh& mesh,
                                                          const MeshToLevelSetOptions& options,
                                                          MeshToLevelSetStats* statsOut)
{
    return convert(mesh, options, statsOut, true);
}

} // namespace levelforge
