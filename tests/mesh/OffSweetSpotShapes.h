// SPDX-License-Identifier: Apache-2.0
// Closed, consistently oriented shapes off the exact band's sweet spot (issue 15): slivers, vertex
// fans, needles. Shared by the main-road tests.
#pragma once

#include <levelforge/core/TriangleMesh.h>

#include <cmath>

namespace levelforge_test {

using levelforge::TriangleMesh;
using levelforge::Vec3d;
using levelforge::Vec3I;

/// A UV sphere of `around` longitudes and `bands` latitude bands, poles closed by fans: for
/// around >> bands every triangle is a sliver (6000 × 4 in the field report).
inline TriangleMesh makeSliverSphere(int around, int bands, double r)
{
    TriangleMesh m;
    m.points.emplace_back(0.0, 0.0, r);
    for (int b = 1; b < bands; ++b) {
        const double th = M_PI * b / bands;
        for (int a = 0; a < around; ++a) {
            const double ph = 2.0 * M_PI * a / around;
            m.points.emplace_back(r * std::sin(th) * std::cos(ph), r * std::sin(th) * std::sin(ph), r * std::cos(th));
        }
    }
    m.points.emplace_back(0.0, 0.0, -r);
    const uint32_t south = uint32_t(m.points.size() - 1);
    auto ring = [&](int b, int a) { return uint32_t(1 + (b - 1) * around + ((a % around) + around) % around); };
    for (int a = 0; a < around; ++a) m.triangles.emplace_back(0u, ring(1, a), ring(1, a + 1));
    for (int b = 1; b + 1 < bands; ++b)
        for (int a = 0; a < around; ++a) {
            m.triangles.emplace_back(ring(b, a), ring(b + 1, a), ring(b + 1, a + 1));
            m.triangles.emplace_back(ring(b, a), ring(b + 1, a + 1), ring(b, a + 1));
        }
    for (int a = 0; a < around; ++a) m.triangles.emplace_back(south, ring(bands - 1, a + 1), ring(bands - 1, a));
    return m;
}

/// A double cone: `n` triangles share the apex (0, 0, h), n more the tip (0, 0, -h).
inline TriangleMesh makeVertexFan(int n, double radius, double h)
{
    TriangleMesh m;
    m.points.emplace_back(0.0, 0.0, h);
    m.points.emplace_back(0.0, 0.0, -h);
    for (int a = 0; a < n; ++a) {
        const double ph = 2.0 * M_PI * a / n;
        m.points.emplace_back(radius * std::cos(ph), radius * std::sin(ph), 0.0);
    }
    for (int a = 0; a < n; ++a) {
        const uint32_t i = uint32_t(2 + a), j = uint32_t(2 + (a + 1) % n);
        m.triangles.emplace_back(0u, i, j);
        m.triangles.emplace_back(1u, j, i);
    }
    return m;
}

/// A long thin triangular prism along x (needles: triangles `length` long, `width` wide).
inline TriangleMesh makeNeedle(double length, double width)
{
    TriangleMesh m;
    const double w = width;
    const Vec3d c[3] = {Vec3d(0.0, 0.0, 0.0), Vec3d(0.0, w, 0.0), Vec3d(0.0, 0.5 * w, 0.8 * w)};
    for (int e = 0; e < 2; ++e)
        for (int k = 0; k < 3; ++k) m.points.push_back(c[k] + Vec3d(e ? length : 0.0, 0.0, 0.0));
    m.triangles = {Vec3I(0, 2, 1), Vec3I(3, 4, 5)};
    for (uint32_t k = 0; k < 3; ++k) {
        const uint32_t a = k, b = (k + 1) % 3;
        m.triangles.emplace_back(a, b, b + 3);
        m.triangles.emplace_back(a, b + 3, a + 3);
    }
    return m;
}

} // namespace levelforge_test
