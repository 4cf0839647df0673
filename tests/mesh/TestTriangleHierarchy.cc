// SPDX-License-Identifier: Apache-2.0
// The single-precision cluster bounds of the exact band's hierarchy (src/mesh/TriangleHierarchy.h):
// the AVX2 build against the baseline (bit-identical), and both against the exact distance
// (a lower bound within the stated rounding).
#include "TestUtil.h"
#include "mesh/TriangleHierarchy.h"

#include <levelforge/core/TriangleDistance.h>
#include <levelforge/reference/MeshShapes.h>

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <random>

using namespace levelforge;
using namespace levelforge::mesh_internal;

namespace {

struct Fixture
{
    TriangleMesh mesh;
    std::vector<Vec3d> cellPts;
    std::vector<uint32_t> use;
};

/// Random triangles (needles and slivers among them) and an icosphere, in cell space.
Fixture makeFixture()
{
    Fixture f;
    f.mesh = makeRandomTriangles(3000, 7, BBoxd(Vec3d(-40.0), Vec3d(40.0)), 12.0);
    const TriangleMesh sphere = makeIcosphere(Vec3d(3.0, -2.0, 1.0), 25.0, 4);
    const uint32_t base = uint32_t(f.mesh.points.size());
    f.mesh.points.insert(f.mesh.points.end(), sphere.points.begin(), sphere.points.end());
    for (const Vec3I& t : sphere.triangles) f.mesh.triangles.push_back(Vec3I(t[0] + base, t[1] + base, t[2] + base));
    f.cellPts = f.mesh.points;
    for (uint32_t t = 0; t < f.mesh.triangles.size(); ++t) {
        const Vec3I& tri = f.mesh.triangles[t];
        const Vec3d n = (f.cellPts[tri[1]] - f.cellPts[tri[0]]).cross(f.cellPts[tri[2]] - f.cellPts[tri[0]]);
        if (n.length() > 1e-9) f.use.push_back(t);
    }
    return f;
}

} // namespace

TEST(TriangleHierarchy, ClusterBoundsAvx2TwinIsBitIdentical)
{
    LF_SKIP_WITHOUT_AVX2();
    ASSERT_TRUE(clusterBoundsAvx2Available()) << "the CPU has AVX2 but the library does not use its AVX2 build";
    const Fixture f = makeFixture();
    const TriangleHierarchy h(f.mesh, f.cellPts, f.use, nullptr);
    ASSERT_GT(h.clusters().size(), 100u);
    std::mt19937_64 rng(11);
    std::uniform_real_distribution<float> off(-15.0f, 15.0f), radius(0.0f, 30.0f);
    size_t compared = 0, someMask = 0;
    for (const TriangleCluster& c : h.clusters()) {
        for (int k = 0; k < 20; ++k) {
            const float q[3] = {off(rng), off(rng), off(rng)};
            const float r = radius(rng), bm2 = r * r;
            alignas(32) float a[kClusterSize], b[kClusterSize];
            const uint32_t ma = clusterBounds(c, q[0], q[1], q[2], bm2, a);
            const uint32_t mb = clusterBoundsBaseline(c, q[0], q[1], q[2], bm2, b);
            ASSERT_EQ(ma, mb);
            for (uint32_t i = 0; i < kClusterSize; ++i)
                ASSERT_EQ(std::memcmp(&a[i], &b[i], sizeof(float)), 0) << "lane " << i << ": " << a[i] << " vs " << b[i];
            ++compared;
            someMask += ma != 0;
        }
    }
    EXPECT_GT(someMask, compared / 10) << "the queries should reach some triangles";
}

TEST(TriangleHierarchy, ClusterBoundsAreLowerBoundsOfTheExactDistance)
{
    const Fixture f = makeFixture();
    const TriangleHierarchy h(f.mesh, f.cellPts, f.use, nullptr);
    std::mt19937_64 rng(5);
    std::uniform_real_distribution<double> off(-15.0, 15.0);
    size_t checked = 0;
    for (const TriangleCluster& c : h.clusters()) {
        for (int k = 0; k < 10; ++k) {
            const Vec3d q(off(rng), off(rng), off(rng));
            alignas(32) float lb2[kClusterSize];
            const uint32_t mask = clusterBounds(c, float(q[0]), float(q[1]), float(q[2]), 1e30f, lb2);
            for (uint32_t i = 0; i < c.count; ++i) {
                ASSERT_TRUE(mask & (1u << i));
                const Vec3I& t = f.mesh.triangles[c.ids[i]];
                const Vec3d p = c.origin + q;
                const double d2 = closestPointOnTriangle(p, f.cellPts[t[0]], f.cellPts[t[1]], f.cellPts[t[2]]).distanceSqr;
                // single precision relative to the cluster origin: a few ulps of |q| + radius
                const double scale = q.length() + 30.0;
                EXPECT_LE(std::sqrt(double(lb2[i])), std::sqrt(d2) + 1e-5 * scale) << "triangle " << c.ids[i];
                EXPECT_GE(std::sqrt(double(lb2[i])), std::sqrt(d2) - 1e-5 * scale) << "triangle " << c.ids[i];
                ++checked;
            }
        }
    }
    EXPECT_GT(checked, 10000u);
}

// The wide band's per-voxel bounds (src/mesh/MeshToLevelSet.cc, computeLeaf()): at a block
// centre c, clusterBoundsDirections() gives each triangle's single-precision distance d and the
// vector g from its closest point to c; the plane through that point with normal g / d separates
// c from the triangle, so d + (g / d)·(v - c) is a lower bound of the distance at any v, up to
// the rounding allowance tauK (1 + tauR / d) the search subtracts. Checked against the exact
// distance at points around c, on random triangles (needles, slivers, triangles split into
// pieces) and a sphere; the AVX2 build gives the baseline's distances bit for bit.
TEST(TriangleHierarchy, SeparatingPlanesBoundTheExactDistanceAroundTheirCentre)
{
    const Fixture f = makeFixture();
    const TriangleHierarchy h(f.mesh, f.cellPts, f.use, nullptr);
    const double radius = h.maxClusterRadius(), limit = 26.0; // |q| <= 15√3
    const double tauK = 4e-6 * (limit + 2.0 * radius + 4.0), tauR = 2.0 * radius + 2.0;
    std::mt19937_64 rng(17);
    std::uniform_real_distribution<double> off(-15.0, 15.0), step(-1.0, 1.0);
    size_t checked = 0, tight = 0;
    for (const TriangleCluster& c : h.clusters()) {
        for (int k = 0; k < 6; ++k) {
            const Vec3d q(off(rng), off(rng), off(rng));
            alignas(32) float lb2[kClusterSize], base[kClusterSize], g[3][kClusterSize];
            const uint32_t mask = clusterBoundsDirections(c, float(q[0]), float(q[1]), float(q[2]), 3.0e38f, lb2, g[0], g[1], g[2]);
            ASSERT_EQ(mask, clusterBoundsBaseline(c, float(q[0]), float(q[1]), float(q[2]), 3.0e38f, base));
            for (uint32_t i = 0; i < c.count; ++i) {
                ASSERT_TRUE(mask & (1u << i));
                ASSERT_EQ(std::memcmp(&lb2[i], &base[i], sizeof(float)), 0) << "lane " << i;
                const double d = std::sqrt(double(lb2[i]));
                if (!(d > 1e-20)) continue;
                const Vec3d u = Vec3d(g[0][i], g[1][i], g[2][i]) / d;
                EXPECT_NEAR(u.length(), 1.0, 1e-3) << "triangle " << c.ids[i];
                const Vec3I& t = f.mesh.triangles[c.ids[i]];
                for (int j = 0; j < 8; ++j) {
                    const Vec3d delta(step(rng), step(rng), step(rng)); // within √3 of c
                    const Vec3d p = c.origin + q + delta;
                    const double exact = std::sqrt(closestPointOnTriangle(p, f.cellPts[t[0]], f.cellPts[t[1]], f.cellPts[t[2]]).distanceSqr);
                    const double bound = d + u.dot(delta) - tauK * (1.0 + tauR / d);
                    ASSERT_LE(bound, exact) << "triangle " << c.ids[i] << ", d(c) " << d << ", offset " << delta;
                    tight += exact - bound < 0.05;
                    ++checked;
                }
            }
        }
    }
    EXPECT_GT(checked, 100000u);
    EXPECT_GT(tight, checked / 10) << "the bound should be tight where the closest point lies inside the face";
}
