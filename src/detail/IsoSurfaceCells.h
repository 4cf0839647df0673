// SPDX-License-Identifier: Apache-2.0
// levelforge internal — the triangles of the interpolated iso-surface in one cell of 8 samples
// (Satherley & Jones §4.1): the cell is split into 6 tetrahedra around its main diagonal
// (Kuhn/Freudenthal; neighbouring cells agree on shared faces, so the surface is closed), and in
// each tetrahedron the surface is the 1 or 2 triangles through the edge crossings found by linear
// interpolation. Shared by SubvoxelShell.cc (dense volumes) and SparseVolumeToLevelSet.cc (VDB
// trees). The triangles are not consistently oriented, and a vertex shared by two tetrahedra may
// differ in the last bit (the crossing is interpolated from either end): a soup.
#pragma once

#include <levelforge/core/TriangleDistance.h>
#include <levelforge/core/TriangleMesh.h>

#include <algorithm>
#include <limits>

namespace levelforge::iso_surface_internal {

/// The 6 tetrahedra of a cell around the diagonal 0 -> 7 (corner bits: x = 1, y = 2, z = 4).
constexpr int kTets[6][4] = {{0, 1, 3, 7}, {0, 1, 5, 7}, {0, 2, 3, 7},
                             {0, 2, 6, 7}, {0, 4, 5, 7}, {0, 4, 6, 7}};

struct Tri
{
    Vec3d a, b, c;
};

/// Appends the 0–2 triangles of one cell (corner values v, corner world positions p).
template<typename Out>
void cellTriangles(const double v[8], const Vec3d p[8], double iso, bool insideBelow, Out&& out)
{
    for (const auto& t : kTets) {
        int in[4], nIn = 0, outc[4], nOut = 0;
        for (int k = 0; k < 4; ++k) {
            const bool inside = insideBelow ? v[t[k]] <= iso : v[t[k]] >= iso;
            if (inside) in[nIn++] = t[k];
            else outc[nOut++] = t[k];
        }
        if (nIn == 0 || nOut == 0) continue;
        auto cross = [&](int a, int b) { // point on edge a-b where the field equals iso
            const double da = v[a] - iso, db = v[b] - iso;
            double s = da / (da - db);
            if (!(s >= 0.0)) s = 0.0;
            if (s > 1.0) s = 1.0;
            return p[a] + (p[b] - p[a]) * s;
        };
        if (nIn == 1) out(Tri{cross(in[0], outc[0]), cross(in[0], outc[1]), cross(in[0], outc[2])});
        else if (nOut == 1) out(Tri{cross(outc[0], in[0]), cross(outc[0], in[1]), cross(outc[0], in[2])});
        else {
            const Vec3d q0 = cross(in[0], outc[0]), q1 = cross(in[0], outc[1]), q2 = cross(in[1], outc[1]),
                        q3 = cross(in[1], outc[0]);
            out(Tri{q0, q1, q2});
            out(Tri{q0, q2, q3});
        }
    }
}

/// Squared distance from p to a triangle, robust to degenerate (collinear) triangles.
inline double triDistance2(const Vec3d& p, const Tri& t, Vec3d& closest)
{
    const Vec3d n = (t.b - t.a).cross(t.c - t.a);
    const double scale = std::max({(t.b - t.a).lengthSqr(), (t.c - t.a).lengthSqr(), 1e-300});
    if (n.lengthSqr() > 1e-24 * scale * scale) {
        const TriangleClosestPoint cp = closestPointOnTriangle(p, t.a, t.b, t.c);
        closest = cp.point;
        return cp.distanceSqr;
    }
    double best = std::numeric_limits<double>::infinity();
    const Vec3d* v[3] = {&t.a, &t.b, &t.c};
    for (int e = 0; e < 3; ++e) {
        const Vec3d& a = *v[e];
        const Vec3d& b = *v[(e + 1) % 3];
        const Vec3d ab = b - a;
        const double l2 = ab.lengthSqr();
        double s = l2 > 0.0 ? (p - a).dot(ab) / l2 : 0.0;
        s = std::min(1.0, std::max(0.0, s));
        const Vec3d q = a + ab * s;
        const double d2 = (p - q).lengthSqr();
        if (d2 < best) { best = d2; closest = q; }
    }
    return best;
}

/// Squared distance from p to the bounding box of t (0 inside): a lower bound of triDistance2.
inline double triBoxDistance2(const Vec3d& p, const Tri& t)
{
    double g2 = 0.0;
    for (int a = 0; a < 3; ++a) {
        const double lo = std::min({t.a[a], t.b[a], t.c[a]}), hi = std::max({t.a[a], t.b[a], t.c[a]});
        const double e = std::max({lo - p[a], p[a] - hi, 0.0});
        g2 += e * e;
    }
    return g2;
}

} // namespace levelforge::iso_surface_internal
