// SPDX-License-Identifier: Apache-2.0
// The one-atan2 sum of solid angles (winding_internal::SolidAngleSum, used by the fast winding
// number's near field and the winding sign's local exact tier) against the sum of
// triangleSolidAngle(): the same to rounding on soups, near and on triangles, and whole turns
// (closed surfaces seen from inside, nested layers) never lost.
#include "TestUtil.h"
#include "mesh/WindingSignInternal.h"

#include <levelforge/mesh/FastWindingNumber.h>
#include <levelforge/reference/ExactReference.h>
#include <levelforge/reference/MeshShapes.h>

#include <cmath>
#include <random>
#include <vector>

using namespace levelforge;
using levelforge::winding_internal::SolidAngleSum;

namespace {
constexpr double kPi = 3.14159265358979323846;

double plainSum(const TriangleMesh& m, const Vec3d& p)
{
    double sum = 0.0;
    for (const Vec3I& t : m.triangles) sum += triangleSolidAngle(m.points[t[0]], m.points[t[1]], m.points[t[2]], p);
    return sum;
}

double productSum(const TriangleMesh& m, const Vec3d& p)
{
    SolidAngleSum s;
    for (const Vec3I& t : m.triangles) s.add(m.points[t[0]].asPointer(), m.points[t[1]].asPointer(), m.points[t[2]].asPointer(), p.asPointer());
    return s.value();
}
} // namespace

TEST(SolidAngleSum, EqualsTheSumOfAtan2sOnASoup)
{
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    TriangleMesh soup;
    for (int t = 0; t < 300; ++t) {
        const Vec3d c(u(rng), u(rng), u(rng));
        for (int k = 0; k < 3; ++k) soup.points.push_back(c + Vec3d(u(rng), u(rng), u(rng)) * 0.4);
        soup.triangles.push_back(Vec3I(3 * t, 3 * t + 1, 3 * t + 2));
    }
    for (int i = 0; i < 2000; ++i) {
        Vec3d p(u(rng), u(rng), u(rng));
        if (i % 4 == 0) {
            // on or a hair off a triangle (on its plane, near its edges and corners)
            const Vec3I& t = soup.triangles[size_t(i) % soup.triangles.size()];
            const double a = std::abs(u(rng)), b = std::abs(u(rng)) * (1.0 - a);
            p = soup.points[t[0]] + (soup.points[t[1]] - soup.points[t[0]]) * a + (soup.points[t[2]] - soup.points[t[0]]) * b;
            if (i % 8 == 0) p += Vec3d(u(rng), u(rng), u(rng)) * 1e-9;
        }
        const double plain = plainSum(soup, p), product = productSum(soup, p);
        ASSERT_NEAR(product, plain, 1e-11) << "point " << i;
    }
}

TEST(SolidAngleSum, KeepsWholeTurnsOfClosedAndNestedSurfaces)
{
    // a closed, outward-oriented sphere: 4π inside (w = 1), 0 outside; three nested copies: 12π
    const TriangleMesh sphere = makeIcosphere(Vec3d(0.0), 1.0, 3);
    TriangleMesh nested = sphere;
    for (int k = 1; k < 3; ++k) {
        const uint32_t base = uint32_t(nested.points.size());
        for (const Vec3d& p : sphere.points) nested.points.push_back(p * (1.0 + 0.5 * k));
        for (const Vec3I& t : sphere.triangles) nested.triangles.push_back(Vec3I(t[0] + base, t[1] + base, t[2] + base));
    }
    TriangleMesh flipped = sphere; // a flipped copy: −4π
    for (Vec3I& t : flipped.triangles) std::swap(t[1], t[2]);
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> u(-0.5, 0.5);
    for (int i = 0; i < 200; ++i) {
        const Vec3d p(u(rng), u(rng), u(rng));
        EXPECT_NEAR(productSum(sphere, p), 4.0 * kPi, 1e-9);
        EXPECT_NEAR(productSum(nested, p), 12.0 * kPi, 1e-9);
        EXPECT_NEAR(productSum(flipped, p), -4.0 * kPi, 1e-9);
        const Vec3d far = p + Vec3d(3.0, 0.0, 0.0);
        EXPECT_NEAR(productSum(sphere, far), 0.0, 1e-9);
        EXPECT_NEAR(productSum(nested, far * 2.0), 0.0, 1e-9);
    }
    // the fast winding number, whose near field now uses the product, against the exact sum:
    // within its rigorous truncation bound, and the batched evaluation too
    const FastWindingNumber fwn(nested);
    std::vector<Vec3d> points;
    for (int i = 0; i < 200; ++i) points.push_back(Vec3d(u(rng), u(rng), u(rng)) * 6.0);
    std::vector<double> many(points.size());
    fwn.evaluate(points.data(), points.size(), many.data());
    for (size_t i = 0; i < points.size(); ++i) {
        const FastWindingNumber::Estimate e = fwn.evaluate(points[i]);
        const double exact = fwn.exact(points[i]);
        EXPECT_NEAR(e.value, exact, e.errorBound + 1e-12) << points[i];
        EXPECT_EQ(e.value, fwn(points[i]));
        EXPECT_NEAR(many[i], exact, e.errorBound + 1e-12) << points[i];
    }
}
