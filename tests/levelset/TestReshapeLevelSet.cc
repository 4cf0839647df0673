// SPDX-License-Identifier: Apache-2.0
// reshapeLevelSet() (dilate / erode / open / close) against analytic shapes, and the `reshape`
// operator end to end.
#include "TestUtil.h"
#include "tools/CliRunner.h"

#include <levelforge/core/Exceptions.h>
#include <levelforge/io/VdbIO.h>
#include <levelforge/levelset/ReshapeLevelSet.h>
#include <levelforge/mesh/MeshToLevelSet.h>
#include <levelforge/reference/MeshShapes.h>

#include <openvdb/openvdb.h>
#include <openvdb/tools/Composite.h>
#include <openvdb/tools/LevelSetSphere.h>

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>

using namespace levelforge;

namespace {

constexpr float kH = 0.05f;   // voxel size
constexpr float kBand = 3.0f; // half-width, voxels

openvdb::FloatGrid::Ptr sphere(float radius, const openvdb::Vec3f& centre = openvdb::Vec3f(0.0f))
{
    openvdb::initialize();
    return openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(radius, centre, kH, kBand);
}

/// The largest |φ − (|x − c| − R)| over the active voxels within 1 voxel of the surface, voxels.
double worstNearSurface(const openvdb::FloatGrid& g, double R, const openvdb::Vec3d& c = openvdb::Vec3d(0.0))
{
    double worst = 0.0;
    for (auto it = g.tree().cbeginValueOn(); it; ++it) {
        if (std::abs(*it) > kH) continue;
        const double exact = (g.indexToWorld(it.getCoord()) - c).length() - R;
        worst = std::max(worst, std::abs(double(*it) - exact) / kH);
    }
    return worst;
}

/// Voxels of the band whose value is negative.
uint64_t insideCount(const openvdb::FloatGrid& g)
{
    uint64_t n = 0;
    for (auto it = g.tree().cbeginValueAll(); it; ++it)
        if (*it < 0.0f) n += it.isVoxelValue() ? 1 : it.getVoxelCount();
    return n;
}

} // namespace

TEST(ReshapeLevelSet, DilateAndErodeASphereMoveItsSurfaceByTheOffset)
{
    const float R = 1.0f;
    const auto s = sphere(R);
    for (const double r : {0.5, 2.0, 5.5}) {
        for (const bool dilate : {true, false}) {
            SCOPED_TRACE(std::string(dilate ? "dilate " : "erode ") + std::to_string(r));
            ReshapeOptions o;
            o.operation = dilate ? ReshapeOperation::Dilate : ReshapeOperation::Erode;
            o.offset = r;
            const auto out = reshapeLevelSet(*s, o);
            EXPECT_EQ(out->getGridClass(), openvdb::GRID_LEVEL_SET);
            EXPECT_EQ(out->background(), s->background());
            EXPECT_EQ(out->transform(), s->transform());
            const double expected = R + (dilate ? r : -r) * kH;
            // first-order tracking: the zero crossing within a fifth of a voxel of the exact sphere
            const double worst = worstNearSurface(*out, expected);
            EXPECT_LT(worst, 0.05);
            std::printf("%s by %.1f voxels: zero crossing within %.3f voxel of the exact sphere\n", dilate ? "dilate" : "erode",
                        r, worst);
            // the band keeps its width: active values reach about ±band
            float lo = 0.0f, hi = 0.0f;
            for (auto it = out->tree().cbeginValueOn(); it; ++it) { lo = std::min(lo, *it); hi = std::max(hi, *it); }
            EXPECT_GT(hi / kH, kBand - 1.0f);
            EXPECT_LT(lo / kH, -(kBand - 1.0f));
        }
    }
    // world units: 0.1 world = 2 voxels
    ReshapeOptions o;
    o.offset = 0.1;
    o.worldUnits = true;
    EXPECT_LT(worstNearSurface(*reshapeLevelSet(*s, o), R + 0.1), 0.2);
    // the input is unchanged
    EXPECT_LT(worstNearSurface(*s, R), 1e-4);
}

TEST(ReshapeLevelSet, OpenRemovesThinFeaturesAndCloseFillsNarrowGaps)
{
    // open: a sphere with a thin disc-like neighbour 2 voxels thick (a flat box) is opened by
    // 2 voxels: the box vanishes, the sphere stays
    const auto ball = sphere(0.6f);
    MeshToLevelSetOptions mo;
    mo.voxelSize = kH;
    mo.exteriorWidth = mo.interiorWidth = kBand;
    auto slab = meshToLevelSet(makeBox(Vec3d(0.9, -0.5, -0.05), Vec3d(1.5, 0.5, 0.05)), mo);
    auto both = ball->deepCopy();
    openvdb::tools::csgUnion(*both, *slab->deepCopy());
    ReshapeOptions o;
    o.operation = ReshapeOperation::Open;
    o.offset = 2.0;
    const auto opened = reshapeLevelSet(*both, o);
    const openvdb::Coord inSlab = opened->transform().worldToIndexCellCentered(openvdb::Vec3d(1.2, 0.0, 0.0));
    const openvdb::Coord inBall = opened->transform().worldToIndexCellCentered(openvdb::Vec3d(0.0, 0.0, 0.0));
    EXPECT_LT(both->tree().getValue(inSlab), 0.0f);
    EXPECT_GT(opened->tree().getValue(inSlab), 0.0f);
    EXPECT_LT(opened->tree().getValue(inBall), 0.0f);
    EXPECT_LT(worstNearSurface(*opened, 0.6), 0.35); // the ball survives, about unchanged

    // close: two balls 2 voxels apart are joined by a close of 3 voxels
    auto pair = sphere(0.5f, openvdb::Vec3f(-0.55f, 0.0f, 0.0f));
    openvdb::tools::csgUnion(*pair, *sphere(0.5f, openvdb::Vec3f(0.55f, 0.0f, 0.0f)));
    const openvdb::Coord gap = pair->transform().worldToIndexCellCentered(openvdb::Vec3d(0.0, 0.0, 0.0));
    EXPECT_GT(pair->tree().getValue(gap), 0.0f);
    o.operation = ReshapeOperation::Close;
    o.offset = 3.0;
    const auto closed = reshapeLevelSet(*pair, o);
    EXPECT_LT(closed->tree().getValue(gap), 0.0f);
    EXPECT_GE(insideCount(*closed), insideCount(*pair));
}

TEST(ReshapeLevelSet, BadInputIsRefused)
{
    const auto s = sphere(1.0f);
    ReshapeOptions o;
    for (const double bad : {0.0, -1.0, std::nan(""), 1e6}) {
        o.offset = bad;
        EXPECT_THROW(reshapeLevelSet(*s, o), InvalidArgumentError) << bad;
    }
    o.offset = 1.0;
    auto fog = s->deepCopy();
    fog->setGridClass(openvdb::GRID_FOG_VOLUME);
    EXPECT_THROW(reshapeLevelSet(*fog, o), InvalidArgumentError);
    const auto thin = openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(1.0f, openvdb::Vec3f(0.0f), kH, 1.5f);
    EXPECT_THROW(reshapeLevelSet(*thin, o), InvalidArgumentError);
    EXPECT_THROW(reshapeOperationFromString("grow"), InvalidArgumentError);
    struct Stop : openvdb::util::NullInterrupter
    {
        bool wasInterrupted(int = -1) override { return true; }
    } stop;
    o.interrupter = &stop;
    EXPECT_THROW(reshapeLevelSet(*s, o), InterruptedError);
}

#ifdef LEVELFORGE_CLI_PATH
TEST(ReshapeLevelSet, CliDilatesAndFailsCleanly)
{
    namespace fs = std::filesystem;
    const fs::path dir = levelforge_test::scratchDir("reshape_cli");
    const auto s = sphere(1.0f);
    s->setName("surface");
    const std::string in = (dir / "in.vdb").string(), out = (dir / "out.vdb").string();
    writeGridsAtomic(in, openvdb::GridPtrVec{s}, openvdb::MetaMap());
    auto r = levelforge_test::runLevelforge(dir, {"reshape", in, out, "--op", "dilate", "--offset", "2", "--quiet"});
    ASSERT_EQ(r.code, 0) << r.err;
    EXPECT_NE(r.out.find("dilate by 2 voxels"), std::string::npos) << r.out;
    const auto grids = readGrids(out);
    ASSERT_EQ(grids->size(), 1u);
    const auto g = openvdb::gridPtrCast<openvdb::FloatGrid>((*grids)[0]);
    ASSERT_TRUE(g);
    EXPECT_LT(worstNearSurface(*g, 1.0 + 2 * kH), 0.2);
    // bad input: one error line, exit status non-zero, no output
    const std::string out2 = (dir / "out2.vdb").string();
    r = levelforge_test::runLevelforge(dir, {"reshape", (dir / "missing.vdb").string(), out2, "--quiet"});
    EXPECT_NE(r.code, 0);
    EXPECT_EQ(levelforge_test::countLines(r.err, "levelforge: error:"), 1) << r.err;
    EXPECT_FALSE(fs::exists(out2));
    r = levelforge_test::runLevelforge(dir, {"reshape", in, out2, "--op", "grow", "--quiet"});
    EXPECT_NE(r.code, 0);
    EXPECT_FALSE(fs::exists(out2));
    r = levelforge_test::runLevelforge(dir, {"reshape", in, out2, "--offset", "-1", "--quiet"});
    EXPECT_NE(r.code, 0);
    EXPECT_FALSE(fs::exists(out2));
}
#endif
