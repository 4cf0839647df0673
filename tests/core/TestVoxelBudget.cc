// SPDX-License-Identifier: Apache-2.0
// The shared voxel budget (src/detail/VoxelBudget.h): the band-leaf count against a brute-force
// count of the leaves that really hold a voxel within reach, and the one message every operator
// prints when a request does not fit.
#include "detail/VoxelBudget.h"

#include <levelforge/core/Exceptions.h>
#include <levelforge/core/TriangleDistance.h>
#include <levelforge/mesh/MeshToLevelSet.h>
#include <levelforge/reference/ExactReference.h>
#include <levelforge/reference/MeshShapes.h>
#include <levelforge/scan/TetScanConversion.h>

#include <gtest/gtest.h>
#include <tbb/global_control.h>
#include <tbb/task_arena.h>

#include <cmath>
#include <set>
#include <string>

using namespace levelforge;

namespace {

/// Leaves (origin / 8) holding a voxel centre (cell ijk + 0.5) within reach of a triangle,
/// by brute force over every voxel of the candidate range.
uint64_t bruteForceLeaves(const std::vector<Vec3d>& pts, const std::vector<Vec3I>& tris, double reach)
{
    std::set<std::array<int, 3>> leaves;
    for (const Vec3I& t : tris) {
        Vec3d lo(1e300), hi(-1e300);
        for (int v = 0; v < 3; ++v)
            for (int k = 0; k < 3; ++k) {
                lo[k] = std::min(lo[k], pts[t[v]][k]);
                hi[k] = std::max(hi[k], pts[t[v]][k]);
            }
        int a[3], b[3];
        for (int k = 0; k < 3; ++k) {
            a[k] = int(std::floor(lo[k] - reach - 1));
            b[k] = int(std::ceil(hi[k] + reach + 1));
        }
        for (int x = a[0]; x <= b[0]; ++x)
            for (int y = a[1]; y <= b[1]; ++y)
                for (int z = a[2]; z <= b[2]; ++z) {
                    const std::array<int, 3> leaf{x >> 3, y >> 3, z >> 3};
                    if (leaves.count(leaf)) continue;
                    const Vec3d p(x + 0.5, y + 0.5, z + 0.5);
                    const TriangleClosestPoint c = closestPointOnTriangle(p, pts[t[0]], pts[t[1]], pts[t[2]]);
                    if ((c.point - p).length() <= reach) leaves.insert(leaf);
                }
    }
    return leaves.size();
}

} // namespace

TEST(VoxelBudget, BandLeafCountHoldsEveryLeafOfTheBandAndLittleMore)
{
    struct Case { const char* name; std::vector<Vec3d> pts; std::vector<Vec3I> tris; double reach; };
    std::vector<Case> cases;
    // a sliver 300 cells long and 0.01 wide, diagonal: its bounding box would be ~5e4 leaves
    cases.push_back({"diagonal sliver", {Vec3d(3.2, 4.1, 5.7), Vec3d(303.2, 204.1, 255.7), Vec3d(303.21, 204.1, 255.7)},
                     {Vec3I(0, 1, 2)}, 3.0});
    // a small sphere, narrow and wide bands
    const TriangleMesh s = makeIcosphere(Vec3d(40.3, 37.1, 35.9), 20.0, 3);
    cases.push_back({"sphere r20 band 3", s.points, s.triangles, 3.0});
    cases.push_back({"sphere r20 band 20", s.points, s.triangles, 20.0});
    // a fan of 400 triangles around one vertex
    Case fan{"vertex fan", {Vec3d(10.5, 10.5, 10.5)}, {}, 2.0};
    for (int i = 0; i < 400; ++i) {
        const double a = 2 * M_PI * i / 400.0;
        fan.pts.push_back(Vec3d(10.5 + 60 * std::cos(a), 10.5 + 60 * std::sin(a), 10.5 + 5 * std::sin(3 * a)));
    }
    for (uint32_t i = 0; i < 400; ++i) fan.tris.push_back(Vec3I(0, 1 + i, 1 + (i + 1) % 400));
    cases.push_back(fan);

    for (const Case& c : cases) {
        const uint64_t truth = bruteForceLeaves(c.pts, c.tris, c.reach);
        uint64_t counts[2];
        for (int threads : {1, 2}) {
            tbb::global_control gc(tbb::global_control::max_allowed_parallelism, threads);
            counts[threads - 1] = detail::bandLeafCount(c.pts, c.tris, {}, c.reach);
        }
        EXPECT_EQ(counts[0], counts[1]) << c.name << ": the count depends on the thread count";
        // a superset (boxes stand for balls) ...
        EXPECT_GE(counts[0], truth) << c.name;
        // ... but not a bounding box: within 2x the leaves really in the band (+ a constant for tiny cases)
        EXPECT_LE(double(counts[0]), 2.0 * double(truth) + 8.0) << c.name << ": truth " << truth;
    }
}

TEST(VoxelBudget, OneMessageNamesTheOperationTheNumbersAndTheLimit)
{
    detail::VoxelBudgetRequest r{"my operator", "the band", "12 leaf nodes", 6144.0, 8.0 * 1024 * 1024, 4000,
                                 "use a larger voxel size"};
    EXPECT_DOUBLE_EQ(detail::budgetVoxels(r), 6144.0 + 2.0 * 1024 * 1024);
    try {
        detail::checkVoxelBudget(r);
        FAIL() << "expected ResourceLimitError";
    } catch (const ResourceLimitError& e) {
        EXPECT_EQ(std::string(e.what()), "my operator: the band would hold up to 6144 voxels (12 leaf nodes) plus 8 MiB "
                                         "of working memory, more than the limit of 4000 voxels; use a larger voxel size");
    }
    r.maxVoxels = 0; // no limit
    EXPECT_NO_THROW(detail::checkVoxelBudget(r));
    r.maxVoxels = 3 * 1024 * 1024;
    EXPECT_NO_THROW(detail::checkVoxelBudget(r));
    // scratch alone can exceed the limit
    r.voxels = 10;
    r.scratchBytes = 64.0 * 1024 * 1024;
    EXPECT_THROW(detail::checkVoxelBudget(r), ResourceLimitError);
}

TEST(VoxelBudget, EveryMeshOperatorRefusesAWideBandAroundACompactSurfaceTheSameWay)
{
    // band 1000 around a sphere 512 voxels across: ~(2512/8)^3 leaves, far beyond 2^31 voxels,
    // though surface area × band would be under the limit by the old estimate's standard
    const TriangleMesh sphere = makeIcosphere(Vec3d(0.0), 1.0, 3);
    MeshToLevelSetOptions mo;
    mo.voxelCount = 512;
    mo.exteriorWidth = 1000.0f;
    TetScanOptions so;
    so.voxelCount = 512;
    so.exteriorWidth = 1000.0f;
    std::string messages[2];
    try {
        meshToLevelSet(sphere, mo);
    } catch (const ResourceLimitError& e) {
        messages[0] = e.what();
    }
    try {
        meshToLevelSetScan(sphere, so);
    } catch (const ResourceLimitError& e) {
        messages[1] = e.what();
    }
    for (const std::string& m : messages) {
        ASSERT_FALSE(m.empty()) << "expected ResourceLimitError";
        EXPECT_NE(m.find("the band would hold up to"), std::string::npos) << m;
        EXPECT_NE(m.find("leaf nodes within 1000 voxels of the surface"), std::string::npos) << m;
        EXPECT_NE(m.find("more than the limit of"), std::string::npos) << m;
    }
}

TEST(VoxelBudget, AHugeTriangleIsRefusedBeforeTheHierarchySplitsIt)
{
    // One triangle 10^6 voxels long: the hierarchy would split it into ~10^10 pieces of 8 cells
    // before the band's leaf count is known. The first guard refuses it from the triangle alone.
    TriangleMesh m;
    m.points = {Vec3d(0.0), Vec3d(1.0, 0.0, 0.0), Vec3d(0.0, 1.0, 0.0)};
    m.triangles = {Vec3I(0, 1, 2)};
    MeshToLevelSetOptions o;
    o.voxelSize = 1e-6;
    try {
        meshToLevelSet(m, o);
        FAIL() << "no error";
    } catch (const ResourceLimitError& e) {
        const std::string msg = e.what();
        EXPECT_NE(msg.find("largest triangle"), std::string::npos) << msg;
        EXPECT_NE(msg.find("working memory"), std::string::npos) << msg;
    }
}

TEST(VoxelBudget, ALongObliqueNeedleIsNotRefusedForItsBox)
{
    // A stray vertex far along the diagonal (a bad export): one needle ~10^4 voxels long whose
    // box is ~6000 voxels on every axis. Its pieces follow its length (~10^3), not its box
    // (~6000² / 64); with a budget of 5·10^6 voxels the first guard used to refuse it (its box
    // alone counted 40 MB of pieces); now it converts, exactly.
    TriangleMesh m = makeIcosphere(Vec3d(0.0), 1.0, 3);
    const uint32_t first = uint32_t(m.points.size());
    m.points.emplace_back(1.5, 0.0, 0.0);
    m.points.emplace_back(1.5, 0.01, 0.0);
    m.points.emplace_back(120.0, 120.0, 120.0);
    m.triangles.emplace_back(first, first + 1, first + 2);
    MeshToLevelSetOptions o;
    o.voxelSize = 0.02;
    o.exteriorWidth = o.interiorWidth = 1.0f;
    o.maxVoxels = 5'000'000;
    o.sign = SignMode::Unsigned; // the needle has no inside
    // two threads: the budget also counts 1 MiB of scratch per thread of the arena
    openvdb::FloatGrid::Ptr grid;
    tbb::task_arena arena(2);
    arena.execute([&] { grid = meshToLevelSet(m, o); });
    ASSERT_TRUE(grid);
    ExactReference ref(m);
    size_t checked = 0;
    double maxError = 0.0;
    for (auto it = grid->cbeginValueOn(); it; ++it) {
        const Vec3d p = grid->indexToWorld(it.getCoord());
        maxError = std::max(maxError, std::abs(double(*it) - std::abs(ref.signedDistance(p))) / o.voxelSize);
        ++checked;
    }
    EXPECT_GT(checked, 10000u);
    EXPECT_LE(maxError, 1e-4);
}

TEST(VoxelBudget, TheMeshBandCheckCountsOnlyWhenItsBoundsDoNotDecide)
{
    // A diagonal sliver 400 voxels long, band 10: its dilated box (the quick upper bound) holds
    // ~53 times the leaves of the band itself, and the ball around a vertex (the quick lower
    // bound) far fewer. A limit between the band's count and the box's must be decided by the
    // count: accepted when the count fits, refused with the count when it does not.
    const std::vector<Vec3d> pts = {Vec3d(0.5), Vec3d(400.5, 400.5, 400.5), Vec3d(400.5, 401.5, 400.5)};
    const std::vector<Vec3I> tris = {Vec3I(0, 1, 2)};
    const double reach = 10.0;
    const uint64_t leaves = detail::bandLeafCount(pts, tris, {}, reach);
    const double boxLeaves = std::pow(std::ceil((400.0 + 2 * reach) / 8.0) + 1.0, 3.0);
    ASSERT_GT(boxLeaves, 20.0 * double(leaves)); // the box alone would refuse a fitting band
    EXPECT_NO_THROW(detail::checkMeshBandBudget("op", pts, tris, reach, 0.0, leaves * 512));
    try {
        detail::checkMeshBandBudget("op", pts, tris, reach, 0.0, leaves * 512 - 1);
        FAIL() << "expected ResourceLimitError";
    } catch (const ResourceLimitError& e) {
        EXPECT_NE(std::string(e.what()).find("(" + std::to_string(leaves) + " leaf nodes within 10 voxels"),
                  std::string::npos) << e.what();
    }
    // the box fits: accepted without a count; the ball cannot fit: refused from the box
    EXPECT_NO_THROW(detail::checkMeshBandBudget("op", pts, tris, reach, 0.0, uint64_t(boxLeaves * 512.0)));
    try {
        detail::checkMeshBandBudget("op", pts, tris, 5000.0, 0.0, uint64_t(1) << 31);
        FAIL() << "expected ResourceLimitError";
    } catch (const ResourceLimitError& e) {
        EXPECT_NE(std::string(e.what()).find("leaf nodes within 5000 voxels"), std::string::npos) << e.what();
    }
}
