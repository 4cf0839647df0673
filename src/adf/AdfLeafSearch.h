// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Private to src/adf/: the nearest-triangle search of a leaf region, the kernel of the
///        type-1/2 samples (Yin et al. 2011 §6.1, §6.2): the gathered triangle lists of the leaf
///        ± 4 cells, visited nearest cell first, four references at a time, with box and plane
///        lower bounds. Inlined into the leaf pass (both its builds, AdfLeafPass.cc) and the
///        bound check (AdfBounds.cc).
#pragma once

#include "adf/AdfMeshProvider.h"

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include <algorithm>
#include <cmath>
#include <limits>

namespace levelforge {
namespace adf_internal {

LF_HOT void MeshProvider::gather(const Coord& o, MeshScratch& s, bool latticeOnly) const
{
    s.cellSlot.assign(size_t(kRegion) * kRegion * kRegion, -1);
    s.rangeBegin.clear();
    s.quads.clear();
    s.tris.clear();
    s.boxes.clear();
    const Coord rmin = o.offsetBy(-kGather), rmax = o.offsetBy(8 + kGather - 1 - (latticeOnly ? 1 : 0));
    s.centre = Vec3d(o.x() + 4.0, o.y() + 4.0, o.z() + 4.0); // origin of the boxes and planes
    size_t entries = 0;
    auto& cells = s.cells; // (region index, ordinal), in the list leaves' voxel order
    cells.clear();
    const auto& tree = mLists.tree();
    for (int lx = rmin.x() & ~7; lx <= rmax.x(); lx += 8)
        for (int ly = rmin.y() & ~7; ly <= rmax.y(); ly += 8)
            for (int lz = rmin.z() & ~7; lz <= rmax.z(); lz += 8) {
                const auto* leaf = tree.probeConstLeaf(Coord(lx, ly, lz));
                if (!leaf) continue;
                // the part of the leaf inside the region, by mask words
                const int x0 = std::max(rmin.x(), lx) - lx, x1 = std::min(rmax.x(), lx + 7) - lx;
                const int y0 = std::max(rmin.y(), ly) - ly, y1 = std::min(rmax.y(), ly + 7) - ly;
                const int z0 = std::max(rmin.z(), lz) - lz, z1 = std::min(rmax.z(), lz + 7) - lz;
                const uint32_t zmask = (0xffu >> (7 - (z1 - z0))) << z0;
                const auto& mask = leaf->getValueMask();
                const uint32_t* vals = leaf->buffer().data();
                for (int x = x0; x <= x1; ++x) {
                    const uint64_t w = mask.template getWord<uint64_t>(openvdb::Index(x));
                    if (!w) continue;
                    for (int y = y0; y <= y1; ++y) {
                        uint32_t bits = uint32_t(w >> (8 * y)) & zmask;
                        while (bits) {
                            const int z = __builtin_ctz(bits);
                            bits &= bits - 1;
                            const uint32_t ord = vals[(x << 6) | (y << 3) | z];
                            const int idx = ((lx + x - rmin.x()) * kRegion + (ly + y - rmin.y())) * kRegion + (lz + z - rmin.z());
                            cells.push_back({idx, ord});
                            entries += mLists.listSize(ord);
                        }
                    }
                }
            }
    // open addressing on the triangle id + 1 (0 = empty; the keys alone are probed, so
    // they stay in L1), the local id beside; sized for the entries (every distinct
    // triangle is at least one entry), load factor <= 1/2
    size_t hsize = 64;
    while (hsize < 2 * entries) hsize <<= 1;
    const uint32_t hmask = uint32_t(hsize - 1);
    s.hashKey.assign(hsize, 0u);
    s.hashLocal.resize(hsize);
    uint32_t* hkey = s.hashKey.data();
    uint32_t* hlocal = s.hashLocal.data();
    s.quads.reserve(entries / 2 + cells.size());
    for (const auto& cell : cells) {
        s.cellSlot[size_t(cell.first)] = int32_t(s.rangeBegin.size());
        s.rangeBegin.push_back(uint32_t(s.quads.size()));
        int lane = 4;
        for (const uint32_t* t = mLists.listBegin(cell.second); t != mLists.listEnd(cell.second); ++t) {
            const uint32_t key = *t + 1;
            uint32_t h = (*t * 2654435761u) & hmask;
            while (hkey[h] != 0u && hkey[h] != key) h = (h + 1) & hmask;
            if (hkey[h] == 0u) {
                hkey[h] = key;
                hlocal[h] = uint32_t(s.tris.size());
                const Vec3I& tri = mMesh.triangles[*t];
                const Vec3d& a = mPts[tri[0]];
                const Vec3d& b = mPts[tri[1]];
                const Vec3d& c = mPts[tri[2]];
                s.tris.push_back({a, b, c, *t});
                // grown by 2e-7 of its coordinates' magnitude before rounding to float, which
                // covers that rounding and the subtraction's (6e-8 each); kPlaneSlack covers
                // the query point's
                const Vec3d lo = minComponent(minComponent(a, b), c) - s.centre;
                const Vec3d hi = maxComponent(maxComponent(a, b), c) - s.centre;
                const double g = 2e-7 * std::max({std::abs(lo[0]), std::abs(lo[1]), std::abs(lo[2]),
                                                  std::abs(hi[0]), std::abs(hi[1]), std::abs(hi[2])});
                s.boxes.push_back({{float(lo[0] - g), float(lo[1] - g), float(lo[2] - g), 0.0f},
                                   {float(hi[0] + g), float(hi[1] + g), float(hi[2] + g), 0.0f}});
            }
            const uint32_t local = hlocal[h];
            if (lane == 4) {
                s.quads.push_back(kPadQuad);
                lane = 0;
            }
            RefQuad& q = s.quads.back();
            const TriBox& bx = s.boxes[local];
            q.lx[lane] = bx.lo[0]; q.ly[lane] = bx.lo[1]; q.lz[lane] = bx.lo[2];
            q.hx[lane] = bx.hi[0]; q.hy[lane] = bx.hi[1]; q.hz[lane] = bx.hi[2];
            q.t[lane] = local;
            ++lane;
        }
    }
    s.rangeBegin.push_back(uint32_t(s.quads.size()));
    s.stamp.assign(s.tris.size(), 0u);
    s.stampValue = 0;
    s.lastTri = kNone;
    s.planes.resize(s.tris.size());
    s.planeReady.assign(s.tris.size(), 0);
    // the plane bounds and the exact distances round at ~1e-16 of the coordinates (and of
    // 1/sin of the smallest angle, >= 1e-3 where the bound is used): a margin of 1e-6 cells
    // per 1000 cells of coordinate magnitude covers both with a wide reserve
    const double mag = std::max(std::abs(s.centre[0]), std::max(std::abs(s.centre[1]), std::abs(s.centre[2]))) + 64.0;
    s.margin = 1e-6 * std::max(1.0, mag / 1000.0);
}

LF_HOT void MeshProvider::preparePlanes(MeshScratch& s, uint32_t t)
{
    s.planeReady[t] = 1;
    TriPlanes& P = s.planes[t];
    double f[16] = {};
    auto store = [&]() {
        double wmax = 0.0;
        for (int row = 0; row < 4; ++row) {
            P.x[row] = float(f[4 * row]);
            P.y[row] = float(f[4 * row + 1]);
            P.z[row] = float(f[4 * row + 2]);
            P.w[row] = float(f[4 * row + 3]);
            wmax = std::max(wmax, std::abs(f[4 * row + 3]));
        }
        P.err = float(1e-5 + 2e-7 * wmax);
    };
    store(); // no bound until the planes are known to be accurate
    const PreparedTri& pt = s.tris[t];
    const Vec3d v[3] = {pt.a - s.centre, pt.b - s.centre, pt.c - s.centre};
    const Vec3d e0 = v[1] - v[0], e1 = v[2] - v[0];
    Vec3d n = e0.cross(e1);
    const double nl = n.length(), l0 = e0.length(), l1 = e1.length();
    if (!(nl > 1e-3 * l0 * l1) || !std::isfinite(nl)) return; // sliver (or degenerate): no bound
    n /= nl;
    f[0] = n[0]; f[1] = n[1]; f[2] = n[2]; f[3] = -n.dot(v[0]);
    for (int k = 0; k < 3; ++k) {
        Vec3d m = (v[(k + 1) % 3] - v[k]).cross(n);
        const double ml = m.length();
        if (!(ml > 0.0)) return; // P still all zero: no bound
        m /= ml;
        f[4 + 4 * k] = m[0]; f[5 + 4 * k] = m[1]; f[6 + 4 * k] = m[2]; f[7 + 4 * k] = -m.dot(v[k]);
    }
    store();
}

LF_HOT double MeshProvider::boundLimit(double d2, double margin)
{
    if (!(d2 < std::numeric_limits<double>::infinity())) return d2;
    const double d = std::sqrt(d2) + margin;
    return d * d;
}

/// Nearest gathered triangle to q (index space); `base` = the lattice point (local to the
/// region's corner o-4) the offsets are relative to. Exact when the result is <= kGather.
/// Cells are visited nearest-first, four references at a time (RefQuad); a triangle is
/// stamped when its box first passes (a box that fails keeps failing: the best only
/// shrinks); the plane bound only skips triangles that provably (with a rounding margin)
/// cannot beat the current best, so the result, ties included, is that of the plain search.
LF_HOT Nearest MeshProvider::nearest(const Vec3d& q, const Coord& baseLocal, const OffsetTable& table, MeshScratch& s) const
{
    Nearest best;
    if (++s.stampValue == 0) { std::fill(s.stamp.begin(), s.stamp.end(), 0u); s.stampValue = 1; }
    if (s.lastTri < s.tris.size()) { // seed: the previous sample's nearest triangle (an upper bound)
        const PreparedTri& pt = s.tris[s.lastTri];
        s.stamp[s.lastTri] = s.stampValue;
        best.cp = closestPointOnTriangle(q, pt.a, pt.b, pt.c);
        best.d2 = best.cp.distanceSqr;
        best.tri = s.lastTri;
    }
    double limit = boundLimit(best.d2, s.margin);
    const Vec3d r = q - s.centre;
    const float rf[3] = {float(r[0]), float(r[1]), float(r[2])};
#if defined(__SSE2__)
    const __m128 rx4 = _mm_set1_ps(rf[0]), ry4 = _mm_set1_ps(rf[1]), rz4 = _mm_set1_ps(rf[2]);
    const __m128 slack4 = _mm_set1_ps(float(kPlaneSlack));
#endif
    const size_t n = table.off.size();
    const double* td2 = table.d2d.data();
    const int32_t* delta = table.delta.data();
    const int32_t* slots = s.cellSlot.data() + ((baseLocal.x() * kRegion + baseLocal.y()) * kRegion + baseLocal.z());
    const uint32_t* rb = s.rangeBegin.data();
    uint32_t* stamp = s.stamp.data();
    const uint32_t sv = s.stampValue;
    const RefQuad* quads = s.quads.data();
    for (size_t k = 0; k < n; ++k) {
        if (td2[k] >= best.d2) break;
        const int32_t slot = slots[delta[k]];
        if (slot < 0) continue;
        for (uint32_t qi = rb[slot], qe = rb[slot + 1]; qi < qe; ++qi) {
            const RefQuad& quad = quads[qi];
            // box lower bounds of the four references in float: per axis max(lo - p, p - hi,
            // 0) less the slack, summed as (x² + z²) + y² (the order of the one-box form)
            unsigned lanes;
#if defined(__SSE2__)
            {
                const __m128 zero = _mm_setzero_ps();
                auto axis = [&](const float* lo, const float* hi, __m128 p) {
                    __m128 d = _mm_max_ps(_mm_sub_ps(_mm_load_ps(lo), p), _mm_sub_ps(p, _mm_load_ps(hi)));
                    d = _mm_max_ps(_mm_sub_ps(d, slack4), zero);
                    return _mm_mul_ps(d, d);
                };
                const __m128 b = _mm_add_ps(_mm_add_ps(axis(quad.lx, quad.hx, rx4), axis(quad.lz, quad.hz, rz4)),
                                            axis(quad.ly, quad.hy, ry4));
                // at least as permissive as the one-box test boxD2 (1 - 1e-6) < best
                const float tf = best.d2 < 1e30 ? float(best.d2 * (1.0 + 2e-6)) : std::numeric_limits<float>::infinity();
                lanes = unsigned(_mm_movemask_ps(_mm_cmplt_ps(b, _mm_set1_ps(tf))));
                if (!lanes) continue;
            }
#else
            lanes = 0;
            for (int l = 0; l < 4; ++l) {
                const float lo[3] = {quad.lx[l], quad.ly[l], quad.lz[l]}, hi[3] = {quad.hx[l], quad.hy[l], quad.hz[l]};
                float sq[3];
                for (int a = 0; a < 3; ++a) {
                    const float d = std::max(std::max(lo[a] - rf[a], rf[a] - hi[a]) - float(kPlaneSlack), 0.0f);
                    sq[a] = d * d;
                }
                const float b = (sq[0] + sq[2]) + sq[1];
                if (b < 1e30f && double(b) * (1.0 - 1e-6) < best.d2) lanes |= 1u << l;
            }
#endif
            // the lanes not yet stamped (a cell lists a triangle once, so the four differ;
            // padding lanes never pass the box test)
            lanes &= unsigned(stamp[quad.t[0]] != sv) | unsigned(stamp[quad.t[1]] != sv) << 1 |
                     unsigned(stamp[quad.t[2]] != sv) << 2 | unsigned(stamp[quad.t[3]] != sv) << 3;
            while (lanes) {
                const int l = __builtin_ctz(lanes);
                lanes &= lanes - 1;
                // a triangle whose box cannot beat the best is skipped at every visit (the
                // best only shrinks), so stamping only the ones that pass is enough; a
                // triangle evaluated although it cannot beat the best changes nothing
                const uint32_t t = quad.t[l];
                stamp[t] = sv;
                if (limit < std::numeric_limits<double>::infinity()) {
                    if (!s.planeReady[t]) preparePlanes(s, t);
                    const TriPlanes& P = s.planes[t];
                    float v[4];
#if defined(__SSE2__)
                    const __m128 pv = _mm_add_ps(_mm_add_ps(_mm_mul_ps(_mm_load_ps(P.x), rx4), _mm_mul_ps(_mm_load_ps(P.y), ry4)),
                                                 _mm_add_ps(_mm_mul_ps(_mm_load_ps(P.z), rz4), _mm_load_ps(P.w)));
                    _mm_storeu_ps(v, pv);
#else
                    for (int row = 0; row < 4; ++row) v[row] = P.x[row] * rf[0] + P.y[row] * rf[1] + P.z[row] * rf[2] + P.w[row];
#endif
                    const double slack = kPlaneSlack + double(P.err);
                    const double pl = std::max(std::abs(double(v[0])) - slack, 0.0);
                    const double e = std::max(double(std::max(std::max(v[1], v[2]), std::max(v[3], 0.0f))) - slack, 0.0);
                    if (pl * pl + e * e > limit) continue;
                }
                const PreparedTri& pt = s.tris[t];
                const TriangleClosestPoint cp = closestPointOnTriangle(q, pt.a, pt.b, pt.c);
                if (cp.distanceSqr < best.d2) {
                    best.d2 = cp.distanceSqr;
                    best.tri = t;
                    best.cp = cp;
                    limit = boundLimit(best.d2, s.margin);
                }
            }
        }
    }
    s.lastTri = best.tri;
    return best;
}

} // namespace adf_internal
} // namespace levelforge
