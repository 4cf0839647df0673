// SPDX-License-Identifier: Apache-2.0
// The exact band's kernel for leaves near few triangles: single-precision distances of every
// voxel of the leaf to each nearby triangle at once, then exact (double) evaluation of the
// triangles that can be closest. See flatLeafDistances() in MeshToLevelSetInternal.h.
#include "mesh/MeshToLevelSetInternal.h"

#include <levelforge/core/TriangleDistance.h>

#include <algorithm>
#include <cmath>
#include <atomic>
#include <cstring>

namespace levelforge::meshtols_internal {

namespace {

// Eight voxels along z per vector; on x86-64 the bodies are compiled for the baseline (two SSE
// halves) and AVX2 (one register), picked at run time. Which build runs changes no result: the vectors only choose which
// triangles are evaluated exactly, with a margin.
typedef float F8 __attribute__((vector_size(32), aligned(4), may_alias));
typedef int32_t I8 __attribute__((vector_size(32), aligned(4), may_alias));

__attribute__((always_inline)) inline bool anyLane(const I8& m)
{
    int32_t w[8];
    std::memcpy(w, &m, sizeof(w));
    return (w[0] | w[1] | w[2] | w[3] | w[4] | w[5] | w[6] | w[7]) != 0;
}


/// The single-precision squared distance from the lanes' voxels, at (qx, qy, lane)
/// relative to the leaf's first voxel centre, to triangle T: the plane distance where the point
/// projects inside the three edges, the nearest edge segment otherwise (the formula of the
/// cluster bounds, TriangleHierarchy.h), or the plane distance alone when every lane of the
/// vector is at least reach2 from the plane, into out. Eight lanes: one row along z. (Vectors
/// go by reference: by value their ABI would depend on the build.)
__attribute__((always_inline)) inline void laneBounds(const LeafTriangle& T, float qx, float qy, float reach2, F8& out)
{
    const F8 qz = {0.0f, 1.0f, 2.0f, 3.0f, 4.0f, 5.0f, 6.0f, 7.0f};
    const F8 zero = {}, one = zero + 1.0f;
    const F8 pd = T.n[2] * qz + (T.n[0] * qx + T.n[1] * qy - T.off);
    const F8 pd2 = pd * pd;
    if (!anyLane(pd2 < reach2)) {
        out = pd2;
        return;
    }
    I8 outside = {};
    F8 seg = zero + 3.0e38f;
    for (int k = 0; k < 3; ++k) {
        const float dx = qx - T.a[k][0], dy = qy - T.a[k][1];
        const F8 dz = qz - T.a[k][2];
        // outside the edge line: (e × n) · d > 0 (counter-clockwise corners)
        const F8 side = T.m[k][2] * dz + (T.m[k][0] * dx + T.m[k][1] * dy);
        outside |= side > zero;
        F8 t = (T.e[k][2] * dz + (T.e[k][0] * dx + T.e[k][1] * dy)) * T.inv[k];
        t = t < zero ? zero : t;
        t = t > one ? one : t;
        const F8 rx = dx - t * T.e[k][0], ry = dy - t * T.e[k][1], rz = dz - t * T.e[k][2];
        const F8 s2 = rx * rx + ry * ry + rz * rz;
        seg = s2 < seg ? s2 : seg;
    }
    out = outside != 0 ? seg : pd2;
}

/// lb[t·512 + v] = laneBounds() of voxel v (offset i·64 + j·8 + k) and triangle t for the rows
/// (i, j) of t's range, fmin[v] = min over t. Rows outside t's range are left as they are.
/// (A 16-lane AVX-512 build, two rows per vector, was tried on 2026-12-04 with these vector
/// extensions: the distance stage went from 0.74 s to 1.08 s on armadillo_100k at 1024; dropped.)
__attribute__((always_inline)) inline void boundsBody(const LeafTriangle* tris, uint32_t count, float reach2, float* lb,
                                                     float* fmin)
{
    for (uint32_t ti = 0; ti < count; ++ti) {
        const LeafTriangle& T = tris[ti];
        float* L = lb + size_t(ti) * 512;
        for (int i = T.x0; i <= T.x1; ++i)
            for (int j = T.y0; j <= T.y1; ++j) {
                const int at = i * 64 + j * 8;
                F8 l;
                laneBounds(T, float(i), float(j), reach2, l);
                *reinterpret_cast<F8*>(L + at) = l;
                F8* m = reinterpret_cast<F8*>(fmin + at);
                *m = l < *m ? l : *m;
            }
    }
}

/// rows[t·64 + r] = the lanes (bit k: voxel r·8 + k) of row r whose bound to triangle t is
/// below the voxel's threshold thr, for the rows of t's range (the others are not written).
__attribute__((always_inline)) inline void candidatesBody(const LeafTriangle* tris, uint32_t count, const float* lb,
                                                         const float* thr, uint8_t* rows)
{
    for (uint32_t ti = 0; ti < count; ++ti) {
        const LeafTriangle& T = tris[ti];
        const float* L = lb + size_t(ti) * 512;
        uint8_t* R = rows + size_t(ti) * 64;
        for (int i = T.x0; i <= T.x1; ++i)
            for (int j = T.y0; j <= T.y1; ++j) {
                const int row = i * 8 + j;
                const I8 below = *reinterpret_cast<const F8*>(L + row * 8) < *reinterpret_cast<const F8*>(thr + row * 8);
                uint8_t bits = 0;
                if (anyLane(below))
                    for (int k = 0; k < 8; ++k) bits = uint8_t(bits | (below[k] ? 1u << k : 0u));
                R[row] = bits;
            }
    }
}

void boundsBaseline(const LeafTriangle* tris, uint32_t count, float reach2, float* lb, float* fmin)
{
    boundsBody(tris, count, reach2, lb, fmin);
}

void candidatesBaseline(const LeafTriangle* tris, uint32_t count, const float* lb, const float* thr, uint8_t* rows)
{
    candidatesBody(tris, count, lb, thr, rows);
}

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define LEVELFORGE_FLAT_AVX2 1
__attribute__((target("avx2"))) void boundsAvx2(const LeafTriangle* tris, uint32_t count, float reach2, float* lb,
                                                float* fmin)
{
    boundsBody(tris, count, reach2, lb, fmin);
}

__attribute__((target("avx2"))) void candidatesAvx2(const LeafTriangle* tris, uint32_t count, const float* lb,
                                                    const float* thr, uint8_t* rows)
{
    candidatesBody(tris, count, lb, thr, rows);
}
#endif

std::atomic<size_t> gMaxTriangles{kMaxLeafTriangles};
std::atomic<int> gWidest{int(FlatLeafIsa::Avx2)}; // the widest build the tests allow

/// The widest build of the kernels this CPU runs (and the tests allow).
FlatLeafIsa flatLeafIsa()
{
    const int cap = gWidest.load(std::memory_order_relaxed);
#if defined(LEVELFORGE_FLAT_AVX2)
    static const bool avx2 = __builtin_cpu_supports("avx2");
    if (avx2 && cap >= int(FlatLeafIsa::Avx2)) return FlatLeafIsa::Avx2;
#endif
    (void)cap;
    return FlatLeafIsa::Baseline;
}

void leafBounds(FlatLeafIsa isa, const LeafTriangle* tris, uint32_t count, float reach2, float* lb, float* fmin)
{
#if defined(LEVELFORGE_FLAT_AVX2)
    if (isa == FlatLeafIsa::Avx2) { boundsAvx2(tris, count, reach2, lb, fmin); return; }
#endif
    boundsBaseline(tris, count, reach2, lb, fmin);
}

void leafCandidates(FlatLeafIsa isa, const LeafTriangle* tris, uint32_t count, const float* lb, const float* thr,
                    uint8_t* rows)
{
#if defined(LEVELFORGE_FLAT_AVX2)
    if (isa != FlatLeafIsa::Baseline) { candidatesAvx2(tris, count, lb, thr, rows); return; }
#endif
    candidatesBaseline(tris, count, lb, thr, rows);
}

/// |(3.5, 3.5, 3.5)|: the farthest a voxel centre of a leaf is from the leaf's centre.
constexpr double kLeafHalfDiagonal = 6.0621778264910713;

} // namespace

void setFlatLeafOptionsForTesting(size_t maxTriangles, FlatLeafIsa widest)
{
    gMaxTriangles.store(maxTriangles);
    gWidest.store(int(widest));
}

FlatLeafIsa flatLeafIsaForTesting() { return flatLeafIsa(); }

bool flatLeafDistances(const Context& ctx, const Coord& origin, Scratch& s, uint32_t* tri, TriangleClosestPoint* cps)
{
    const size_t maxTriangles = gMaxTriangles.load(std::memory_order_relaxed);
    if (!s.flat || s.order.empty()) return false;
    const auto& nodes = ctx.hierarchy.nodes();
    const auto& clusters = ctx.hierarchy.clusters();
    // too many triangles around for one pass over the whole leaf each: the search per voxel
    size_t lanes = 0;
    for (const auto& entry : s.order) lanes += clusters[nodes[entry.second].left].count;
    if (lanes > 4 * maxTriangles) return false;

    const Vec3d base(origin.x() + 0.5, origin.y() + 0.5, origin.z() + 0.5), centre = base + Vec3d(3.5);
    const double reach = ctx.limit + ctx.margin;
    // a triangle some voxel centre of the leaf is within the reach of is within
    // reach + kLeafHalfDiagonal of the centre; its bound there within that plus the margin
    const double pick = reach + kLeafHalfDiagonal + 2.0 * ctx.margin;
    const float pick2 = float(pick * pick) * (1.0f + 1e-6f);
    s.leafIds.clear();
    for (const auto& entry : s.order) {
        const TriangleCluster& c = clusters[nodes[entry.second].left];
        const Vec3d q = centre - c.origin;
        alignas(16) float lb2[kClusterSize];
        uint32_t mask = clusterBounds(c, float(q[0]), float(q[1]), float(q[2]), pick2, lb2);
        s.boundTests += c.count;
        for (; mask; mask &= mask - 1) s.leafIds.push_back(c.ids[__builtin_ctz(mask)]);
    }
    // in increasing index (ties go to the smaller), once each (a split triangle is in several clusters)
    std::sort(s.leafIds.begin(), s.leafIds.end());
    s.leafIds.erase(std::unique(s.leafIds.begin(), s.leafIds.end()), s.leafIds.end());
    if (s.leafIds.size() > maxTriangles) return false;

    // the triangles relative to the first voxel centre, with the voxel rows they can reach
    s.leafTris.clear();
    double radius = 14.0; // |q| <= 7√3 for the voxels, and the corners'
    for (const uint32_t id : s.leafIds) {
        const Vec3I& tr = ctx.mesh.triangles[id];
        const Vec3d P[3] = {ctx.cellPts[tr[0]] - base, ctx.cellPts[tr[1]] - base, ctx.cellPts[tr[2]] - base};
        int range[3][2];
        bool empty = false;
        for (int k = 0; k < 3; ++k) {
            const double lo = std::min({P[0][k], P[1][k], P[2][k]}), hi = std::max({P[0][k], P[1][k], P[2][k]});
            range[k][0] = int(std::max(0.0, std::ceil(lo - reach)));
            range[k][1] = int(std::min(7.0, std::floor(hi + reach)));
            empty = empty || range[k][0] > range[k][1];
            radius = std::max({radius, std::abs(lo), std::abs(hi)});
        }
        if (empty) continue;
        const Vec3d e1 = P[1] - P[0], e2 = P[2] - P[0];
        const Vec3d nd = e1.cross(e2);
        const double len = nd.length();
        // The bounds here must be right both ways (a bound too low lowers a voxel's threshold
        // and could leave its closest triangle out), so the unit normal must be: its direction
        // error from the double cross product is about 4ε|e1||e2| / |e1 × e2|, times the
        // distance to the plane's points. A sliver for which that comes near the margin (or
        // whose cell-space corners came out collinear) sends the leaf to the search per voxel,
        // which only needs lower bounds.
        const double reachOfPlane = radius + 14.0;
        if (!(len > 0.0) || 1e-15 * e1.length() * e2.length() / len * reachOfPlane > 0.25 * ctx.margin) return false;
        LeafTriangle T;
        T.id = id;
        T.x0 = range[0][0];
        T.x1 = range[0][1];
        T.y0 = range[1][0];
        T.y1 = range[1][1];
        for (int k = 0; k < 3; ++k) T.n[k] = float(nd[k] / len);
        for (int c = 0; c < 3; ++c)
            for (int k = 0; k < 3; ++k) T.a[c][k] = float(P[c][k]);
        T.off = float(double(T.n[0]) * double(T.a[0][0]) + double(T.n[1]) * double(T.a[0][1]) +
                      double(T.n[2]) * double(T.a[0][2]));
        for (int c = 0; c < 3; ++c) {
            const int d = (c + 1) % 3;
            float* e = T.e[c];
            for (int k = 0; k < 3; ++k) e[k] = T.a[d][k] - T.a[c][k];
            T.m[c][0] = e[1] * T.n[2] - e[2] * T.n[1];
            T.m[c][1] = e[2] * T.n[0] - e[0] * T.n[2];
            T.m[c][2] = e[0] * T.n[1] - e[1] * T.n[0];
            const float l2 = e[0] * e[0] + e[1] * e[1] + e[2] * e[2];
            T.inv[c] = l2 > 0.0f ? 1.0f / l2 : 0.0f;
        }
        s.leafTris.push_back(T);
    }
    const uint32_t count = uint32_t(s.leafTris.size());
    ++s.leafPasses;
    // The single-precision distances are within a few ulps of the coordinates' magnitude of the
    // exact ones (as the cluster bounds, TriangleHierarchy.h); the margin covers that 8x.
    const double margin = std::max(ctx.margin, 2e-6 * (radius + 2.0));
    const double cap = ctx.limit + margin;
    s.leafLb.resize(size_t(count) * 512); // only the rows in each triangle's range are written and read
    std::fill(s.leafMin, s.leafMin + 512, 3.0e38f);
    const FlatLeafIsa isa = flatLeafIsa();
    leafBounds(isa, s.leafTris.data(), count, float(cap * cap), s.leafLb.data(), s.leafMin);
    for (uint32_t ti = 0; ti < count; ++ti) {
        const LeafTriangle& T = s.leafTris[ti];
        s.boundTests += uint64_t(T.x1 - T.x0 + 1) * uint64_t(T.y1 - T.y0 + 1) * 8u;
    }

    // Exact evaluation of every triangle whose bound is within 2 margins of the smallest bound:
    // the closest triangle t* has bound <= (d* + m)² and the smallest bound is at least
    // (d* - m)² (a bound below the cap is a distance to within m, not the plane's lower bound),
    // so t* and every triangle tied with it are among them. The closest by (d², index) wins.
    const float capf = float(cap * cap) * (1.0f + 1e-6f);
    for (uint32_t v = 0; v < 512; ++v) {
        tri[v] = kNone;
        s.leafBest2[v] = ctx.limit2;
        const float f = s.leafMin[v];
        if (!(f < capf)) { s.leafThr[v] = -1.0f; continue; } // no triangle within the limit
        const double th = std::sqrt(double(f)) + 2.0 * margin;
        s.leafThr[v] = float(th * th) * (1.0f + 1e-6f);
    }
    // triangle by triangle in increasing index, row by row: a later triangle replaces the best
    // only when strictly closer, so ties keep the smaller index
    s.leafRows.resize(size_t(count) * 64);
    leafCandidates(isa, s.leafTris.data(), count, s.leafLb.data(), s.leafThr, s.leafRows.data());
    for (uint32_t ti = 0; ti < count; ++ti) {
        const LeafTriangle& T = s.leafTris[ti];
        const uint8_t* R = s.leafRows.data() + size_t(ti) * 64;
        const Vec3I& tr = ctx.mesh.triangles[T.id];
        const Vec3d &A = ctx.cellPts[tr[0]], &B = ctx.cellPts[tr[1]], &C = ctx.cellPts[tr[2]];
        for (int i = T.x0; i <= T.x1; ++i)
            for (int j = T.y0; j <= T.y1; ++j)
                for (uint32_t bits = R[i * 8 + j]; bits; bits &= bits - 1) {
                    const int k = __builtin_ctz(bits);
                    const uint32_t v = uint32_t(i * 64 + j * 8 + k);
                    const Vec3d p(base[0] + double(i), base[1] + double(j), base[2] + double(k));
                    const TriangleClosestPoint cp = closestPointOnTriangle(p, A, B, C);
                    ++s.evaluations;
                    if (cp.distanceSqr < s.leafBest2[v]) {
                        s.leafBest2[v] = cp.distanceSqr;
                        tri[v] = T.id;
                        cps[v] = cp;
                    }
                }
    }
    return true;
}

} // namespace levelforge::meshtols_internal
