// SPDX-License-Identifier: Apache-2.0
// `levelforge mesh-to-sdf --fog-grid / --reference / --primitive-index-grid` end to end (issue
// 16, items 3-5): real processes, real files, and the bad inputs that must leave no output.
#include "CliRunner.h"
#include "TestUtil.h"

#include <levelforge/core/Metadata.h>
#include <levelforge/io/MeshIO.h>
#include <levelforge/io/VdbIO.h>
#include <levelforge/reference/MeshShapes.h>

#include <openvdb/openvdb.h>

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <sys/wait.h>

namespace fs = std::filesystem;
using levelforge_test::scratchDir;

#ifdef LEVELFORGE_CLI_PATH

using levelforge_test::countLines;

namespace {

using levelforge_test::CliRun;
using levelforge_test::readText;

CliRun runCli(const fs::path& dir, const std::vector<std::string>& args) { return levelforge_test::runLevelforge(dir, args); }

/// A cube of 6 quads and a pentagon-capped prism would do; a box of quads (each face split in
/// two by the reader) is enough for the CLI.
std::string writeQuadBox(const fs::path& dir)
{
    const std::string path = (dir / "box.obj").string();
    std::ofstream f(path);
    f << "v -0.5 -0.5 -0.5\nv 0.5 -0.5 -0.5\nv 0.5 0.5 -0.5\nv -0.5 0.5 -0.5\n"
         "v -0.5 -0.5 0.5\nv 0.5 -0.5 0.5\nv 0.5 0.5 0.5\nv -0.5 0.5 0.5\n"
         "f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\n";
    return path;
}

openvdb::GridPtrVecPtr readAll(const std::string& path)
{
    return levelforge::readGrids(path);
}

using levelforge_test::expectCleanFailure;

} // namespace

TEST(CliOutputs, FogAndPrimitiveIndexGrids)
{
    const fs::path dir = scratchDir("cli_outputs_grids");
    const std::string mesh = writeQuadBox(dir);
    const std::string out = (dir / "box.vdb").string();
    const CliRun r = runCli(dir, {"mesh-to-sdf", mesh, out, "--voxel-size", "0.05", "--quiet", "--fog-grid",
                                  "density", "--primitive-index-grid", "primitive"});
    ASSERT_EQ(r.code, 0) << r.command << "\n" << r.err;
    EXPECT_NE(r.out.find("fog grid 'density'"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("primitive index grid 'primitive'"), std::string::npos) << r.out;
    const auto grids = readAll(out);
    ASSERT_EQ(grids->size(), 3u);
    auto byName = [&](const std::string& name) {
        for (const auto& g : *grids)
            if (g->getName() == name) return g;
        return openvdb::GridBase::Ptr();
    };
    auto sdf = openvdb::gridPtrCast<openvdb::FloatGrid>(byName("surface"));
    auto fog = openvdb::gridPtrCast<openvdb::FloatGrid>(byName("density"));
    auto prim = openvdb::gridPtrCast<openvdb::Int32Grid>(byName("primitive"));
    ASSERT_TRUE(sdf && fog && prim);
    EXPECT_EQ(sdf->getName(), "surface");
    EXPECT_EQ(fog->getName(), "density");
    EXPECT_EQ(prim->getName(), "primitive");
    EXPECT_EQ(fog->getGridClass(), openvdb::GRID_FOG_VOLUME);
    EXPECT_EQ(fog->transform(), sdf->transform());
    EXPECT_EQ(prim->transform(), sdf->transform());
    EXPECT_EQ(prim->activeVoxelCount(), sdf->activeVoxelCount());
    // the box's centre: fog 1; the voxel above the top face's middle: face 1 (z = 0.5)
    EXPECT_EQ(fog->tree().getValue(openvdb::Coord(0, 0, 0)), 1.0f);
    EXPECT_EQ(prim->tree().getValue(openvdb::Coord(0, 0, 11)), 1);
    EXPECT_EQ(prim->tree().getValue(openvdb::Coord(0, 0, -11)), 0);
    EXPECT_EQ(prim->tree().getValue(openvdb::Coord(11, 0, 0)), 3);
    int32_t maxIndex = -1;
    for (auto it = prim->tree().cbeginValueOn(); it; ++it) maxIndex = std::max(maxIndex, *it);
    EXPECT_EQ(maxIndex, 5); // 6 quads, not 12 triangles
}

TEST(CliOutputs, ReferenceTransformAndBands)
{
    openvdb::initialize();
    const fs::path dir = scratchDir("cli_outputs_reference");
    const std::string mesh = writeQuadBox(dir);
    auto xform = openvdb::math::Transform::createLinearTransform(0.1);
    xform->postTranslate(openvdb::Vec3d(0.03, -0.02, 0.05));
    auto ref = openvdb::FloatGrid::create(0.25f);
    ref->setTransform(xform);
    ref->setName("ref");
    levelforge::stampLevelSetMetadata(*ref, 2.5, 1.5, "test", "test");
    const std::string refPath = (dir / "ref.vdb").string();
    levelforge::writeGridsAtomic(refPath, openvdb::GridPtrVec{ref});

    const std::string out = (dir / "aligned.vdb").string();
    CliRun r = runCli(dir, {"mesh-to-sdf", mesh, out, "--quiet", "--reference", refPath});
    ASSERT_EQ(r.code, 0) << r.command << "\n" << r.err;
    EXPECT_NE(r.out.find("transform: from reference"), std::string::npos) << r.out;
    auto grids = readAll(out);
    ASSERT_EQ(grids->size(), 1u);
    auto sdf = openvdb::gridPtrCast<openvdb::FloatGrid>((*grids)[0]);
    ASSERT_TRUE(sdf);
    EXPECT_EQ(sdf->transform(), *xform);
    EXPECT_NEAR(sdf->metaValue<float>(levelforge::meta::kExteriorBandVoxels), 2.5f, 1e-6);
    EXPECT_NEAR(sdf->metaValue<float>(levelforge::meta::kInteriorBandVoxels), 1.5f, 1e-6);
    // voxel (5, 0, 0) is centred at x = 0.53: 0.03 outside the face x = 0.5
    EXPECT_NEAR(sdf->tree().getValue(openvdb::Coord(5, 0, 0)), 0.03f, 1e-6);

    // a width given on the command line wins; world units are world units
    r = runCli(dir, {"mesh-to-sdf", mesh, out, "--quiet", "--reference", refPath, "--exterior-band", "0.4",
                     "--world-units"});
    ASSERT_EQ(r.code, 0) << r.command << "\n" << r.err;
    sdf = openvdb::gridPtrCast<openvdb::FloatGrid>((*readAll(out))[0]);
    EXPECT_NEAR(sdf->metaValue<float>(levelforge::meta::kExteriorBandVoxels), 4.0f, 1e-5);
    EXPECT_NEAR(sdf->metaValue<float>(levelforge::meta::kInteriorBandVoxels), 1.5f, 1e-5);

    // the reference gives the voxel size: --voxel-size with it is a usage error
    r = runCli(dir, {"mesh-to-sdf", mesh, (dir / "x.vdb").string(), "--quiet", "--reference", refPath,
                     "--voxel-size", "0.2"});
    expectCleanFailure(r, (dir / "x.vdb").string(), "--reference");
}

TEST(CliOutputs, BadInputsLeaveNoOutput)
{
    openvdb::initialize();
    const fs::path dir = scratchDir("cli_outputs_bad");
    const std::string mesh = writeQuadBox(dir);
    const std::string out = (dir / "out.vdb").string();

    // unreadable reference
    const std::string missing = (dir / "missing.vdb").string();
    expectCleanFailure(runCli(dir, {"mesh-to-sdf", mesh, out, "--quiet", "--reference", missing}), out, missing);
    const std::string garbage = (dir / "garbage.vdb").string();
    std::ofstream(garbage) << "not a vdb file\n";
    expectCleanFailure(runCli(dir, {"mesh-to-sdf", mesh, out, "--quiet", "--reference", garbage}), out, garbage);

    // a reference without a float grid
    auto v = openvdb::Vec3SGrid::create();
    v->setName("velocity");
    const std::string noFloat = (dir / "velocity.vdb").string();
    levelforge::writeGridsAtomic(noFloat, openvdb::GridPtrVec{v});
    expectCleanFailure(runCli(dir, {"mesh-to-sdf", mesh, out, "--quiet", "--reference", noFloat}), out, noFloat);

    // a reference with a non-uniform scale
    openvdb::math::Mat4d scale = openvdb::math::Mat4d::identity();
    scale.setToScale(openvdb::Vec3d(0.1, 0.1, 0.3));
    auto stretched = openvdb::FloatGrid::create();
    stretched->setTransform(openvdb::math::Transform::createLinearTransform(scale));
    const std::string stretchedPath = (dir / "stretched.vdb").string();
    levelforge::writeGridsAtomic(stretchedPath, openvdb::GridPtrVec{stretched});
    expectCleanFailure(runCli(dir, {"mesh-to-sdf", mesh, out, "--quiet", "--reference", stretchedPath}), out,
                       stretchedPath);

    // duplicate grid names
    expectCleanFailure(runCli(dir, {"mesh-to-sdf", mesh, out, "--quiet", "--voxel-size", "0.1", "--fog-grid",
                                    "surface"}),
                       out, "distinct");
    expectCleanFailure(runCli(dir, {"mesh-to-sdf", mesh, out, "--quiet", "--voxel-size", "0.1", "--fog-grid", "a",
                                    "--primitive-index-grid", "a"}),
                       out, "distinct");
    // a primitive index with an expansion
    expectCleanFailure(runCli(dir, {"mesh-to-sdf", mesh, out, "--quiet", "--voxel-size", "0.1",
                                    "--primitive-index-grid", "p", "--expansion", "sweep", "--exterior-band", "6"}),
                       out, "primitive index");
    // an existing output is left untouched by a failure
    std::ofstream(out) << "keep";
    runCli(dir, {"mesh-to-sdf", mesh, out, "--quiet", "--reference", missing});
    EXPECT_EQ(readText(out), "keep");
}

#endif // LEVELFORGE_CLI_PATH
