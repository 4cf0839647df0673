// SPDX-License-Identifier: Apache-2.0
// Geometry of the boundary-current bounds of the fast winding number (mesh/FastWindingNumber.h):
// the distance from a straight edge to a box, whether it meets the box, and one edge's bound of
// the Hessian of w.
#pragma once

#include <levelforge/core/TriangleMesh.h>

#include <algorithm>
#include <cmath>
#include <utility>

namespace levelforge::fwn_internal {

/// Squared distance from the segment [a, b] to the box [lo, hi], less a slack far above its
/// rounding (so a lower bound): the minimum over t of g(t) = Σ_k (a_k + t d_k clamped out of
/// [lo_k, hi_k])², a convex piecewise quadratic in t whose pieces break where a coordinate
/// crosses a face's plane; the piece where g' changes sign holds the minimum. (The distance
/// between the segment's box and the box would be 0 wherever the box lies inside a long
/// oblique segment's box: a stray vertex far away would put every box of the object at
/// distance 0 from its edges.)
inline double segmentBoxDist2(const Vec3d& a, const Vec3d& b, const Vec3d& lo, const Vec3d& hi)
{
    const Vec3d d = b - a;
    const auto at = [&](double t, int k) { return a[k] + t * d[k]; };
    const auto value = [&](double t) {
        double g = 0.0;
        for (int k = 0; k < 3; ++k) {
            const double x = at(t, k);
            const double e = x < lo[k] ? lo[k] - x : (x > hi[k] ? x - hi[k] : 0.0);
            g += e * e;
        }
        return g;
    };
    const auto slope = [&](double t) {
        double g = 0.0;
        for (int k = 0; k < 3; ++k) {
            const double x = at(t, k);
            if (x < lo[k]) g += d[k] * (x - lo[k]);
            else if (x > hi[k]) g += d[k] * (x - hi[k]);
        }
        return g;
    };
    double ts[8];
    int n = 0;
    ts[n++] = 0.0;
    for (int k = 0; k < 3; ++k) {
        if (d[k] == 0.0) continue;
        for (double face : {lo[k], hi[k]}) {
            const double t = (face - a[k]) / d[k];
            if (t > 0.0 && t < 1.0) ts[n++] = t;
        }
    }
    ts[n++] = 1.0;
    for (int i = 1; i < n; ++i) // insertion sort of at most 8
        for (int j = i; j > 0 && ts[j] < ts[j - 1]; --j) std::swap(ts[j], ts[j - 1]);
    double best = value(0.0);
    if (slope(0.0) < 0.0) {
        best = value(1.0);
        for (int i = 1; i < n; ++i) {
            if (slope(ts[i]) < 0.0 && i + 1 < n) continue;
            // the minimum lies in [ts[i-1], ts[i]]: there each coordinate stays on one side
            const double tm = 0.5 * (ts[i - 1] + ts[i]);
            double num = 0.0, den = 0.0;
            for (int k = 0; k < 3; ++k) {
                const double x = at(tm, k);
                if (x < lo[k]) { num += d[k] * (lo[k] - a[k]); den += d[k] * d[k]; }
                else if (x > hi[k]) { num += d[k] * (hi[k] - a[k]); den += d[k] * d[k]; }
            }
            const double t = den > 0.0 ? std::clamp(num / den, ts[i - 1], ts[i]) : ts[i - 1];
            best = std::min({best, value(t), value(ts[i - 1]), value(ts[i])});
            break;
        }
    }
    double scale = 0.0;
    for (int k = 0; k < 3; ++k)
        scale += std::abs(a[k]) + std::abs(b[k]) + std::abs(lo[k]) + std::abs(hi[k]);
    const double dist = std::sqrt(best) - 1e-12 * scale;
    return dist > 0.0 ? dist * dist : 0.0;
}

/// True when the segment [a, b] meets the box [lo, hi] (slab test, boundaries included).
inline bool segmentMeetsBox(const Vec3d& a, const Vec3d& b, const Vec3d& lo, const Vec3d& hi)
{
    double t0 = 0.0, t1 = 1.0;
    for (int k = 0; k < 3; ++k) {
        const double d = b[k] - a[k];
        if (d == 0.0) {
            if (a[k] < lo[k] || a[k] > hi[k]) return false;
            continue;
        }
        double u = (lo[k] - a[k]) / d, v = (hi[k] - a[k]) / d;
        if (u > v) std::swap(u, v);
        t0 = std::max(t0, u);
        t1 = std::min(t1, v);
        if (t0 > t1) return false;
    }
    return true;
}

/// One straight current element's bound of the operator norm of ∇∇w over a box at squared
/// distance de2 from it, times 4π: |I| min(2 L/δ³, 4/δ²).
inline double edgeHessianTerm(double current, double length, double de2)
{
    return current * std::min(2.0 * length / (de2 * std::sqrt(de2)), 4.0 / de2);
}

} // namespace levelforge::fwn_internal
