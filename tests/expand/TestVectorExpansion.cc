// SPDX-License-Identifier: Apache-2.0
// Vector expansion (sparse 8-pass VCVDT over VDB leaves, VectorExpansion.h): exact closest-point
// shells from meshToLevelSetWithClosestPoints, accuracy against the exact reference (mean and
// max error, signs, coverage), never underestimating, frozen band, estimated shells, thread-count
// determinism and the CLI.
#include "TestUtil.h"

#include <levelforge/reference/ExactReference.h>
#include <levelforge/expand/ExpandLevelSet.h>
#include <levelforge/io/MeshIO.h>
#include <levelforge/reference/MeshShapes.h>
#include <levelforge/mesh/MeshToLevelSet.h>
#include "expand/VectorExpansion.h"

#include <tbb/global_control.h>

#include <algorithm>
#include <cmath>
#include <iostream>

using namespace levelforge;

namespace {

LevelSetWithClosestPoints shellOf(const TriangleMesh& mesh, int voxelCount, float w = 3.0f)
{
    MeshToLevelSetOptions opt;
    opt.voxelCount = voxelCount;
    opt.exteriorWidth = opt.interiorWidth = w;
    return meshToLevelSetWithClosestPoints(mesh, opt);
}

openvdb::FloatGrid::Ptr expandVector(const LevelSetWithClosestPoints& s, double ext, double in,
                                     bool useClosest = true, ExpandLevelSetStats* st = nullptr,
                                     const TriangleMesh* mesh = nullptr)
{
    ExpandLevelSetOptions opt;
    opt.method = ExpansionMethod::Vector;
    opt.exteriorWidth = ext;
    opt.interiorWidth = in;
    if (useClosest) opt.closestPoints = &s.closestPoints->tree();
    if (useClosest && mesh) {
        opt.closestTriangles = &s.closestTriangles->tree();
        opt.mesh = mesh;
    }
    return expandLevelSet(*s.levelSet, opt, st);
}

} // namespace

TEST(VectorExpansion, ClosestPointsLieOnTheMeshAtTheBandDistance)
{
    const TriangleMesh knot = makeTorusKnot();
    const LevelSetWithClosestPoints s = shellOf(knot, 64);
    ASSERT_TRUE(s.closestPoints);
    EXPECT_EQ(s.closestPoints->activeVoxelCount(), s.levelSet->activeVoxelCount());
    EXPECT_EQ(s.closestPoints->tree().hasSameTopology(s.levelSet->tree()), true);
    // and the plain converter gives the same level set bit for bit
    MeshToLevelSetOptions opt;
    opt.voxelCount = 64;
    auto plain = meshToLevelSet(knot, opt);
    ASSERT_EQ(plain->activeVoxelCount(), s.levelSet->activeVoxelCount());
    auto pAcc = plain->getConstAccessor();
    ExactReference ref(knot);
    const double h = s.levelSet->voxelSize()[0];
    auto cAcc = s.closestPoints->getConstAccessor();
    uint64_t n = 0;
    for (auto it = s.levelSet->cbeginValueOn(); it; ++it) {
        const openvdb::Coord c = it.getCoord();
        ASSERT_EQ(pAcc.getValue(c), *it);
        const openvdb::Vec3f v = cAcc.getValue(c);
        EXPECT_NEAR(v.length() * h, std::abs(*it), 1e-5 * h) << c;
        if ((++n % 7) == 0) { // the point is on the surface
            const Vec3d p = s.levelSet->indexToWorld(c) + Vec3d(v) * h;
            EXPECT_LT(std::abs(ref.query(p).distance), 1e-5 * h) << c;
        }
    }
}

TEST(VectorExpansion, MeshesMatchTheExactReferenceToAHundredthOfAVoxel)
{
    const TriangleMesh sphere = makeIcosphere(Vec3d(0.0), 1.0, 5);
    const TriangleMesh knot = makeTorusKnot();
    const TriangleMesh box = makeBox(Vec3d(-0.93, -0.51, -0.37), Vec3d(0.71, 0.49, 0.83), 2);
    struct Case { const TriangleMesh* mesh; int res; double ext, in; };
    for (const Case& c : {Case{&sphere, 64, 20, 20}, Case{&knot, 80, 12, 6}, Case{&box, 60, 20, 10}}) {
        const LevelSetWithClosestPoints s = shellOf(*c.mesh, c.res);
        ExpandLevelSetStats st;
        auto out = expandVector(s, c.ext, c.in, true, &st, c.mesh);
        ExactReference ref(*c.mesh);
        const BandErrorReport r = compareToReference(*out, ref, c.ext, c.in);
        std::cout << "[ vector " << c.res << ", 3->" << c.ext << "/" << c.in << " ] mean "
                  << r.meanError << " max " << r.maxError << " of " << r.checkedVoxels
                  << " extra " << r.extraVoxels << " unreached " << st.unreachedVoxels << "\n";
        EXPECT_EQ(r.signErrors, 0u);
        EXPECT_EQ(r.missingVoxels, 0u);
        EXPECT_LE(r.meanError, 0.01);
        EXPECT_LE(r.maxError, 0.1);
        EXPECT_EQ(st.estimatedVectors, 0u);
        EXPECT_EQ(st.refinedVoxels + st.frozenVoxels, st.candidateVoxels - st.unreachedVoxels);
        // never below the exact distance: every value is the distance to a surface point
        const double h = out->voxelSize()[0];
        uint64_t n = 0;
        for (auto it = out->cbeginValueOn(); it; ++it) {
            if ((++n % 11) != 0) continue;
            const double d = ref.query(out->indexToWorld(it.getCoord())).distance;
            ASSERT_GE(std::abs(*it) / h, std::abs(d) / h - 1e-4) << it.getCoord();
        }
    }
}

TEST(VectorExpansion, ClosestPointsAloneStayWithinTheDiscreteFootPointBound)
{
    // Without the triangles, a new value is |x - p| for the foot point p of some shell voxel:
    // never below the exact distance, and above it by at most about s²/(2d) for foot points
    // spaced s apart — small, but not a hundredth of a voxel on curved surfaces.
    const TriangleMesh sphere = makeIcosphere(Vec3d(0.0), 1.0, 5);
    const LevelSetWithClosestPoints s = shellOf(sphere, 64);
    ExpandLevelSetStats st;
    auto out = expandVector(s, 20, 20, true, &st);
    EXPECT_EQ(st.refinedVoxels, 0u);
    ExactReference ref(sphere);
    const BandErrorReport r = compareToReference(*out, ref, 20, 20);
    std::cout << "[ vector, points only, sphere 64 3->20 ] mean " << r.meanError << " max "
              << r.maxError << "\n";
    EXPECT_EQ(r.signErrors, 0u);
    EXPECT_EQ(r.missingVoxels, 0u);
    EXPECT_LT(r.meanError, 0.03);
    EXPECT_LT(r.maxError, 0.4);
}

TEST(VectorExpansion, FrozenBandIsKeptBitForBit)
{
    const LevelSetWithClosestPoints s = shellOf(makeTorusKnot(), 80);
    auto out = expandVector(s, 8, 4);
    auto acc = out->getConstAccessor();
    for (auto it = s.levelSet->cbeginValueOn(); it; ++it) {
        ASSERT_TRUE(acc.isValueOn(it.getCoord()));
        ASSERT_EQ(acc.getValue(it.getCoord()), *it);
    }
    EXPECT_EQ(out->getGridClass(), openvdb::GRID_LEVEL_SET);
}

TEST(VectorExpansion, EstimatedShellVectorsStillGiveAccurateDistances)
{
    // no closest points: the shell vectors come from φ and ∇φ (first-order near edges)
    const TriangleMesh sphere = makeIcosphere(Vec3d(0.0), 1.0, 5);
    const LevelSetWithClosestPoints s = shellOf(sphere, 64);
    ExpandLevelSetStats st;
    auto out = expandVector(s, 15, 15, false, &st);
    EXPECT_EQ(st.estimatedVectors, s.levelSet->activeVoxelCount());
    ExactReference ref(sphere);
    const BandErrorReport r = compareToReference(*out, ref, 15, 15);
    std::cout << "[ vector, estimated shell, sphere 64 3->15 ] mean " << r.meanError << " max "
              << r.maxError << "\n";
    EXPECT_EQ(r.signErrors, 0u);
    EXPECT_EQ(r.missingVoxels, 0u);
    EXPECT_LT(r.meanError, 0.05);
    EXPECT_LT(r.maxError, 0.5);
}

TEST(VectorExpansion, RealMeshFromSharedData)
{
    LEVELFORGE_SHARED_FILE_OR_SKIP(path, "meshes/watertight/fandisk.obj");
    const TriangleMesh mesh = readMesh(path);
    const LevelSetWithClosestPoints s = shellOf(mesh, 96);
    auto out = expandVector(s, 20, 20, true, nullptr, &mesh);
    ExactReference ref(mesh);
    const BandErrorReport r = compareToReference(*out, ref, 20, 20);
    std::cout << "[ vector, fandisk 96 3->20 ] mean " << r.meanError << " max " << r.maxError << "\n";
    EXPECT_EQ(r.signErrors, 0u);
    EXPECT_EQ(r.missingVoxels, 0u);
    EXPECT_LE(r.meanError, 0.01);
    EXPECT_LE(r.maxError, 0.1);
}

TEST(VectorExpansion, IdenticalForAnyThreadCount)
{
    const TriangleMesh knot = makeTorusKnot();
    const LevelSetWithClosestPoints s = shellOf(knot, 64);
    openvdb::FloatGrid::Ptr a, b;
    {
        tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
        a = expandVector(s, 10, 10, true, nullptr, &knot);
    }
    b = expandVector(s, 10, 10, true, nullptr, &knot);
    ASSERT_EQ(a->activeVoxelCount(), b->activeVoxelCount());
    auto acc = b->getConstAccessor();
    for (auto it = a->cbeginValueOn(); it; ++it) ASSERT_EQ(acc.getValue(it.getCoord()), *it);
}


TEST(VectorExpansion, MeshAdjacencyMatchesSortedEdgeSlotsWithHubsAndNonManifoldEdges)
{
    // The walk's adjacency against its definition: all edge slots sorted by (undirected edge,
    // slot); each slot of an edge with two or more slots names the next slot's triangle (the
    // last the first's), a lone slot -1. The mesh mixes a closed sphere, a fan of 300 triangles
    // around one vertex (fan scans), a non-manifold edge between two hubs shared by 200
    // triangles (the sorted fallback), triangles that name a vertex twice and a duplicate.
    TriangleMesh mesh = makeIcosphere(Vec3d(0.0), 1.0, 2);
    const uint32_t base = uint32_t(mesh.points.size());
    for (int i = 0; i < 402; ++i) mesh.points.emplace_back(3.0 + 0.01 * i, 0.1 * (i % 7), 0.2);
    const uint32_t hubA = base, hubB = base + 1;
    for (uint32_t i = 0; i < 300; ++i) mesh.triangles.emplace_back(hubA, base + 2 + i, base + 2 + (i + 1) % 300);
    for (uint32_t i = 0; i < 200; ++i) mesh.triangles.emplace_back(hubA, hubB, base + 2 + (i * 7) % 400);
    mesh.triangles.emplace_back(hubA, hubA, hubB);
    mesh.triangles.emplace_back(base + 5, base + 6, base + 5);
    mesh.triangles.push_back(mesh.triangles[3]);
    std::vector<uint32_t> fanBegin;
    std::vector<int32_t> fan, edge;
    vector_expansion_internal::meshAdjacency(mesh, fanBegin, fan, edge);
    const size_t nt = mesh.triangles.size();
    ASSERT_EQ(edge.size(), 3 * nt);
    std::vector<std::pair<uint64_t, uint32_t>> slots;
    for (size_t t = 0; t < nt; ++t)
        for (int e = 0; e < 3; ++e) {
            const uint64_t a = mesh.triangles[t][e], b = mesh.triangles[t][(e + 1) % 3];
            slots.emplace_back((std::min(a, b) << 32) | std::max(a, b), uint32_t(3 * t + size_t(e)));
        }
    std::sort(slots.begin(), slots.end());
    size_t linked = 0, ringsOfMany = 0;
    for (size_t i = 0; i < slots.size();) {
        size_t j = i;
        while (j < slots.size() && slots[j].first == slots[i].first) ++j;
        for (size_t k = i; k < j; ++k) {
            const int32_t want = j - i >= 2 ? int32_t(slots[k + 1 < j ? k + 1 : i].second / 3) : -1;
            EXPECT_EQ(edge[slots[k].second], want) << "slot " << slots[k].second;
            linked += want >= 0 ? 1 : 0;
        }
        ringsOfMany += j - i > 2 ? 1 : 0;
        i = j;
    }
    EXPECT_GT(linked, 3 * 320u);
    EXPECT_GE(ringsOfMany, 2u); // the hub edge and the duplicated triangle's edges
    // the fans: every corner listed once, triangles in increasing order
    ASSERT_EQ(fanBegin.size(), mesh.points.size() + 1);
    EXPECT_EQ(fan.size(), 3 * nt);
    for (size_t v = 0; v < mesh.points.size(); ++v)
        for (uint32_t q = fanBegin[v] + 1; q < fanBegin[v + 1]; ++q) EXPECT_LE(fan[q - 1], fan[q]);
    EXPECT_EQ(fanBegin[hubA + 1] - fanBegin[hubA], 300u + 200u + 2u);
}
