// SPDX-License-Identifier: Apache-2.0
// Tests for MeshShapes.h: every shape is closed, outward (positive signed volume), has the
// expected topology, and matches the analytic volume and area; the torus knot does not touch
// itself; random soups are deterministic and respect their bounds.
#include "TestUtil.h"

#include <levelforge/core/Exceptions.h>
#include <levelforge/reference/MeshShapes.h>
#include <levelforge/core/MeshValidation.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>

namespace {

using namespace levelforge;
constexpr double kPi = 3.14159265358979323846;

/// Checks the properties every closed shape guarantees.
void expectWellFormedClosed(const TriangleMesh& m, int64_t euler, uint64_t components = 1)
{
    const MeshReport r = validateMesh(m);
    EXPECT_TRUE(r.closed()) << r.summary();
    EXPECT_EQ(r.degenerateTriangles, 0u) << r.summary();
    EXPECT_EQ(r.unusedVertices, 0u) << r.summary();
    EXPECT_EQ(r.nonManifoldVertices, 0u) << r.summary();
    EXPECT_EQ(r.components, components);
    EXPECT_EQ(r.eulerCharacteristic(), euler);
    EXPECT_GT(signedVolume(m), 0.0) << "inward oriented";
    EXPECT_FALSE(m.source.empty());
    EXPECT_EQ(m.source.front(), '<');
}

/// Centre-line length of the torus knot by fine polyline sampling.
double knotLength(int p, int q, double radius)
{
    const int n = 200000;
    double length = 0;
    Vec3d prev = torusKnotPoint(p, q, radius, 0.0);
    for (int i = 1; i <= n; ++i) {
        const Vec3d c = torusKnotPoint(p, q, radius, 2.0 * kPi * i / n);
        length += (c - prev).length();
        prev = c;
    }
    return length;
}

TriangleMesh flipped(TriangleMesh m)
{
    for (Vec3I& t : m.triangles) std::swap(t[1], t[2]);
    return m;
}

} // namespace

TEST(MeshShapes, IcosphereCountsRadiusAndMeasures)
{
    const Vec3d c(1.0, -2.0, 0.5);
    const double r = 1.5;
    double previousVolumeError = 1.0;
    for (int s = 0; s <= 5; ++s) {
        SCOPED_TRACE(s);
        const TriangleMesh m = makeIcosphere(c, r, s);
        EXPECT_EQ(m.points.size(), size_t(10) * (size_t(1) << (2 * s)) + 2);
        EXPECT_EQ(m.triangles.size(), size_t(20) * (size_t(1) << (2 * s)));
        expectWellFormedClosed(m, 2);
        for (const Vec3d& p : m.points) EXPECT_NEAR((p - c).length(), r, 1e-12);
        const double volumeError = 1.0 - signedVolume(m) / (4.0 / 3.0 * kPi * r * r * r);
        const double areaError = 1.0 - surfaceArea(m) / (4.0 * kPi * r * r);
        EXPECT_GT(volumeError, 0.0); // inscribed
        EXPECT_GT(areaError, 0.0);
        EXPECT_LT(volumeError, previousVolumeError); // converges
        previousVolumeError = volumeError;
        if (s >= 4) {
            EXPECT_LT(volumeError, 0.005);
            EXPECT_LT(areaError, 0.005);
        }
    }
    EXPECT_EQ(makeIcosphere(Vec3d(0.0), 1.0, 3).source, "<icosphere c=(0,0,0) r=1 s=3>");
    EXPECT_THROW(makeIcosphere(Vec3d(0.0), 0.0, 2), InvalidArgumentError);
    EXPECT_THROW(makeIcosphere(Vec3d(0.0), -1.0, 2), InvalidArgumentError);
    EXPECT_THROW(makeIcosphere(Vec3d(0.0), 1.0, -1), InvalidArgumentError);
    EXPECT_THROW(makeIcosphere(Vec3d(0.0), 1.0, 11), InvalidArgumentError);
    EXPECT_THROW(makeIcosphere(Vec3d(std::nan(""), 0, 0), 1.0, 1), InvalidArgumentError);
}

TEST(MeshShapes, BoxIsExact)
{
    const Vec3d lo(-1.0, 0.0, 2.0), hi(2.0, 0.5, 4.0);
    for (int seg : {1, 2, 5}) {
        SCOPED_TRACE(seg);
        const TriangleMesh m = makeBox(lo, hi, seg);
        EXPECT_EQ(m.triangles.size(), size_t(12 * seg * seg));
        EXPECT_EQ(m.points.size(), size_t(6 * seg * seg + 2));
        expectWellFormedClosed(m, 2);
        EXPECT_NEAR(signedVolume(m), 3.0 * 0.5 * 2.0, 1e-12);
        EXPECT_NEAR(surfaceArea(m), 2.0 * (3.0 * 0.5 + 0.5 * 2.0 + 2.0 * 3.0), 1e-12);
        const BBoxd b = m.bounds();
        EXPECT_EQ(b.min(), lo);
        EXPECT_EQ(b.max(), hi);
    }
    EXPECT_EQ(makeBox(Vec3d(0.0), Vec3d(1.0)).triangles.size(), 12u);
    EXPECT_THROW(makeBox(Vec3d(0.0), Vec3d(1.0, 0.0, 1.0)), InvalidArgumentError);
    EXPECT_THROW(makeBox(Vec3d(1.0), Vec3d(0.0)), InvalidArgumentError);
    EXPECT_THROW(makeBox(Vec3d(0.0), Vec3d(1.0), 0), InvalidArgumentError);
}

TEST(MeshShapes, TorusTopologyAndMeasures)
{
    const double R = 2.0, r = 0.5;
    const TriangleMesh m = makeTorus(Vec3d(0.0, 0.0, 1.0), R, r, 128, 48);
    EXPECT_EQ(m.points.size(), 128u * 48u);
    EXPECT_EQ(m.triangles.size(), 2u * 128u * 48u);
    expectWellFormedClosed(m, 0);
    EXPECT_NEAR(signedVolume(m) / (2.0 * kPi * kPi * R * r * r), 1.0, 0.005);
    EXPECT_NEAR(surfaceArea(m) / (4.0 * kPi * kPi * R * r), 1.0, 0.005);
    EXPECT_THROW(makeTorus(Vec3d(0.0), 1.0, 1.0, 16, 8), InvalidArgumentError);
    EXPECT_THROW(makeTorus(Vec3d(0.0), 1.0, 0.0, 16, 8), InvalidArgumentError);
    EXPECT_THROW(makeTorus(Vec3d(0.0), 1.0, 0.5, 2, 8), InvalidArgumentError);
}

TEST(MeshShapes, TorusKnotIsAClosedTubeWithoutSelfContact)
{
    const TriangleMesh m = makeTorusKnot();
    const int segments = 256, tubeSegments = 24;
    const double radius = 1.0, tube = 0.25;
    ASSERT_EQ(m.points.size(), size_t(segments * tubeSegments));
    EXPECT_EQ(m.triangles.size(), size_t(2 * segments * tubeSegments));
    expectWellFormedClosed(m, 0);
    EXPECT_EQ(m.source, "<torus knot p=2 q=3 r=1 tube=0.25 segments=256x24>");

    // Tube formulas (Pappus / Weyl), discretisation costs < 2 %.
    const double L = knotLength(2, 3, radius);
    EXPECT_NEAR(signedVolume(m) / (kPi * tube * tube * L), 1.0, 0.02);
    EXPECT_NEAR(surfaceArea(m) / (2.0 * kPi * tube * L), 1.0, 0.02);

    // Layout: ring i is centred on the centre line at t_i and has radius `tube`.
    for (int i = 0; i < segments; ++i) {
        const Vec3d c = torusKnotPoint(2, 3, radius, 2.0 * kPi * i / segments);
        Vec3d centroid(0.0);
        for (int j = 0; j < tubeSegments; ++j) centroid += m.points[size_t(i * tubeSegments + j)];
        centroid /= double(tubeSegments);
        EXPECT_NEAR((centroid - c).length(), 0.0, 1e-12) << "ring " << i;
        for (int j = 0; j < tubeSegments; ++j) {
            EXPECT_NEAR((m.points[size_t(i * tubeSegments + j)] - c).length(), tube, 1e-12);
        }
    }
    // No self-contact: no vertex comes closer to any part of the centre line than the tube
    // radius (the nearest centre-line point of every vertex is its own ring centre).
    const int samples = 4096;
    std::vector<Vec3d> line(samples);
    for (int k = 0; k < samples; ++k) line[k] = torusKnotPoint(2, 3, radius, 2.0 * kPi * k / samples);
    double closest = 1e30;
    for (const Vec3d& p : m.points) {
        for (const Vec3d& c : line) closest = std::min(closest, (p - c).lengthSqr());
    }
    EXPECT_GT(std::sqrt(closest), tube * (1.0 - 1e-3));
    // ... and strands far apart along the curve stay apart by more than two tube radii.
    double strands = 1e30;
    for (int a = 0; a < samples; a += 4) {
        for (int b = a + samples / 8; b < a + samples - samples / 8 && b < samples; b += 4) {
            strands = std::min(strands, (line[a] - line[b]).length());
        }
    }
    EXPECT_GT(strands, 2.0 * tube * 1.5);
}

TEST(MeshShapes, OtherTorusKnots)
{
    for (auto [p, q] : {std::pair<int, int>{3, 2}, {2, 5}, {3, 4}, {1, 1}}) {
        SCOPED_TRACE(std::to_string(p) + "," + std::to_string(q));
        const TriangleMesh m = makeTorusKnot(p, q, 2.0, 0.2, 300, 16);
        expectWellFormedClosed(m, 0);
    }
    EXPECT_THROW(makeTorusKnot(2, 4), InvalidArgumentError); // a link, not a knot
    EXPECT_THROW(makeTorusKnot(0, 3), InvalidArgumentError);
    EXPECT_THROW(makeTorusKnot(2, 3, 1.0, 0.0), InvalidArgumentError);
    EXPECT_THROW(makeTorusKnot(2, 3, 1.0, 0.25, 2, 24), InvalidArgumentError);
}

TEST(MeshShapes, SignedVolumeDetectsInwardOrientation)
{
    const TriangleMesh s = makeIcosphere(Vec3d(3.0), 1.0, 3);
    EXPECT_NEAR(signedVolume(flipped(s)), -signedVolume(s), 1e-12);
    EXPECT_TRUE(validateMesh(flipped(s)).closed()); // consistently inward is still consistent
    EXPECT_DOUBLE_EQ(surfaceArea(flipped(s)), surfaceArea(s));
}

TEST(MeshShapes, RandomTrianglesAreDeterministicAndBounded)
{
    const BBoxd box(Vec3d(-1.0, 0.0, 10.0), Vec3d(1.0, 0.5, 12.0));
    const double maxEdge = 0.3;
    const TriangleMesh a = makeRandomTriangles(5000, 42, box, maxEdge);
    const TriangleMesh b = makeRandomTriangles(5000, 42, box, maxEdge);
    const TriangleMesh c = makeRandomTriangles(5000, 43, box, maxEdge);
    EXPECT_EQ(a.points, b.points);
    EXPECT_EQ(a.triangles, b.triangles);
    EXPECT_NE(a.points, c.points);
    ASSERT_EQ(a.triangles.size(), 5000u);
    ASSERT_EQ(a.points.size(), 15000u);
    double longest = 0;
    for (const Vec3d& p : a.points) {
        for (int k = 0; k < 3; ++k) {
            EXPECT_GE(p[k], box.min()[k]);
            EXPECT_LE(p[k], box.max()[k]);
        }
    }
    for (const Vec3I& t : a.triangles) {
        for (int k = 0; k < 3; ++k) longest = std::max(longest, (a.points[t[k]] - a.points[t[(k + 1) % 3]]).length());
    }
    EXPECT_LE(longest, maxEdge);
    EXPECT_GT(longest, 0.5 * maxEdge); // and they do use the allowance
    const MeshReport r = validateMesh(a);
    EXPECT_EQ(r.degenerateTriangles, 0u);
    EXPECT_EQ(r.components, 5000u);
    EXPECT_NE(a.source.find("seed=42"), std::string::npos) << a.source;
    // A box smaller than maxEdge: still inside the box.
    const TriangleMesh tight = makeRandomTriangles(100, 1, BBoxd(Vec3d(0.0), Vec3d(0.01)), 1.0);
    for (const Vec3d& p : tight.points) EXPECT_LE(p[0], 0.01);
    EXPECT_TRUE(makeRandomTriangles(0, 1, box, 0.1).triangles.empty());
    EXPECT_THROW(makeRandomTriangles(10, 1, box, 0.0), InvalidArgumentError);
    EXPECT_THROW(makeRandomTriangles(10, 1, BBoxd(), 0.1), InvalidArgumentError);
}
