// SPDX-License-Identifier: Apache-2.0
// Two-pass triangle lists (Chang et al. §3.2): every list holds exactly the triangles the
// voxelizer assigns to that cell, sorted; identical for any thread count.
#include "TestUtil.h"

#include <levelforge/reference/MeshShapes.h>
#include <levelforge/mesh/TriangleListTree.h>

#include <tbb/global_control.h>

#include <map>

using namespace levelforge;

TEST(TriangleListTree, ListsMatchVoxelization)
{
    TriangleMesh knot = makeTorusKnot(2, 3, 1.0, 0.25, 80, 10);
    for (Vec3d& p : knot.points) p = p * 23.0 + Vec3d(0.31);
    std::vector<uint32_t> use(knot.triangles.size());
    for (uint32_t i = 0; i < use.size(); ++i) use[i] = i;
    VoxelizerCounters counters;
    const TriangleListTree lists = TriangleListTree::build(knot.points, knot.triangles, use, &counters);

    std::map<openvdb::math::Coord, std::vector<uint32_t>> expect;
    std::vector<openvdb::math::Coord> cells;
    for (uint32_t t : use) {
        cells.clear();
        const Vec3I& tri = knot.triangles[t];
        voxelizeTriangle(knot.points[tri[0]], knot.points[tri[1]], knot.points[tri[2]], cells);
        for (const auto& c : cells) expect[c].push_back(t);
    }
    ASSERT_EQ(lists.cellCount(), expect.size());
    uint64_t entries = 0;
    for (const auto& [c, ids] : expect) {
        uint32_t ord = 0;
        ASSERT_TRUE(lists.tree().probeValue(c, ord)) << c;
        ASSERT_EQ(lists.listSize(ord), ids.size()) << c;
        EXPECT_TRUE(std::equal(ids.begin(), ids.end(), lists.listBegin(ord))) << c;
        entries += ids.size();
    }
    EXPECT_EQ(lists.entryCount(), entries);
    EXPECT_GT(counters.microtriangles, knot.triangles.size());
    EXPECT_GT(lists.memoryUsage(), 0u);
}

TEST(TriangleListTree, SameForAnyThreadCount)
{
    TriangleMesh s = makeIcosphere(Vec3d(0.0), 40.0, 4);
    std::vector<uint32_t> use(s.triangles.size());
    for (uint32_t i = 0; i < use.size(); ++i) use[i] = i;
    std::unique_ptr<TriangleListTree> one;
    {
        tbb::global_control gc(tbb::global_control::max_allowed_parallelism, 1);
        one.reset(new TriangleListTree(TriangleListTree::build(s.points, s.triangles, use)));
    }
    const TriangleListTree many = TriangleListTree::build(s.points, s.triangles, use);
    ASSERT_EQ(one->cellCount(), many.cellCount());
    for (auto it = one->tree().cbeginValueOn(); it; ++it) {
        uint32_t o2 = 0;
        ASSERT_TRUE(many.tree().probeValue(it.getCoord(), o2));
        ASSERT_EQ(*it, o2);
        ASSERT_TRUE(std::equal(one->listBegin(*it), one->listEnd(*it), many.listBegin(o2), many.listEnd(o2)));
    }
}
