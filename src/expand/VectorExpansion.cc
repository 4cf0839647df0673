// SPDX-License-Identifier: Apache-2.0
// The vector method of the expansion: the sparse 8-pass VCVDT over VDB leaves (see
// src/expand/VectorExpansion.h).
#include "expand/VectorExpansion.h"

#include "detail/Timer.h"

#include <levelforge/core/Exceptions.h>
#include <levelforge/core/PseudoNormals.h>
#include <levelforge/core/TriangleDistance.h>

#include <openvdb/tree/LeafManager.h>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_sort.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <vector>

namespace levelforge {
namespace vector_expansion_internal {
namespace {

using FloatTree = openvdb::FloatTree;
using LeafT = FloatTree::LeafNodeType;
using openvdb::Coord;

constexpr float kInf = std::numeric_limits<float>::infinity();
using detail::Clock;

/// Offset to the closest feature point (voxel units), its squared length (Leymarie–Levine) and
/// the triangle it lies on (-1: unknown).
struct Cell
{
    float x, y, z, d2;
    int32_t tri;
};

enum : uint8_t { kOutside = 0, kFree = 1, kFrozen = 2 };

/// Cell layout inside a leaf: slice-major (k*64 + j*8 + i), so a slice is one 1 KiB block and
/// a row one 128-byte run — the raster passes stream through memory.
inline int cellIndex(int i, int j, int k) { return (k << 6) | (j << 3) | i; }
/// VDB's own leaf offset (x slowest).
inline openvdb::Index vdbOffset(int i, int j, int k) { return openvdb::Index((i << 6) | (j << 3) | k); }

inline void relax(Cell& best, const Cell& n, float ox, float oy, float oz)
{
    const float x = n.x + ox, y = n.y + oy, z = n.z + oz;
    const float d2 = x * x + y * y + z * z;
    if (d2 < best.d2) best = Cell{x, y, z, d2, n.tri};
}

/// The adjacency the refinement walks over (meshAdjacency()); points are read through the mesh.
struct MeshWalk
{
    std::vector<int32_t> edge;      ///< 3 per triangle: the triangle across each edge (-1: none)
    std::vector<uint32_t> fanBegin; ///< per vertex + 1: offsets into fan
    std::vector<int32_t> fan;       ///< triangles around each vertex, in increasing order
    void build(const TriangleMesh& mesh) { meshAdjacency(mesh, fanBegin, fan, edge); }
};

/// The undirected key of edge e of triangle t (its end points, smaller first).
inline uint64_t edgeKey(const Vec3I& tri, int e)
{
    const uint64_t a = tri[e], b = tri[(e + 1) % 3];
    return (std::min(a, b) << 32) | std::max(a, b);
}

} // namespace

void meshAdjacency(const TriangleMesh& mesh, std::vector<uint32_t>& fanBegin, std::vector<int32_t>& fan,
                   std::vector<int32_t>& edge)
{
    const size_t nt = mesh.triangles.size();
    const size_t nv = mesh.points.size();
    // the fans: a counting sort of the corners by vertex, triangles in increasing order
    fanBegin.assign(nv + 1, 0);
    for (const Vec3I& t : mesh.triangles)
        for (int k = 0; k < 3; ++k) ++fanBegin[t[k] + 1];
    for (size_t v = 0; v < nv; ++v) fanBegin[v + 1] += fanBegin[v];
    fan.resize(fanBegin[nv]);
    {
        std::vector<uint32_t> fill(fanBegin.begin(), fanBegin.end() - 1);
        for (size_t t = 0; t < nt; ++t)
            for (int k = 0; k < 3; ++k) fan[fill[mesh.triangles[t][k]]++] = int32_t(t);
    }
    edge.resize(3 * nt);
    // For every triangle, the triangles across its three edges (-1: boundary), from the fan of
    // the edge's end point with fewer triangles. A non-manifold edge links its triangles in a
    // ring, in the order of their edge slots (3 t + e): each slot names the triangle of the next
    // one. Edges whose both end points have large fans (hubs of degenerate exports) are linked
    // afterwards by sorting their slots, so no fan is scanned once per triangle of a hub.
    constexpr uint32_t kFanScan = 64;
    constexpr int32_t kPending = -2;
    tbb::parallel_for(tbb::blocked_range<size_t>(0, nt, 4096), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t t = r.begin(); t != r.end(); ++t) {
            const Vec3I& tri = mesh.triangles[t];
            for (int e = 0; e < 3; ++e) {
                const uint64_t key = edgeKey(tri, e);
                const size_t slot = 3 * t + size_t(e);
                size_t first = ~size_t(0), next = ~size_t(0), count = 0;
                const uint32_t a = tri[e], b = tri[(e + 1) % 3];
                const uint32_t na = fanBegin[a + 1] - fanBegin[a], nb = fanBegin[b + 1] - fanBegin[b];
                if (std::min(na, nb) > kFanScan) {
                    edge[slot] = kPending;
                    continue;
                }
                const uint32_t v = na <= nb ? a : b;
                int32_t prev = -1;
                for (uint32_t q = fanBegin[v]; q < fanBegin[v + 1]; ++q) {
                    const int32_t u = fan[q];
                    if (u == prev) continue; // a triangle with this vertex twice is listed twice
                    prev = u;
                    const Vec3I& ut = mesh.triangles[size_t(u)];
                    for (int f = 0; f < 3; ++f) {
                        if (edgeKey(ut, f) != key) continue;
                        const size_t s2 = 3 * size_t(u) + size_t(f);
                        ++count;
                        first = std::min(first, s2);
                        if (s2 > slot) next = std::min(next, s2);
                    }
                }
                edge[slot] = count >= 2 ? int32_t((next != ~size_t(0) ? next : first) / 3) : -1;
            }
        }
    });
    // the edges between two hubs: every slot of such an edge is pending (same end points)
    std::vector<std::pair<uint64_t, uint32_t>> pending;
    for (size_t slot = 0; slot < 3 * nt; ++slot)
        if (edge[slot] == kPending) pending.emplace_back(edgeKey(mesh.triangles[slot / 3], int(slot % 3)), uint32_t(slot));
    if (pending.empty()) return;
    tbb::parallel_sort(pending.begin(), pending.end());
    for (size_t i = 0; i < pending.size();) {
        size_t j = i;
        while (j < pending.size() && pending[j].first == pending[i].first) ++j;
        for (size_t k = i; k < j; ++k)
            edge[pending[k].second] = j - i >= 2 ? int32_t(pending[k + 1 < j ? k + 1 : i].second / 3) : -1;
        i = j;
    }
}

namespace {

class SparseVcvdt
{
    struct Row { int32_t begin, end; };
    struct Slab { int32_t rowBegin = 0, rowEnd = 0; };

public:
    SparseVcvdt(FloatTree& tree, const FloatTree& frozen, const ShellVectors& shell, float h,
                PropagationStats& stats)
        : mStats(stats)
    {
        const openvdb::Vec3fTree* closest = shell.points;
        tree.getNodes(mLeaves);
        std::sort(mLeaves.begin(), mLeaves.end(), [](const LeafT* a, const LeafT* b) {
            const Coord &p = a->origin(), &q = b->origin();
            if (p.z() != q.z()) return p.z() < q.z();
            if (p.y() != q.y()) return p.y() < q.y();
            return p.x() < q.x();
        });
        const size_t n = mLeaves.size();
        mOrigins.resize(n);
        for (size_t i = 0; i < n; ++i) mOrigins[i] = mLeaves[i]->origin();
        // rows (same y, z) and slabs (same z) of leaves
        for (size_t i = 0; i < n;) {
            Slab slab;
            slab.rowBegin = int32_t(mRows.size());
            const int z = mOrigins[i].z();
            while (i < n && mOrigins[i].z() == z) {
                Row row{int32_t(i), int32_t(i)};
                const int y = mOrigins[i].y();
                while (i < n && mOrigins[i].z() == z && mOrigins[i].y() == y) ++i;
                row.end = int32_t(i);
                mRows.push_back(row);
            }
            slab.rowEnd = int32_t(mRows.size());
            mSlabs.push_back(slab);
        }
        auto find = [&](const Coord& c) -> int32_t {
            auto it = std::lower_bound(mOrigins.begin(), mOrigins.end(), c, [](const Coord& a, const Coord& b) {
                if (a.z() != b.z()) return a.z() < b.z();
                if (a.y() != b.y()) return a.y() < b.y();
                return a.x() < b.x();
            });
            return (it != mOrigins.end() && *it == c) ? int32_t(it - mOrigins.begin()) : -1;
        };
        mNb.assign(n * 6, -1);
        mCells.resize(n * 512);
        mState.assign(n * 512, kOutside);
        mHasFree.assign(n, 0);
        std::atomic<uint64_t> nShellTotal{0}, estimated{0};
        tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 16), [&](const tbb::blocked_range<size_t>& r) {
            openvdb::tree::ValueAccessor<const FloatTree, false> fAcc(frozen);
            std::unique_ptr<openvdb::tree::ValueAccessor<const openvdb::Vec3fTree, false>> cAcc;
            if (closest) cAcc.reset(new openvdb::tree::ValueAccessor<const openvdb::Vec3fTree, false>(*closest));
            std::unique_ptr<openvdb::tree::ValueAccessor<const openvdb::Int32Tree, false>> tAcc;
            if (shell.triangles) tAcc.reset(new openvdb::tree::ValueAccessor<const openvdb::Int32Tree, false>(*shell.triangles));
            uint64_t nShell = 0, nEst = 0;
            for (size_t li = r.begin(); li != r.end(); ++li) {
                const LeafT& leaf = *mLeaves[li];
                const Coord o = leaf.origin();
                for (int a = 0; a < 3; ++a)
                    for (int s = 0; s < 2; ++s) {
                        Coord c = o;
                        c[a] += s ? 8 : -8;
                        mNb[li * 6 + size_t(a * 2 + s)] = find(c);
                    }
                const LeafT* fl = frozen.probeConstLeaf(o);
                const bool frozenTile = !fl && frozen.isValueOn(o);
                Cell* cells = &mCells[li * 512];
                uint8_t* state = &mState[li * 512];
                bool anyFree = false;
                for (int i = 0; i < 8; ++i)
                    for (int j = 0; j < 8; ++j)
                        for (int k = 0; k < 8; ++k) {
                            const openvdb::Index vo = vdbOffset(i, j, k);
                            const int ci = cellIndex(i, j, k);
                            cells[ci] = Cell{kInf, kInf, kInf, kInf, -1};
                            if (!leaf.isValueOn(vo)) { state[ci] = kOutside; continue; }
                            const bool isFrozen = frozenTile || (fl && fl->isValueOn(vo));
                            if (!isFrozen) { state[ci] = kFree; anyFree = true; continue; }
                            state[ci] = kFrozen;
                            ++nShell;
                            const Coord xyz = o.offsetBy(i, j, k);
                            openvdb::Vec3f v;
                            if (cAcc && cAcc->probeValue(xyz, v) && std::isfinite(v[0] + v[1] + v[2])) {
                                int32_t t = -1;
                                if (tAcc && !tAcc->probeValue(xyz, t)) t = -1;
                                cells[ci] = Cell{v[0], v[1], v[2], v.lengthSqr(), t};
                                continue;
                            }
                            // estimate: p = x - φ ∇φ/|∇φ| (central differences over the frozen band)
                            ++nEst;
                            const float phi = fAcc.getValue(xyz) / h;
                            openvdb::Vec3f g(0.0f);
                            for (int a = 0; a < 3; ++a) {
                                Coord lo = xyz, hi = xyz;
                                lo[a] -= 1;
                                hi[a] += 1;
                                float vl, vh;
                                const bool hasL = fAcc.probeValue(lo, vl), hasH = fAcc.probeValue(hi, vh);
                                if (hasL && hasH) g[a] = 0.5f * (vh - vl) / h;
                                else if (hasH) g[a] = vh / h - phi;
                                else if (hasL) g[a] = phi - vl / h;
                            }
                            const float gl = g.length();
                            if (!(gl > 0.0f) || !std::isfinite(gl)) continue; // no direction: not a seed
                            const openvdb::Vec3f e = g * (-phi / gl);
                            cells[ci] = Cell{e[0], e[1], e[2], e.lengthSqr(), -1};
                        }
                mHasFree[li] = anyFree;
            }
            nShellTotal += nShell;
            estimated += nEst;
        });
        mStats.shellVoxels = nShellTotal;
        mStats.estimatedVectors = estimated;
    }

    /// One in-slice raster pass over slice k of slab s: y order dy, x order dx, vertical
    /// neighbour at k - dz (dz = 0: none).
    void pass(const Slab& slab, int k, int dy, int dx, int dz)
    {
        const int rb = slab.rowBegin, re = slab.rowEnd;
        const int nbXUp = dx > 0 ? 0 : 1; // upstream leaf in x: -x for dx > 0
        const int nbYUp = dy > 0 ? 2 : 3;
        const int nbZUp = dz > 0 ? 4 : 5;
        const float ox = float(-dx), oy = float(-dy), oz = float(-dz);
        const int kn = k - dz;
        const int iEdge = dx > 0 ? 7 : 0, jEdge = dy > 0 ? 7 : 0, kEdge = dz > 0 ? 7 : 0;
        for (int rr = 0; rr < re - rb; ++rr) {
            const Row& row = mRows[size_t(dy > 0 ? rb + rr : re - 1 - rr)];
            for (int jj = 0; jj < 8; ++jj) {
                const int j = dy > 0 ? jj : 7 - jj;
                const int jn = j - dy;
                for (int ll = 0; ll < row.end - row.begin; ++ll) {
                    const int32_t L = dx > 0 ? row.begin + ll : row.end - 1 - ll;
                    if (!mHasFree[size_t(L)]) continue;
                    Cell* base = &mCells[size_t(L) * 512];
                    const uint8_t* st = &mState[size_t(L) * 512];
                    // neighbour rows/slices that may live in other leaves
                    const Cell* yRow = nullptr;
                    if (jn >= 0 && jn < 8) yRow = base + cellIndex(0, jn, k);
                    else if (int32_t nl = mNb[size_t(L) * 6 + size_t(nbYUp)]; nl >= 0)
                        yRow = &mCells[size_t(nl) * 512] + cellIndex(0, jEdge, k);
                    const Cell* zRow = nullptr;
                    if (dz != 0) {
                        if (kn >= 0 && kn < 8) zRow = base + cellIndex(0, j, kn);
                        else if (int32_t nl = mNb[size_t(L) * 6 + size_t(nbZUp)]; nl >= 0)
                            zRow = &mCells[size_t(nl) * 512] + cellIndex(0, j, kEdge);
                    }
                    const Cell* xEdge = nullptr;
                    if (int32_t nl = mNb[size_t(L) * 6 + size_t(nbXUp)]; nl >= 0)
                        xEdge = &mCells[size_t(nl) * 512] + cellIndex(iEdge, j, k);
                    Cell* rowCells = base + cellIndex(0, j, k);
                    const uint8_t* rowState = st + cellIndex(0, j, k);
                    for (int ii = 0; ii < 8; ++ii) {
                        const int i = dx > 0 ? ii : 7 - ii;
                        if (rowState[i] != kFree) continue;
                        Cell best = rowCells[i];
                        const int in = i - dx;
                        if (in >= 0 && in < 8) relax(best, rowCells[in], ox, 0.0f, 0.0f);
                        else if (xEdge) relax(best, *xEdge, ox, 0.0f, 0.0f);
                        if (yRow) relax(best, yRow[i], 0.0f, oy, 0.0f);
                        if (zRow) relax(best, zRow[i], 0.0f, 0.0f, oz);
                        rowCells[i] = best;
                    }
                }
            }
        }
    }

    void run(openvdb::util::NullInterrupter* interrupter)
    {
        const size_t nSlabs = mSlabs.size();
        for (int sweep = 0; sweep < 2; ++sweep) {
            const int dz = sweep == 0 ? 1 : -1;
            for (size_t ss = 0; ss < nSlabs; ++ss) {
                if (interrupter && interrupter->wasInterrupted(
                        int(100.0 * double(sweep * nSlabs + ss) / double(2 * nSlabs)))) {
                    throw InterruptedError("interrupted while propagating closest-point vectors");
                }
                const Slab& slab = mSlabs[dz > 0 ? ss : nSlabs - 1 - ss];
                for (int kk = 0; kk < 8; ++kk) {
                    const int k = dz > 0 ? kk : 7 - kk;
                    pass(slab, k, +1, +1, dz); // P1: from the (-x, -y) corner, + the vertical check
                    pass(slab, k, +1, -1, 0);  // P2: from the (+x, -y) corner
                    pass(slab, k, -1, -1, 0);  // P3: from the (+x, +y) corner
                    pass(slab, k, -1, +1, 0);  // P4: from the (-x, +y) corner
                }
            }
        }
    }

    /// The cell at (i, j, k) relative to leaf L, one leaf step at most across each axis; null
    /// when that leaf does not exist.
    const Cell* cellAt(int32_t L, int i, int j, int k) const
    {
        const int c[3] = {i, j, k};
        int local[3];
        for (int a = 0; a < 3; ++a) {
            local[a] = c[a];
            if (c[a] < 0 || c[a] > 7) {
                L = mNb[size_t(L) * 6 + size_t(a * 2 + (c[a] > 7 ? 1 : 0))];
                if (L < 0) return nullptr;
                local[a] = c[a] & 7;
            }
        }
        return &mCells[size_t(L) * 512 + size_t(cellIndex(local[0], local[1], local[2]))];
    }

    /// Exact refinement (mesh road): every new voxel takes the exact distance to the triangle its
    /// vector points at, improved by a greedy walk over the mesh (strictly closer edge-adjacent
    /// triangles, and the vertex fan when the closest point is a vertex); then Jacobi rounds let
    /// each voxel try the (refined) triangles of its six face neighbours, until no voxel
    /// improves. Double-buffered, so the result does not depend on the thread count.
    void refine(const TriangleMesh& mesh, const openvdb::math::Transform& xform,
                openvdb::util::NullInterrupter* interrupter)
    {
        auto checkInterrupt = [&] {
            if (interrupter && interrupter->wasInterrupted())
                throw InterruptedError("interrupted while refining the expanded distances");
        };
        const size_t n = mCells.size();
        const uint32_t nTris = uint32_t(mesh.triangles.size());
        MeshWalk walk;
        walk.build(mesh);
        mRefTri.assign(n, -1);
        mRefD2.assign(n, std::numeric_limits<double>::infinity());
        std::atomic<uint64_t> walked{0}, refined{0};
        static const int kOff[6][3] = {{-1, 0, 0}, {1, 0, 0}, {0, -1, 0}, {0, 1, 0}, {0, 0, -1}, {0, 0, 1}};

        std::atomic<uint64_t> evalsTotal{0};
        auto closest = [&](const openvdb::Vec3d& p, int32_t tri, uint64_t& ev) {
            ++ev;
            const Vec3I& t = mesh.triangles[size_t(tri)];
            return closestPointOnTriangle(p, mesh.points[t[0]], mesh.points[t[1]], mesh.points[t[2]]);
        };
        // try triangle `start` at p; if strictly closer than (best2, bestT), walk downhill from it
        // greedy walk downhill from triangle cur (squared distance cur2, closest feature curF):
        // to a strictly closer triangle across an edge, or around the vertex fan when the
        // closest point is a vertex (there the edge neighbours tie)
        auto walkFrom = [&](const openvdb::Vec3d& p, int32_t& cur, double& cur2, TriangleFeature curF,
                            uint64_t& steps, uint64_t& ev) {
            for (int step = 0; step < 64; ++step) {
                int32_t next = -1;
                double next2 = cur2;
                TriangleFeature nextF = curF;
                auto consider = [&](int32_t c) {
                    if (c < 0 || c == cur) return;
                    const TriangleClosestPoint q = closest(p, c, ev);
                    if (q.distanceSqr < next2) { next2 = q.distanceSqr; next = c; nextF = q.feature; }
                };
                for (int e = 0; e < 3; ++e) consider(walk.edge[size_t(cur) * 3 + size_t(e)]);
                if (next < 0 && curF >= TriangleFeature::Vertex0 && curF <= TriangleFeature::Vertex2) {
                    const uint32_t v = mesh.triangles[size_t(cur)][int(curF) - int(TriangleFeature::Vertex0)];
                    for (uint32_t q = walk.fanBegin[v]; q < walk.fanBegin[v + 1]; ++q) consider(walk.fan[q]);
                }
                if (next < 0) break;
                cur = next;
                cur2 = next2;
                curF = nextF;
                ++steps;
            }
        };
        // evaluates the candidate triangles (each once), then walks from the best of them if it
        // beats (best2, bestT); returns whether it did
        auto tryBest = [&](const openvdb::Vec3d& p, const int32_t* cand, int n, double& best2, int32_t& bestT,
                           uint64_t& steps, uint64_t& ev) {
            int32_t t = -1;
            double t2 = best2;
            TriangleFeature f = TriangleFeature::Face;
            for (int q = 0; q < n; ++q) {
                const int32_t c = cand[q];
                if (c < 0 || uint32_t(c) >= nTris || c == bestT) continue;
                const TriangleClosestPoint cp = closest(p, c, ev);
                if (cp.distanceSqr < t2) { t2 = cp.distanceSqr; t = c; f = cp.feature; }
            }
            if (t < 0) return false;
            walkFrom(p, t, t2, f, steps, ev);
            best2 = t2;
            bestT = t;
            return true;
        };

        // round 0: own triangle + the six neighbours' propagated triangles
        tbb::enumerable_thread_specific<std::vector<size_t>> movedTls;
        std::atomic<bool> stop{false};
        tbb::parallel_for(tbb::blocked_range<size_t>(0, mLeaves.size(), 8), [&](const tbb::blocked_range<size_t>& r) {
            // one poll per block of leaves (at most 8 × 512 voxels of work)
            if (stop.load(std::memory_order_relaxed)) return;
            if (interrupter && interrupter->wasInterrupted()) { stop = true; return; }
            uint64_t steps = 0, nr = 0, evals = 0;
            auto& moved = movedTls.local();
            for (size_t li = r.begin(); li != r.end(); ++li) {
                const Coord o = mLeaves[li]->origin();
                for (int ci = 0; ci < 512; ++ci) {
                    const size_t idx = li * 512 + size_t(ci);
                    const Cell& c = mCells[idx];
                    if (mState[idx] == kFrozen) { mRefTri[idx] = c.tri; continue; }
                    if (mState[idx] != kFree || c.tri < 0) continue;
                    const int i = ci & 7, j = (ci >> 3) & 7, k = ci >> 6;
                    const openvdb::Vec3d p = xform.indexToWorld(o.offsetBy(i, j, k));
                    double best2 = std::numeric_limits<double>::infinity();
                    int32_t bestT = -1;
                    // Inside the region of one triangle (all six neighbours point at it too) the
                    // exact distance to it is enough; at the borders between triangles' regions,
                    // where the propagated choice may be off, walk and try the neighbours'.
                    bool border = false;
                    const Cell* nbs[6];
                    for (int q = 0; q < 6; ++q) {
                        nbs[q] = cellAt(int32_t(li), i + kOff[q][0], j + kOff[q][1], k + kOff[q][2]);
                        if (nbs[q] && nbs[q]->tri >= 0 && nbs[q]->tri != c.tri) border = true;
                    }
                    if (!border && uint32_t(c.tri) < nTris) {
                        best2 = closest(p, c.tri, evals).distanceSqr;
                        bestT = c.tri;
                    } else {
                        // own triangle and those of all 26 neighbours (each distinct one once)
                        int32_t cand[27];
                        int nc = 0;
                        cand[nc++] = c.tri;
                        for (int dz = -1; dz <= 1; ++dz)
                            for (int dy = -1; dy <= 1; ++dy)
                                for (int dx = -1; dx <= 1; ++dx) {
                                    const Cell* nb = cellAt(int32_t(li), i + dx, j + dy, k + dz);
                                    if (!nb || nb->tri < 0) continue;
                                    bool seen = false;
                                    for (int q = 0; q < nc && !seen; ++q) seen = cand[q] == nb->tri;
                                    if (!seen) cand[nc++] = nb->tri;
                                }
                        tryBest(p, cand, nc, best2, bestT, steps, evals);
                    }
                    mRefTri[idx] = bestT;
                    mRefD2[idx] = best2;
                    if (bestT != c.tri) moved.push_back(idx);
                    ++nr;
                }
            }
            walked += steps;
            evalsTotal += evals;
            refined += nr;
        });
        // Jacobi rounds: voxels next to a voxel whose triangle changed try that triangle. Each
        // round reads the previous state only and applies its changes afterwards.
        std::vector<size_t> changedList;
        for (auto& v : movedTls) changedList.insert(changedList.end(), v.begin(), v.end());
        std::vector<uint32_t> stamp(n, 0);
        int rounds = 0;
        struct Change { size_t idx; int32_t tri; double d2; };
        if (stop) throw InterruptedError("interrupted while refining the expanded distances");
        checkInterrupt();
        while (!changedList.empty() && rounds < 256) {
            checkInterrupt();
            ++rounds;
            tbb::parallel_sort(changedList.begin(), changedList.end());
            // candidates: free neighbours of the changed voxels (each once)
            std::vector<size_t> cand;
            for (size_t idx : changedList) {
                const int32_t li = int32_t(idx / 512);
                const int ci = int(idx % 512);
                const int i = ci & 7, j = (ci >> 3) & 7, k = ci >> 6;
                for (const auto& off : kOff) {
                    const size_t q = cellIndexAt(li, i + off[0], j + off[1], k + off[2]);
                    if (q == size_t(-1) || mState[q] != kFree || mRefTri[q] < 0 || stamp[q] == uint32_t(rounds)) continue;
                    stamp[q] = uint32_t(rounds);
                    cand.push_back(q);
                }
            }
            tbb::enumerable_thread_specific<std::vector<Change>> changesTls;
            tbb::parallel_for(tbb::blocked_range<size_t>(0, cand.size(), 256), [&](const tbb::blocked_range<size_t>& r) {
                uint64_t steps = 0, evals = 0;
                auto& changes = changesTls.local();
                for (size_t c = r.begin(); c != r.end(); ++c) {
                    const size_t idx = cand[c];
                    const int32_t li = int32_t(idx / 512);
                    const int ci = int(idx % 512);
                    const int i = ci & 7, j = (ci >> 3) & 7, k = ci >> 6;
                    const openvdb::Vec3d p = xform.indexToWorld(mLeaves[size_t(li)]->origin().offsetBy(i, j, k));
                    double best2 = mRefD2[idx];
                    int32_t bestT = mRefTri[idx];
                    int32_t cand[6];
                    int nc = 0;
                    for (const auto& off : kOff) {
                        const size_t q = cellIndexAt(li, i + off[0], j + off[1], k + off[2]);
                        if (q != size_t(-1) && mRefTri[q] != bestT) cand[nc++] = mRefTri[q];
                    }
                    const bool improved = tryBest(p, cand, nc, best2, bestT, steps, evals);
                    if (improved) changes.push_back({idx, bestT, best2});
                }
                walked += steps;
                evalsTotal += evals;
            });
            changedList.clear();
            for (auto& v : changesTls) {
                for (const Change& c : v) {
                    mRefTri[c.idx] = c.tri;
                    mRefD2[c.idx] = c.d2;
                    changedList.push_back(c.idx);
                }
            }
            mStats.improvedByNeighbours += changedList.size();
        }
        mStats.refineRounds = rounds;
        mStats.refineEvaluations = evalsTotal;
        mStats.walkSteps = walked;
        mStats.refinedVoxels = refined;
    }

    void writeBack(float h, float unreached)
    {
        std::atomic<uint64_t> updated{0}, missed{0};
        const bool refined = !mRefTri.empty();
        tbb::parallel_for(tbb::blocked_range<size_t>(0, mLeaves.size(), 16), [&](const tbb::blocked_range<size_t>& r) {
            uint64_t nu = 0, nm = 0;
            for (size_t li = r.begin(); li != r.end(); ++li) {
                if (!mHasFree[li]) continue;
                float* v = mLeaves[li]->buffer().data();
                for (int ci = 0; ci < 512; ++ci) {
                    const size_t idx = li * 512 + size_t(ci);
                    if (mState[idx] != kFree) continue;
                    const openvdb::Index vo = vdbOffset(ci & 7, (ci >> 3) & 7, ci >> 6);
                    const Cell& c = mCells[idx];
                    if (c.d2 < kInf) {
                        float d = std::sqrt(c.d2) * h;
                        if (refined && mRefTri[idx] >= 0) d = std::min(d, float(std::sqrt(mRefD2[idx])));
                        v[vo] = std::copysign(d, v[vo]);
                        ++nu;
                    } else {
                        v[vo] = std::copysign(unreached, v[vo]);
                        ++nm;
                    }
                }
            }
            updated += nu;
            missed += nm;
        });
        mStats.updatedVoxels = updated;
        mStats.unreachedVoxels = missed;
    }

    /// Index into mCells of (i, j, k) relative to leaf L (one leaf step at most), or size_t(-1).
    size_t cellIndexAt(int32_t L, int i, int j, int k) const
    {
        const Cell* c = cellAt(L, i, j, k);
        return c ? size_t(c - mCells.data()) : size_t(-1);
    }

private:

    PropagationStats& mStats;
    std::vector<LeafT*> mLeaves;
    std::vector<Coord> mOrigins;
    std::vector<Row> mRows;
    std::vector<Slab> mSlabs;
    std::vector<int32_t> mNb; ///< per leaf: -x, +x, -y, +y, -z, +z (or -1)
    std::vector<Cell> mCells;
    std::vector<uint8_t> mState;
    std::vector<uint8_t> mHasFree;
    std::vector<int32_t> mRefTri; ///< refined closest triangle per cell (mesh road)
    std::vector<double> mRefD2;   ///< its squared distance, world units
};

} // namespace

void propagateClosestVectors(openvdb::FloatTree& tree, const openvdb::FloatTree& frozen,
                             const ShellVectors& shell, const openvdb::math::Transform& transform,
                             float unreached, openvdb::util::NullInterrupter* interrupter,
                             PropagationStats* statsOut)
{
    PropagationStats stats;
    const auto t0 = Clock::now();
    const float voxelSize = float(transform.voxelSize()[0]);
    tree.voxelizeActiveTiles();
    SparseVcvdt vcvdt(tree, frozen, shell, voxelSize, stats);
    stats.secondsSetup = detail::secondsSince(t0);
    const auto t1 = Clock::now();
    vcvdt.run(interrupter);
    stats.secondsPasses = detail::secondsSince(t1);
    const auto t2 = Clock::now();
    if (shell.points && shell.triangles && shell.mesh) vcvdt.refine(*shell.mesh, transform, interrupter);
    vcvdt.writeBack(voxelSize, unreached);
    stats.secondsFinish = detail::secondsSince(t2);
    if (statsOut) *statsOut = stats;
}

} // namespace vector_expansion_internal
} // namespace levelforge
