// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Exact point–triangle distance with the closest feature.
///
/// The closest point of a triangle to a point, found by Voronoi-region classification (vertex,
/// edge or face region; the standard barycentric case analysis, e.g. Ericson, "Real-Time
/// Collision Detection" §5.1.5). Exact up to double rounding. The returned feature selects the
/// pseudonormal used for the sign (PseudoNormals.h, Chang et al. §4.2).
#pragma once

#include <levelforge/core/TriangleFeature.h>
#include <levelforge/core/TriangleMesh.h>

namespace levelforge {

/// @brief The answer of closestPointOnTriangle().
struct TriangleClosestPoint
{
    Vec3d point;                 ///< closest point on the triangle
    double distanceSqr;          ///< squared distance |p - point|²
    TriangleFeature feature;     ///< Voronoi region holding `point`
};

/// @brief Closest point on triangle (a, b, c) to p.
///
/// Inline: it is the innermost loop of every method. Works in any units (world or index space)
/// as long as all four points share them.
/// @param[in] p  the query point
/// @param[in] a  first corner of the triangle
/// @param[in] b  second corner of the triangle
/// @param[in] c  third corner of the triangle
/// @return the closest point, its squared distance to @p p and the Voronoi region (vertex, edge
///         or face) that holds it
inline TriangleClosestPoint closestPointOnTriangle(const Vec3d& p, const Vec3d& a, const Vec3d& b,
                                                  const Vec3d& c)
{
    auto make = [&p](const Vec3d& q, TriangleFeature f) {
        return TriangleClosestPoint{q, (p - q).lengthSqr(), f};
    };
    const Vec3d ab = b - a, ac = c - a, ap = p - a;
    const double d1 = ab.dot(ap), d2 = ac.dot(ap);
    if (d1 <= 0.0 && d2 <= 0.0) return make(a, TriangleFeature::Vertex0);

    const Vec3d bp = p - b;
    const double d3 = ab.dot(bp), d4 = ac.dot(bp);
    if (d3 >= 0.0 && d4 <= d3) return make(b, TriangleFeature::Vertex1);

    const double vc = d1 * d4 - d3 * d2;
    if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) {
        const double v = d1 / (d1 - d3);
        return make(a + ab * v, TriangleFeature::Edge01);
    }

    const Vec3d cp = p - c;
    const double d5 = ab.dot(cp), d6 = ac.dot(cp);
    if (d6 >= 0.0 && d5 <= d6) return make(c, TriangleFeature::Vertex2);

    const double vb = d5 * d2 - d1 * d6;
    if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) {
        const double w = d2 / (d2 - d6);
        return make(a + ac * w, TriangleFeature::Edge20);
    }

    const double va = d3 * d6 - d5 * d4;
    if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0) {
        const double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return make(b + (c - b) * w, TriangleFeature::Edge12);
    }

    const double denom = 1.0 / (va + vb + vc);
    const double v = vb * denom, w = vc * denom;
    return make(a + ab * v + ac * w, TriangleFeature::Face);
}

/// @brief Squared distance from p to the axis-aligned box [lo, hi] (0 inside).
///
/// A lower bound of the distance to anything inside the box.
/// @param[in] p   the query point
/// @param[in] lo  the box's minimum corner (same units as @p p)
/// @param[in] hi  the box's maximum corner (same units as @p p)
/// @return the squared distance, in the units of @p p squared
inline double boxDistanceSqr(const Vec3d& p, const Vec3d& lo, const Vec3d& hi)
{
    double d2 = 0.0;
    for (int k = 0; k < 3; ++k) {
        const double e = p[k] < lo[k] ? lo[k] - p[k] : (p[k] > hi[k] ? p[k] - hi[k] : 0.0);
        d2 += e * e;
    }
    return d2;
}

} // namespace levelforge
