// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief One triangle tested against many axis-aligned boxes (private to mesh/): the
///        Akenine-Möller separating-axis test of triangleBoxOverlap(), with the triangle's
///        13 axes and its intervals on them computed once.
///
/// The candidate-leaf step of the exact band (MeshToLevelSet.cc) tests every triangle against
/// the dilated boxes of the leaves (and blocks of leaves) around it: tens of boxes per triangle
/// at 1024–2048 voxels. triangleBoxOverlap() rebuilds the edges, the normal, the 9 cross-product
/// axes and the triangle's projections on them for every box; here they are built once per
/// triangle, and a box costs one dot product per axis (its centre's) plus the projected
/// half-size. Conservative as triangleBoxOverlap() is: a box is rejected only when an axis
/// separates it from the triangle by more than the tolerance (times the axis length) plus an
/// allowance for the rounding of the projections; boxes touching or overlapping the triangle
/// are never rejected. Exactly the same axes are tested (degenerate ones skipped), so the boxes
/// it accepts are those triangleBoxOverlap() accepts, up to separations within that allowance.
#pragma once

#include <levelforge/core/TriangleMesh.h>

#include <algorithm>
#include <cmath>

namespace levelforge::mesh_internal {

class PreparedTriangleBox
{
public:
    /// The triangle (a, b, c); tolerance: separations up to tolerance × |axis| count as overlap
    /// (triangleBoxOverlap()'s meaning).
    PreparedTriangleBox(const Vec3d& a, const Vec3d& b, const Vec3d& c, double tolerance) : mOrigin(a)
    {
        const Vec3d v[3] = {Vec3d(0.0), b - a, c - a}; // relative to a: small, exact differences
        const Vec3d e[3] = {v[1] - v[0], v[2] - v[1], v[0] - v[2]};
        double extent = 0.0;
        for (const Vec3d& p : v) extent = std::max({extent, std::abs(p[0]), std::abs(p[1]), std::abs(p[2])});
        auto add = [&](const Vec3d& axis) {
            const double len2 = axis.lengthSqr();
            if (len2 == 0.0) return; // a degenerate axis separates nothing
            Axis& A = mAxes[mCount++];
            A.n = axis;
            A.abs = Vec3d(std::abs(axis[0]), std::abs(axis[1]), std::abs(axis[2]));
            const double p0 = axis.dot(v[0]), p1 = axis.dot(v[1]), p2 = axis.dot(v[2]);
            A.lo = std::min({p0, p1, p2});
            A.hi = std::max({p0, p1, p2});
            // tolerance as triangleBoxOverlap() scales it, plus the rounding of a projection of
            // coordinates up to extent (triangle) and of the box centre's (relative to a),
            // bounded at test time by the same factor times |centre - a|
            const double l1 = A.abs[0] + A.abs[1] + A.abs[2];
            A.slack = tolerance * std::sqrt(len2) + 1e-13 * l1 * (extent + 1.0);
            A.rel = 1e-13 * l1;
        };
        // the triangle's plane first (it separates most often), the box's own axes last (the
        // callers' boxes lie in the triangle's dilated bounding box: they rarely separate)
        mNormal = e[0].cross(e[1]);
        add(mNormal);
        for (int j = 0; j < 3; ++j) // unit axis i × edge j
            for (int i = 0; i < 3; ++i) {
                Vec3d axis(0.0);
                const int i1 = (i + 1) % 3, i2 = (i + 2) % 3;
                axis[i1] = -e[j][i2];
                axis[i2] = e[j][i1];
                add(axis);
            }
        for (int i = 0; i < 3; ++i) {
            Vec3d u(0.0);
            u[i] = 1.0;
            add(u);
        }
    }

    /// True unless an axis separates the box (centre, half-sizes) from the triangle.
    bool overlaps(const Vec3d& centre, const Vec3d& half) const
    {
        const Vec3d q = centre - mOrigin;
        const double qmax = std::max({std::abs(q[0]), std::abs(q[1]), std::abs(q[2])});
        for (int k = 0; k < mCount; ++k) {
            const Axis& A = mAxes[k];
            const double p = A.n.dot(q);
            const double r = A.abs.dot(half) + A.slack + A.rel * qmax;
            if (A.lo - p > r || p - A.hi > r) return false;
        }
        return true;
    }

    /// The first vertex (a) and the unnormalised normal (b − a) × (c − b), zero when degenerate.
    const Vec3d& origin() const { return mOrigin; }
    const Vec3d& normal() const { return mNormal; }

private:
    struct Axis
    {
        Vec3d n, abs;
        double lo, hi, slack, rel;
    };
    Vec3d mOrigin, mNormal{0.0};
    Axis mAxes[13];
    int mCount = 0;
};

} // namespace levelforge::mesh_internal
