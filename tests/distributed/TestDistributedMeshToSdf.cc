// SPDX-License-Identifier: Apache-2.0
// The brick decomposition in one process: K "ranks" converted one after the other with
// meshToSdfBricks(), merged with finishBrickUnion(), must equal meshToSdf() bit for bit (values,
// active states, tiles, metadata), whatever K and the brick size. Also the decomposition's
// invariants, the byte form of a part, the restriction of meshToLevelSet() and the refusals.
#include "TestUtil.h"
#include "distributed/GridIdentity.h"

#include <levelforge/core/Exceptions.h>
#include <levelforge/distributed/DistributedMeshToSdf.h>
#include <levelforge/io/MeshIO.h>
#include <levelforge/mesh/MeshToLevelSet.h>
#include <levelforge/pipeline/MeshToSdf.h>
#include <levelforge/reference/MeshShapes.h>

#include <gtest/gtest.h>

#include <filesystem>
#include <set>

using namespace levelforge;
using levelforge_test::gridDifference;

namespace {

/// Converts in @p ranks parts (each a fresh copy of the options) and merges them.
openvdb::FloatGrid::Ptr inBricks(const TriangleMesh& mesh, const MeshToSdfOptions& o, int ranks, int brickLog2,
                                 std::vector<uint64_t>* trianglesPerRank = nullptr)
{
    const double h = resolveVoxelSize(mesh, o);
    const double limit = std::max(o.widthInVoxels(o.exteriorWidth, h), o.widthInVoxels(o.interiorWidth, h));
    const BrickDecomposition d = decomposeIntoBricks(mesh, h, limit, ranks, brickLog2);
    std::vector<openvdb::FloatGrid::Ptr> parts;
    for (int r = 0; r < ranks; ++r) {
        MeshToSdfStats s;
        parts.push_back(meshToSdfBricks(mesh, o, d.boxesOf(r), &s));
        if (trianglesPerRank) trianglesPerRank->push_back(s.band.triangles);
    }
    return finishBrickUnion(mesh, o, parts);
}

MeshToSdfOptions knotOptions()
{
    MeshToSdfOptions o;
    o.voxelCount = 96;
    return o;
}

} // namespace

TEST(DistributedMeshToSdf, BricksEqualSingleProcessBitForBit)
{
    const TriangleMesh knot = makeTorusKnot();
    const MeshToSdfOptions o = knotOptions();
    const openvdb::FloatGrid::Ptr single = meshToSdf(knot, o);
    ASSERT_GT(single->activeVoxelCount(), 10000u);
    for (int brickLog2 : {3, 4, 5, 7})
        for (int ranks = 1; ranks <= 4; ++ranks) {
            const openvdb::FloatGrid::Ptr merged = inBricks(knot, o, ranks, brickLog2);
            EXPECT_EQ(gridDifference(*single, *merged), "") << ranks << " ranks, bricks of 2^" << brickLog2;
        }
}

TEST(DistributedMeshToSdf, UnequalWidthsUnsignedAndFilledEqualSingleProcess)
{
    const TriangleMesh knot = makeTorusKnot();
    MeshToSdfOptions o = knotOptions();
    o.exteriorWidth = 5.0;
    o.interiorWidth = 2.0;
    EXPECT_EQ(gridDifference(*meshToSdf(knot, o), *inBricks(knot, o, 3, 4)), "") << "5 / 2 voxels";
    MeshToSdfOptions f = knotOptions();
    f.fillInterior = true;
    const openvdb::FloatGrid::Ptr filled = meshToSdf(knot, f);
    ASSERT_GT(filled->activeVoxelCount(), meshToSdf(knot, knotOptions())->activeVoxelCount());
    EXPECT_EQ(gridDifference(*filled, *inBricks(knot, f, 4, 3)), "") << "fill interior";
    // an open mesh, unsigned, and signed by pseudonormals on request
    TriangleMesh open = makeBox(Vec3d(-1.0), Vec3d(1.0), 4);
    open.triangles.resize(open.triangles.size() - 2);
    MeshToSdfOptions u;
    u.voxelCount = 64;
    u.sign = SignMode::Unsigned;
    EXPECT_EQ(gridDifference(*meshToSdf(open, u), *inBricks(open, u, 3, 4)), "") << "unsigned";
    u.sign = SignMode::Pseudonormal;
    EXPECT_EQ(gridDifference(*meshToSdf(open, u), *inBricks(open, u, 2, 3)), "") << "pseudonormal, open mesh";
}

TEST(DistributedMeshToSdf, RanksKeepOnlyTheTrianglesNearTheirBricks)
{
    const TriangleMesh knot = makeTorusKnot();
    std::vector<uint64_t> kept;
    MeshToSdfOptions o = knotOptions();
    o.voxelCount = 200;
    inBricks(knot, o, 4, 7, &kept);
    ASSERT_EQ(kept.size(), 4u);
    uint64_t sum = 0;
    for (uint64_t k : kept) {
        EXPECT_GT(k, 0u);
        EXPECT_LT(k, knot.triangles.size()) << "a rank of 4 holds every triangle in its hierarchy";
        sum += k;
    }
    // the halos overlap a little; far less than 4 whole meshes
    EXPECT_LT(sum, 2 * knot.triangles.size());
}

TEST(DistributedMeshToSdf, DecompositionCoversEveryBrickOnceAndBalances)
{
    const TriangleMesh knot = makeTorusKnot();
    const double h = resolveVoxelSize(knot, knotOptions());
    for (int ranks : {1, 2, 3, 7}) {
        const BrickDecomposition d = decomposeIntoBricks(knot, h, 3.0, ranks, 4);
        ASSERT_EQ(d.origins.size(), d.owner.size());
        ASSERT_GT(d.origins.size(), size_t(ranks));
        std::set<openvdb::Coord> seen(d.origins.begin(), d.origins.end());
        EXPECT_EQ(seen.size(), d.origins.size()) << "a brick listed twice";
        double total = 0.0, heaviest = 0.0;
        for (size_t i = 0; i < d.origins.size(); ++i) {
            EXPECT_EQ(d.origins[i].x() % 16, 0);
            EXPECT_EQ(d.origins[i].z() % 16, 0);
            if (i) EXPECT_LE(d.owner[i - 1], d.owner[i]) << "owners run in Morton order";
            total += d.weights[i];
            heaviest = std::max(heaviest, d.weights[i]);
        }
        double sumLoads = 0.0;
        for (int r = 0; r < ranks; ++r) {
            const double load = d.loadOf(r);
            sumLoads += load;
            // each share is within one brick of the even share
            EXPECT_LE(std::abs(load - total / ranks), heaviest + 1e-6 * total) << ranks << " ranks, rank " << r;
            size_t boxes = d.boxesOf(r).size();
            EXPECT_GT(boxes, 0u);
        }
        EXPECT_NEAR(sumLoads, total, 1e-6 * total);
        // the estimate: about the band's volume (2 x 3 voxels x area, plus a voxel per triangle)
        const double area = surfaceArea(knot) / (h * h);
        EXPECT_GT(total, 6.0 * area);
        EXPECT_LT(total, 6.0 * area + 1.01 * double(knot.triangles.size()));
    }
    EXPECT_THROW(decomposeIntoBricks(knot, h, 3.0, 0, 7), InvalidArgumentError);
    EXPECT_THROW(decomposeIntoBricks(knot, h, 3.0, 2, 13), InvalidArgumentError);
}

TEST(DistributedMeshToSdf, UnevenLoadsAndEmptyRanks)
{
    // a sphere in one brick: one rank gets it, the others nothing, the union is still exact
    const TriangleMesh ball = makeIcosphere(Vec3d(0.5, 0.5, 0.5), 0.3, 3);
    MeshToSdfOptions o;
    o.voxelSize = 0.01; // voxels 20..80: inside the brick [0, 127]
    const BrickDecomposition d = decomposeIntoBricks(ball, 0.01, 3.0, 3, 7);
    ASSERT_EQ(d.origins.size(), 1u);
    EXPECT_EQ(d.boxesOf(0).size() + d.boxesOf(1).size() + d.boxesOf(2).size(), 1u) << "one rank has it, two none";
    const openvdb::FloatGrid::Ptr single = meshToSdf(ball, o);
    EXPECT_EQ(gridDifference(*single, *inBricks(ball, o, 3, 7)), "");
    // two spheres of very different size: the big one's bricks carry most of the work
    TriangleMesh two = makeIcosphere(Vec3d(0.0), 1.0, 4);
    const TriangleMesh small = makeIcosphere(Vec3d(3.0, 0.0, 0.0), 0.1, 2);
    const uint32_t base = uint32_t(two.points.size());
    two.points.insert(two.points.end(), small.points.begin(), small.points.end());
    for (const Vec3I& t : small.triangles) two.triangles.push_back(Vec3I(t[0] + base, t[1] + base, t[2] + base));
    MeshToSdfOptions t;
    t.voxelCount = 160;
    EXPECT_EQ(gridDifference(*meshToSdf(two, t), *inBricks(two, t, 4, 5)), "") << "two spheres, 4 ranks";
}

TEST(DistributedMeshToSdf, SharedDataMeshEqualsSingleProcess)
{
    const std::string dir = levelforge_test::sharedDataDir();
    const std::string path = dir + "/meshes/watertight/cow.obj";
    if (dir.empty() || !std::filesystem::exists(path)) LF_SHARED_DATA_MISSING("no " << path);
    const TriangleMesh cow = readMesh(path);
    MeshToSdfOptions o;
    o.voxelCount = 128;
    o.sign = SignMode::Pseudonormal;
    EXPECT_EQ(gridDifference(*meshToSdf(cow, o), *inBricks(cow, o, 3, 5)), "");
}

TEST(DistributedMeshToSdf, RefusesWhatIsNotDistributedYet)
{
    const TriangleMesh knot = makeTorusKnot();
    auto refused = [&](MeshToSdfOptions o, const std::string& what) {
        try {
            checkDistributable(knot, o);
            ADD_FAILURE() << what << " was accepted";
        } catch (const InvalidArgumentError& e) {
            EXPECT_NE(std::string(e.what()).find("not yet"), std::string::npos) << e.what();
            EXPECT_NE(std::string(e.what()).find(what), std::string::npos) << e.what();
        }
    };
    MeshToSdfOptions o = knotOptions();
    o.method = BandMethod::Scan;
    refused(o, "--method scan");
    o = knotOptions();
    o.expansion = Expansion::Sweep;
    refused(o, "--expansion sweep");
    o = knotOptions();
    o.sign = SignMode::Winding;
    refused(o, "winding");
    o = knotOptions();
    o.fogGridName = "fog";
    refused(o, "--fog-grid");
    // auto on an open mesh is the winding number: refused, saying why
    TriangleMesh open = makeBox(Vec3d(-1.0), Vec3d(1.0), 2);
    open.triangles.pop_back();
    MeshToSdfOptions a;
    a.voxelCount = 32;
    EXPECT_THROW(checkDistributable(open, a), InvalidArgumentError);
    EXPECT_EQ(checkDistributable(knot, knotOptions()), SignMode::Pseudonormal);
    MeshToSdfOptions uf = knotOptions();
    uf.sign = SignMode::Unsigned;
    uf.fillInterior = true;
    EXPECT_THROW(checkDistributable(knot, uf), InvalidArgumentError);
}

TEST(DistributedMeshToSdf, RestrictionOfTheMainRoad)
{
    const TriangleMesh knot = makeTorusKnot();
    MeshToLevelSetOptions o;
    o.voxelCount = 64;
    const openvdb::FloatGrid::Ptr whole = meshToLevelSet(knot, o);
    // no bricks: no leaves, no error
    const std::vector<openvdb::CoordBBox> none;
    o.onlyLeavesIn = &none;
    MeshToLevelSetStats s;
    const openvdb::FloatGrid::Ptr empty = meshToLevelSet(knot, o, &s);
    EXPECT_EQ(empty->tree().leafCount(), 0u);
    EXPECT_EQ(s.triangles, 0u);
    EXPECT_EQ(empty->background(), whole->background());
    // one octant: exactly the whole run's leaves there, value for value
    const std::vector<openvdb::CoordBBox> octant{openvdb::CoordBBox(openvdb::Coord(0), openvdb::Coord(4095))};
    o.onlyLeavesIn = &octant;
    const openvdb::FloatGrid::Ptr part = meshToLevelSet(knot, o, &s);
    EXPECT_LT(s.triangles, knot.triangles.size());
    size_t inOctant = 0;
    for (auto it = whole->tree().cbeginLeaf(); it; ++it) {
        if (!octant[0].isInside(it->origin())) {
            EXPECT_FALSE(part->tree().probeConstLeaf(it->origin()));
            continue;
        }
        ++inOctant;
        const auto* p = part->tree().probeConstLeaf(it->origin());
        ASSERT_TRUE(p) << it->origin();
        EXPECT_EQ(p->getValueMask(), it->getValueMask());
        for (auto v = it->cbeginValueOn(); v; ++v) EXPECT_EQ(p->getValue(v.pos()), *v);
    }
    EXPECT_GT(inOctant, 0u);
    EXPECT_EQ(part->tree().leafCount(), inOctant);
    // the winding number and the fill are passes over the whole tree
    o.sign = SignMode::Winding;
    EXPECT_THROW(meshToLevelSet(knot, o), InvalidArgumentError);
    o.sign = SignMode::Pseudonormal;
    o.fillInterior = true;
    EXPECT_THROW(meshToLevelSet(knot, o), InvalidArgumentError);
}

TEST(DistributedMeshToSdf, PartsTravelAsBytesExactly)
{
    const TriangleMesh knot = makeTorusKnot();
    const openvdb::FloatGrid::Ptr g = meshToSdf(knot, knotOptions());
    const std::string bytes = serializeGrid(*g);
    const openvdb::FloatGrid::Ptr back = deserializeGrid(bytes);
    EXPECT_EQ(gridDifference(*g, *back), "");
    EXPECT_THROW(deserializeGrid("not a vdb stream"), IoError);
    EXPECT_THROW(deserializeGrid(bytes.substr(0, bytes.size() / 2)), IoError);
    // two parts claiming the same leaf
    std::vector<openvdb::FloatGrid::Ptr> parts{meshToSdfBricks(knot, knotOptions(), {openvdb::CoordBBox(openvdb::Coord(-512), openvdb::Coord(511))}),
                                               meshToSdfBricks(knot, knotOptions(), {openvdb::CoordBBox(openvdb::Coord(-512), openvdb::Coord(511))})};
    EXPECT_THROW(finishBrickUnion(knot, knotOptions(), parts), InvalidArgumentError);
}

TEST(DistributedMeshToSdf, WithoutMpiTheEntryPointsSayHowToGetIt)
{
    if (mpiAvailable()) GTEST_SKIP() << "built with MPI: the MPI runs are tested under mpirun (TestCliDistributed.cc)";
    try {
        distributedRank();
        ADD_FAILURE() << "no error";
    } catch (const InvalidArgumentError& e) {
        EXPECT_NE(std::string(e.what()).find("libopenmpi-dev"), std::string::npos) << e.what();
    }
}
