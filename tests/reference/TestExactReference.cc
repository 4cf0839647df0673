// SPDX-License-Identifier: Apache-2.0
// The exact reference itself: BVH against brute force; sign and pseudonormals on simple shapes.
#include "TestUtil.h"

#include <levelforge/reference/ExactReference.h>
#include <levelforge/reference/MeshShapes.h>
#include <levelforge/core/PseudoNormals.h>
#include <levelforge/core/TriangleDistance.h>

#include <random>

using namespace levelforge;

TEST(ExactReference, BvhEqualsBruteForce)
{
    const TriangleMesh knot = makeTorusKnot(2, 3, 1.0, 0.25, 64, 10);
    ExactReference ref(knot);
    std::mt19937_64 rng(7);
    std::uniform_real_distribution<double> u(-2.0, 2.0);
    for (int i = 0; i < 2000; ++i) {
        const Vec3d p(u(rng), u(rng), u(rng) * 0.5);
        const auto a = ref.query(p), b = ref.bruteForce(p);
        ASSERT_DOUBLE_EQ(a.distance, b.distance) << p;
    }
}

TEST(ExactReference, SignInsideOutsideSphere)
{
    const TriangleMesh s = makeIcosphere(Vec3d(0.0), 1.0, 3);
    ExactReference ref(s);
    EXPECT_LT(ref.signedDistance(Vec3d(0.0)), -0.9);
    EXPECT_GT(ref.signedDistance(Vec3d(2.0, 0.0, 0.0)), 0.9);
    EXPECT_NEAR(ref.signedDistance(Vec3d(0.0, 0.0, 3.0)), 2.0, 1e-12); // a vertex sits on the pole
}

TEST(PseudoNormals, BoxFeatures)
{
    const TriangleMesh box = makeBox(Vec3d(0.0), Vec3d(1.0));
    PseudoNormals pn(box);
    for (uint32_t v = 0; v < box.points.size(); ++v) {
        Vec3d n = pn.vertexNormal(v);
        n.normalize();
        const Vec3d expect = (box.points[v] - Vec3d(0.5)) * (2.0 / std::sqrt(3.0));
        EXPECT_NEAR((n - expect).length(), 0.0, 1e-12) << v;
    }
    for (uint32_t t = 0; t < box.triangles.size(); ++t) {
        EXPECT_NEAR(pn.faceNormal(t).length(), 1.0, 1e-12);
        for (int k = 0; k < 3; ++k) {
            const Vec3d& e = pn.edgeNormal(t, k);
            // Every box edge normal points away from the centre.
            const Vec3d mid = (box.points[box.triangles[t][k]] + box.points[box.triangles[t][(k + 1) % 3]]) * 0.5;
            EXPECT_GT(e.dot(mid - Vec3d(0.5)), 0.0);
        }
    }
}

TEST(TriangleDistance, FeaturesAndDistances)
{
    const Vec3d a(0, 0, 0), b(1, 0, 0), c(0, 1, 0);
    auto r = closestPointOnTriangle(Vec3d(0.2, 0.2, 1.0), a, b, c);
    EXPECT_EQ(r.feature, TriangleFeature::Face);
    EXPECT_DOUBLE_EQ(r.distanceSqr, 1.0);
    r = closestPointOnTriangle(Vec3d(-1, -1, 0), a, b, c);
    EXPECT_EQ(r.feature, TriangleFeature::Vertex0);
    EXPECT_DOUBLE_EQ(r.distanceSqr, 2.0);
    r = closestPointOnTriangle(Vec3d(0.5, -2, 0), a, b, c);
    EXPECT_EQ(r.feature, TriangleFeature::Edge01);
    EXPECT_DOUBLE_EQ(r.distanceSqr, 4.0);
    r = closestPointOnTriangle(Vec3d(1, 1, 0), a, b, c);
    EXPECT_EQ(r.feature, TriangleFeature::Edge12);
    EXPECT_NEAR(r.distanceSqr, 0.5, 1e-15);
    r = closestPointOnTriangle(Vec3d(-3, 0.5, 0), a, b, c);
    EXPECT_EQ(r.feature, TriangleFeature::Edge20);
    r = closestPointOnTriangle(Vec3d(2, -0.5, 0), a, b, c);
    EXPECT_EQ(r.feature, TriangleFeature::Vertex1);
    r = closestPointOnTriangle(Vec3d(-0.5, 2, 0), a, b, c);
    EXPECT_EQ(r.feature, TriangleFeature::Vertex2);
}
