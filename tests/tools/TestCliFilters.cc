// SPDX-License-Identifier: Apache-2.0
// `levelforge smooth / rebuild / resample` end to end: real processes, real files, results
// checked against the analytic sphere, and the bad inputs that must give one error line, a
// non-zero exit and no output file.
#include "CliRunner.h"
#include "TestUtil.h"

#include <levelforge/io/VdbIO.h>
#include <levelforge/levelset/SdfToFog.h>

#include <openvdb/openvdb.h>
#include <openvdb/tools/LevelSetSphere.h>

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

namespace fs = std::filesystem;

#ifdef LEVELFORGE_CLI_PATH

using levelforge_test::CliRun;
using levelforge_test::countLines;
using levelforge_test::scratchDir;

namespace {

constexpr float kH = 0.05f;
constexpr double kR = 1.0;

CliRun runCli(const fs::path& dir, const std::vector<std::string>& args) { return levelforge_test::runLevelforge(dir, args); }

openvdb::FloatGrid::Ptr sphere()
{
    openvdb::initialize();
    auto s = openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(float(kR), openvdb::Vec3f(0.0f), kH, 3.0f);
    s->setName("surface");
    return s;
}

/// in.vdb: the sphere level set "surface" and an int grid "labels" (to be passed through).
std::string writeInput(const fs::path& dir)
{
    const std::string path = (dir / "in.vdb").string();
    auto labels = openvdb::Int32Grid::create(0);
    labels->setName("labels");
    labels->tree().setValue(openvdb::Coord(1, 2, 3), 7);
    levelforge::writeGridsAtomic(path, openvdb::GridPtrVec{sphere(), labels}, openvdb::MetaMap());
    return path;
}

/// Max |φ − (|x| − R)| over the active voxels, in voxels of @p g.
double worstError(const openvdb::FloatGrid& g, double R = kR)
{
    double worst = 0.0;
    for (auto it = g.tree().cbeginValueOn(); it; ++it)
        worst = std::max(worst, std::abs(double(*it) - (g.indexToWorld(it.getCoord()).length() - R)));
    return worst / g.voxelSize()[0];
}

openvdb::GridBase::Ptr findGrid(const std::string& path, const std::string& name)
{
    const openvdb::GridPtrVecPtr grids = levelforge::readGrids(path);
    for (const auto& g : *grids)
        if (g->getName() == name) return g;
    return nullptr;
}

using levelforge_test::expectCleanFailure;

} // namespace

TEST(CliFilters, SmoothKeepsTheSphereAndPassesOtherGridsThrough)
{
    const fs::path dir = scratchDir("cli_smooth");
    const std::string in = writeInput(dir), out = (dir / "out.vdb").string();
    for (const std::string filter : {"mean", "gaussian", "median", "mean-curvature", "laplacian"}) {
        SCOPED_TRACE(filter);
        fs::remove(out);
        const CliRun r = runCli(dir, {"smooth", in, out, "--filter", filter, "--iterations", "1", "--quiet"});
        ASSERT_EQ(r.code, 0) << r.err;
        EXPECT_NE(r.out.find(filter + " x1"), std::string::npos) << r.out;
        EXPECT_EQ(r.err, "");
        const auto g = openvdb::gridPtrCast<openvdb::FloatGrid>(findGrid(out, "surface"));
        ASSERT_TRUE(g);
        EXPECT_EQ(g->getGridClass(), openvdb::GRID_LEVEL_SET);
        EXPECT_LT(worstError(*g), 0.2); // one iteration shrinks a 20-voxel sphere by <= 0.14 voxel (gaussian)
        EXPECT_GT(worstError(*g), 0.01); // and it did something
        const auto labels = openvdb::gridPtrCast<openvdb::Int32Grid>(findGrid(out, "labels"));
        ASSERT_TRUE(labels);
        EXPECT_EQ(labels->tree().getValue(openvdb::Coord(1, 2, 3)), 7);
    }
    // --radius widens the box: mean of radius 2 shrinks the sphere by 0.1 voxel instead of 0.033
    fs::remove(out);
    const CliRun r = runCli(dir, {"smooth", in, out, "--radius", "2", "--quiet"});
    ASSERT_EQ(r.code, 0) << r.err;
    EXPECT_NE(r.out.find("radius 2 voxels"), std::string::npos) << r.out;
    const auto g = openvdb::gridPtrCast<openvdb::FloatGrid>(findGrid(out, "surface"));
    ASSERT_TRUE(g);
    EXPECT_GT(worstError(*g), 0.09);
}

TEST(CliFilters, SmoothRefusesBadInput)
{
    const fs::path dir = scratchDir("cli_smooth_bad");
    const std::string in = writeInput(dir), out = (dir / "out.vdb").string();
    // not a level set
    const std::string fog = (dir / "fog.vdb").string();
    levelforge::writeGridsAtomic(fog, openvdb::GridPtrVec{levelforge::sdfToFog(*sphere())}, openvdb::MetaMap());
    expectCleanFailure(runCli(dir, {"smooth", fog, out, "--quiet"}), out, "level-set");
    expectCleanFailure(runCli(dir, {"smooth", fog, out, "--grid-name", "surface", "--quiet"}), out, "not a level set");
    expectCleanFailure(runCli(dir, {"smooth", in, out, "--grid-name", "nope", "--quiet"}), out, "nope");
    expectCleanFailure(runCli(dir, {"smooth", in, out, "--radius", "0", "--quiet"}), out, "--radius");
    expectCleanFailure(runCli(dir, {"smooth", in, out, "--filter", "blur", "--quiet"}), out, "blur");
    expectCleanFailure(runCli(dir, {"smooth", (dir / "missing.vdb").string(), out, "--quiet"}), out, "missing.vdb");
}

TEST(CliFilters, RebuildMakesAnExactBandFromAFogVolume)
{
    const fs::path dir = scratchDir("cli_rebuild");
    const std::string fog = (dir / "fog.vdb").string(), out = (dir / "out.vdb").string();
    auto f = levelforge::sdfToFog(*sphere());
    f->setName("density");
    levelforge::writeGridsAtomic(fog, openvdb::GridPtrVec{f}, openvdb::MetaMap());
    CliRun r = runCli(dir, {"rebuild", fog, out, "--iso", "0.5", "--exterior-band", "4", "--quiet"});
    ASSERT_EQ(r.code, 0) << r.err;
    EXPECT_NE(r.out.find("fog volume"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("inside above"), std::string::npos) << r.out;
    auto g = levelforge_test::readSingleFloatGrid(out);
    ASSERT_TRUE(g);
    EXPECT_EQ(g->getName(), "density");
    EXPECT_EQ(g->getGridClass(), openvdb::GRID_LEVEL_SET);
    EXPECT_FLOAT_EQ(g->background(), 4 * kH);
    EXPECT_LT(worstError(*g, kR - 1.5 * kH), 0.05); // iso 0.5 of a 3-voxel ramp: 1.5 voxels inside
    // at another voxel size
    fs::remove(out);
    r = runCli(dir, {"rebuild", fog, out, "--iso", "0.5", "--voxel-size", "0.1", "--quiet"});
    ASSERT_EQ(r.code, 0) << r.err;
    g = levelforge_test::readSingleFloatGrid(out);
    ASSERT_TRUE(g);
    EXPECT_DOUBLE_EQ(g->voxelSize()[0], 0.1);
    EXPECT_LT(worstError(*g, kR - 1.5 * kH), 0.03);
}

TEST(CliFilters, RebuildRefusesBadInput)
{
    const fs::path dir = scratchDir("cli_rebuild_bad");
    const std::string in = writeInput(dir), out = (dir / "out.vdb").string();
    expectCleanFailure(runCli(dir, {"rebuild", in, out, "--iso", "5", "--quiet"}), out, "no iso-surface");
    expectCleanFailure(runCli(dir, {"rebuild", in, out, "--grid-name", "labels", "--quiet"}), out, "labels");
    expectCleanFailure(runCli(dir, {"rebuild", in, out, "--voxel-size", "0", "--quiet"}), out, "--voxel-size");
    expectCleanFailure(runCli(dir, {"rebuild", in, out, "--voxel-size", "-0.1", "--quiet"}), out, "--voxel-size");
    expectCleanFailure(runCli(dir, {"rebuild", in, out, "--exterior-band", "0", "--quiet"}), out, "--exterior-band");
    // no float grid at all
    const std::string ints = (dir / "ints.vdb").string();
    levelforge::writeGridsAtomic(ints, openvdb::GridPtrVec{openvdb::Int32Grid::create(0)}, openvdb::MetaMap());
    expectCleanFailure(runCli(dir, {"rebuild", ints, out, "--quiet"}), out, "no float grid");
}

TEST(CliFilters, ResampleToAVoxelSizeAndToAReference)
{
    const fs::path dir = scratchDir("cli_resample");
    const std::string in = writeInput(dir), out = (dir / "out.vdb").string();
    CliRun r = runCli(dir, {"resample", in, out, "--voxel-size", "0.1", "--quiet"});
    ASSERT_EQ(r.code, 0) << r.err;
    EXPECT_NE(r.out.find("rebuilt"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("'labels' (int32): written unchanged"), std::string::npos) << r.out;
    auto g = openvdb::gridPtrCast<openvdb::FloatGrid>(findGrid(out, "surface"));
    ASSERT_TRUE(g);
    EXPECT_DOUBLE_EQ(g->voxelSize()[0], 0.1);
    EXPECT_LT(worstError(*g), 0.03);
    ASSERT_TRUE(findGrid(out, "labels"));

    // a reference with a rotated, offset transform
    auto refGrid = openvdb::FloatGrid::create(0.0f);
    refGrid->setName("ref");
    auto t = openvdb::math::Transform::createLinearTransform(0.04);
    t->postRotate(0.5, openvdb::math::Z_AXIS);
    t->postTranslate(openvdb::Vec3d(0.013, -0.021, 0.007));
    refGrid->setTransform(t);
    const std::string ref = (dir / "ref.vdb").string();
    levelforge::writeGridsAtomic(ref, openvdb::GridPtrVec{refGrid}, openvdb::MetaMap());
    fs::remove(out);
    r = runCli(dir, {"resample", in, out, "--reference", ref, "--grid-name", "surface", "--order", "quadratic", "--quiet"});
    ASSERT_EQ(r.code, 0) << r.err;
    g = openvdb::gridPtrCast<openvdb::FloatGrid>(findGrid(out, "surface"));
    ASSERT_TRUE(g);
    EXPECT_EQ(g->transform(), *t);
    EXPECT_LT(worstError(*g), 0.06);

    // interpolated instead of rebuilt: the same transform, the values of the sampler
    fs::remove(out);
    r = runCli(dir, {"resample", in, out, "--reference", ref, "--level-sets", "interpolate", "--quiet"});
    ASSERT_EQ(r.code, 0) << r.err;
    EXPECT_NE(r.out.find("interpolated (linear)"), std::string::npos) << r.out;
    g = openvdb::gridPtrCast<openvdb::FloatGrid>(findGrid(out, "surface"));
    ASSERT_TRUE(g);
    EXPECT_EQ(g->transform(), *t);
}

TEST(CliFilters, ResampleRefusesBadInput)
{
    const fs::path dir = scratchDir("cli_resample_bad");
    const std::string in = writeInput(dir), out = (dir / "out.vdb").string();
    expectCleanFailure(runCli(dir, {"resample", in, out, "--quiet"}), out, "--voxel-size or --reference");
    expectCleanFailure(runCli(dir, {"resample", in, out, "--voxel-size", "0", "--quiet"}), out, "--voxel-size");
    expectCleanFailure(runCli(dir, {"resample", in, out, "--voxel-size", "abc", "--quiet"}), out, "--voxel-size");
    expectCleanFailure(runCli(dir, {"resample", in, out, "--voxel-size", "0.1", "--grid-name", "nope", "--quiet"}), out,
                       "nope");
    expectCleanFailure(runCli(dir, {"resample", in, out, "--voxel-size", "0.1", "--grid-name", "labels", "--quiet"}), out,
                       "int32");
    // a reference file without grids
    const std::string empty = (dir / "empty.vdb").string();
    levelforge::writeGridsAtomic(empty, openvdb::GridPtrVec{}, openvdb::MetaMap());
    expectCleanFailure(runCli(dir, {"resample", in, out, "--reference", empty, "--quiet"}), out, "no grids");
    expectCleanFailure(runCli(dir, {"resample", in, out, "--reference", (dir / "nothere.vdb").string(), "--quiet"}), out,
                       "nothere.vdb");
    expectCleanFailure(runCli(dir, {"resample", in, out, "--voxel-size", "0.1", "--reference", empty, "--quiet"}), out,
                       "--reference");
}

#endif
