// SPDX-License-Identifier: Apache-2.0
// `levelforge mesh-to-sdf --sign ... --fill-interior` end to end (issue 16): real processes,
// real files.
#include "CliRunner.h"
#include "TestUtil.h"

#include <levelforge/io/MeshIO.h>
#include <levelforge/io/VdbIO.h>
#include <levelforge/mesh/MeshToLevelSet.h>
#include <levelforge/reference/MeshShapes.h>

#include <openvdb/openvdb.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>


namespace fs = std::filesystem;
using levelforge_test::scratchDir;

#ifdef LEVELFORGE_CLI_PATH

using levelforge_test::countLines;

namespace {

using levelforge_test::CliRun;

CliRun runCli(const fs::path& dir, const std::vector<std::string>& args) { return levelforge_test::runLevelforge(dir, args); }

/// The unit icosphere without its cap z > 0.7, as an OBJ file in `dir`.
std::string writeOpenSphere(const fs::path& dir)
{
    const levelforge::TriangleMesh s = levelforge::makeIcosphere(levelforge::Vec3d(0.0), 1.0, 3);
    levelforge::TriangleMesh m;
    m.points = s.points;
    for (const levelforge::Vec3I& t : s.triangles)
        if ((s.points[t[0]] + s.points[t[1]] + s.points[t[2]])[2] / 3.0 <= 0.7) m.triangles.push_back(t);
    const std::string path = (dir / "open_sphere.obj").string();
    levelforge::writeMesh(m, path);
    return path;
}

openvdb::FloatGrid::Ptr readGrid(const std::string& path) { return levelforge_test::readSingleFloatGrid(path); }

} // namespace

TEST(Cli, MeshToSdfSignModes)
{
    const fs::path dir = scratchDir("cli_sign_modes");
    const std::string mesh = writeOpenSphere(dir);

    // auto on an open mesh: the winding number, and the report says why
    const std::string autoOut = (dir / "auto.vdb").string();
    CliRun r = runCli(dir, {"mesh-to-sdf", mesh, autoOut, "--voxel-count", "40", "--quiet", "--report"});
    ASSERT_EQ(r.code, 0) << r.command << "\n" << r.err;
    EXPECT_NE(r.out.find("sign: winding (auto: the mesh is not closed"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("winding number:"), std::string::npos) << r.out;
    EXPECT_EQ(r.err.find("pseudonormal's verdict"), std::string::npos) << r.err;
    auto grid = readGrid(autoOut);
    ASSERT_TRUE(grid);
    EXPECT_EQ(grid->getGridClass(), openvdb::GRID_LEVEL_SET);
    EXPECT_EQ(grid->metaValue<std::string>(levelforge::kSignMetadata), "winding");
    // inside the (open) sphere, deep below the hole: inside
    EXPECT_LT(grid->tree().getValue(grid->transform().worldToIndexCellCentered(openvdb::Vec3d(0.0, 0.0, -0.5))), 0.0f);

    // pseudonormal on an open mesh warns
    r = runCli(dir, {"mesh-to-sdf", mesh, (dir / "pn.vdb").string(), "--voxel-count", "32", "--quiet", "--sign",
                         "pseudonormal"});
    ASSERT_EQ(r.code, 0) << r.err;
    EXPECT_NE(r.err.find("pseudonormal's verdict"), std::string::npos) << r.err;
    EXPECT_NE(r.out.find("sign: pseudonormal (pseudonormal: requested)"), std::string::npos) << r.out;

    // unsigned: not a level set
    const std::string udfOut = (dir / "udf.vdb").string();
    r = runCli(dir, {"mesh-to-sdf", mesh, udfOut, "--voxel-count", "32", "--quiet", "--sign", "unsigned"});
    ASSERT_EQ(r.code, 0) << r.err;
    grid = readGrid(udfOut);
    ASSERT_TRUE(grid);
    EXPECT_EQ(grid->getGridClass(), openvdb::GRID_UNKNOWN);
    EXPECT_EQ(grid->metaValue<std::string>(levelforge::kSignMetadata), "unsigned");
    uint64_t negative = 0;
    for (auto it = grid->tree().cbeginValueAll(); it; ++it) negative += *it < 0.0f ? 1 : 0;
    EXPECT_EQ(negative, 0u);

    // fill interior: active inside tiles
    const std::string fillOut = (dir / "fill.vdb").string();
    r = runCli(dir, {"mesh-to-sdf", mesh, fillOut, "--voxel-count", "64", "--quiet", "--fill-interior", "--report"});
    ASSERT_EQ(r.code, 0) << r.err;
    EXPECT_NE(r.out.find("interior filled"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("fill interior:"), std::string::npos) << r.out;
    grid = readGrid(fillOut);
    ASSERT_TRUE(grid);
    EXPECT_TRUE(grid->metaValue<bool>(levelforge::kFillInteriorMetadata));
    EXPECT_GT(grid->tree().activeTileCount(), 0u);
    const openvdb::Coord centre = grid->transform().worldToIndexCellCentered(openvdb::Vec3d(0.0, 0.0, -0.3));
    EXPECT_TRUE(grid->tree().isValueOn(centre));
    EXPECT_LT(grid->tree().getValue(centre), 0.0f);
}

TEST(Cli, MeshToSdfBadSignInputIsOneErrorLineAndNoOutput)
{
    const fs::path dir = scratchDir("cli_sign_errors");
    const std::string mesh = writeOpenSphere(dir);
    const std::vector<std::vector<std::string>> bad = {
        {"--sign", "unsigned", "--fill-interior"},
        {"--sign", "flood"},
        {"--sign", "winding", "--method", "scan"},
        {"--sign", "unsigned", "--expansion", "sweep"},
        {"--sign", "winding", "--expansion", "sweep"},
        {"--winding-accuracy", "1"},
    };
    for (const auto& extra : bad) {
        const std::string out = (dir / "bad.vdb").string();
        std::vector<std::string> args = {"mesh-to-sdf", mesh, out, "--voxel-count", "24", "--quiet"};
        args.insert(args.end(), extra.begin(), extra.end());
        const CliRun r = runCli(dir, args);
        EXPECT_NE(r.code, 0) << r.command;
        EXPECT_EQ(countLines(r.err, "levelforge: error:"), 1) << r.command << "\n" << r.err;
        EXPECT_FALSE(fs::exists(out)) << r.command;
    }
}

#else
TEST(Cli, SignModesNotBuilt) { GTEST_SKIP() << "the levelforge executable is not part of this build"; }
#endif
