// SPDX-License-Identifier: Apache-2.0
// `levelforge sdf-to-mesh` and `levelforge slice` end to end: real processes, real files, the
// orientation round trip (mesh-to-sdf of the extracted mesh is negative inside), the PNG decoded
// with libpng, and the bad inputs that must give one error line and leave no output.
#include "CliRunner.h"
#include "TestUtil.h"

#include <levelforge/io/MeshIO.h>
#include <levelforge/io/VdbIO.h>
#include <levelforge/reference/MeshShapes.h>

#include <openvdb/openvdb.h>
#include <openvdb/tools/LevelSetSphere.h>

#include <png.h>

#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

namespace fs = std::filesystem;
using levelforge_test::scratchDir;

#ifdef LEVELFORGE_CLI_PATH

using levelforge_test::countLines;

namespace {

using levelforge_test::CliRun;

CliRun runCli(const fs::path& dir, const std::vector<std::string>& args) { return levelforge_test::runLevelforge(dir, args); }

using levelforge_test::expectCleanFailure;

/// A level-set sphere of radius 1 (20 voxels of 0.05) written to @p path.
void writeSphere(const std::string& path)
{
    openvdb::initialize();
    auto g = openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(1.0f, openvdb::Vec3f(0.0f), 0.05f, 3.0f);
    g->setName("surface");
    levelforge::writeGridsAtomic(path, openvdb::GridPtrVec{g});
}

/// Width and height of a PNG file (libpng's simplified API); {0, 0} when it cannot be read.
std::array<unsigned, 2> pngSize(const std::string& path)
{
    png_image png;
    std::memset(&png, 0, sizeof(png));
    png.version = PNG_IMAGE_VERSION;
    if (!png_image_begin_read_from_file(&png, path.c_str())) return {0, 0};
    const std::array<unsigned, 2> size{png.width, png.height};
    png_image_free(&png);
    return size;
}

/// The number after @p key in @p text (e.g. "max " -> 0.0012), NaN when absent.
double numberAfter(const std::string& text, const std::string& key)
{
    const size_t at = text.find(key);
    return at == std::string::npos ? std::nan("") : std::strtod(text.c_str() + at + key.size(), nullptr);
}

} // namespace

TEST(CliMeshSlice, SdfToMeshWritesAnOutwardClosedSphereInEveryFormat)
{
    const fs::path dir = scratchDir("cli_sdf_to_mesh");
    const std::string vdb = (dir / "sphere.vdb").string();
    writeSphere(vdb);
    size_t triangles = 0;
    for (const std::string ext : {"obj", "ply", "stl", "off"}) {
        SCOPED_TRACE(ext);
        const std::string out = (dir / ("sphere." + ext)).string();
        const CliRun r = runCli(dir, {"sdf-to-mesh", vdb, out, "--quiet"});
        ASSERT_EQ(r.code, 0) << r.command << "\n" << r.err;
        EXPECT_NE(r.out.find("triangles"), std::string::npos) << r.out;
        EXPECT_NE(r.out.find("level set"), std::string::npos) << r.out;
        EXPECT_TRUE(r.err.empty()) << r.err;
        const levelforge::TriangleMesh mesh = levelforge::readMesh(out);
        if (triangles == 0) triangles = mesh.triangleCount();
        EXPECT_EQ(mesh.triangleCount(), triangles);
        EXPECT_NEAR(levelforge::signedVolume(mesh) / (4.0 / 3.0 * M_PI), 1.0, 0.01);
        double worst = 0.0;
        for (const auto& p : mesh.points) worst = std::max(worst, std::abs(p.length() - 1.0) / 0.05);
        EXPECT_LT(worst, 0.05);
    }
    // the round trip: mesh-to-sdf of the extracted mesh is negative inside, positive outside
    const std::string back = (dir / "back.vdb").string();
    const CliRun r = runCli(dir, {"mesh-to-sdf", (dir / "sphere.obj").string(), back, "--voxel-size", "0.05",
                                  "--quiet"});
    ASSERT_EQ(r.code, 0) << r.command << "\n" << r.err;
    const auto grid = levelforge_test::readSingleFloatGrid(back);
    ASSERT_TRUE(grid);
    EXPECT_LT(grid->tree().getValue(openvdb::Coord(0, 0, 0)), 0.0f);
    EXPECT_LT(grid->tree().getValue(openvdb::Coord(18, 0, 0)), 0.0f);
    EXPECT_GT(grid->tree().getValue(openvdb::Coord(0, 22, 0)), 0.0f);

    // adaptivity: fewer triangles
    const std::string low = (dir / "low.obj").string();
    const CliRun a = runCli(dir, {"sdf-to-mesh", vdb, low, "--adaptivity", "0.5", "--quiet"});
    ASSERT_EQ(a.code, 0) << a.command << "\n" << a.err;
    EXPECT_LT(levelforge::readMesh(low).triangleCount(), triangles / 2 + triangles / 10);
}

TEST(CliMeshSlice, SdfToMeshOfAFogVolumeUsesIsoOneHalf)
{
    const fs::path dir = scratchDir("cli_sdf_to_mesh_fog");
    openvdb::initialize();
    auto fog = openvdb::FloatGrid::create(0.0f);
    fog->setTransform(openvdb::math::Transform::createLinearTransform(0.05));
    fog->setGridClass(openvdb::GRID_FOG_VOLUME);
    fog->setName("density");
    auto acc = fog->getAccessor();
    for (int i = -26; i <= 26; ++i)
        for (int j = -26; j <= 26; ++j)
            for (int k = -26; k <= 26; ++k) {
                const double d = fog->indexToWorld(openvdb::Coord(i, j, k)).length() - 1.0;
                const double rho = std::clamp(0.5 - d / 0.2, 0.0, 1.0);
                if (rho > 0.0) acc.setValue(openvdb::Coord(i, j, k), float(rho));
            }
    const std::string vdb = (dir / "fog.vdb").string();
    levelforge::writeGridsAtomic(vdb, openvdb::GridPtrVec{fog});
    const std::string out = (dir / "fog.obj").string();
    const CliRun r = runCli(dir, {"sdf-to-mesh", vdb, out, "--quiet"});
    ASSERT_EQ(r.code, 0) << r.command << "\n" << r.err;
    EXPECT_NE(r.out.find("fog volume"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("isovalue 0.5"), std::string::npos) << r.out;
    const auto mesh = levelforge::readMesh(out);
    EXPECT_NEAR(levelforge::signedVolume(mesh) / (4.0 / 3.0 * M_PI), 1.0, 0.01);
}

TEST(CliMeshSlice, SliceWritesThePictureItDescribes)
{
    const fs::path dir = scratchDir("cli_slice");
    const std::string vdb = (dir / "sphere.vdb").string();
    writeSphere(vdb);
    const std::string png = (dir / "y.png").string();
    CliRun r = runCli(dir, {"slice", vdb, png, "--axis", "y", "--pixels-per-voxel", "4", "--quiet"});
    ASSERT_EQ(r.code, 0) << r.command << "\n" << r.err;
    EXPECT_NE(r.out.find("slice y = 0"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("45 x 45 voxels at 4 px per voxel"), std::string::npos) << r.out;
    const auto size = pngSize(png);
    EXPECT_NE(r.out.find("image " + std::to_string(size[0]) + " x " + std::to_string(size[1])), std::string::npos)
        << r.out;
    EXPECT_GE(size[0], 45u * 4u);
    EXPECT_GT(size[1], 45u * 4u);

    // --world, --units world
    r = runCli(dir, {"slice", vdb, png, "--axis", "x", "--world", "0.5", "--units", "world", "--quiet"});
    ASSERT_EQ(r.code, 0) << r.command << "\n" << r.err;
    EXPECT_NE(r.out.find("slice x = 10 (world 0.5)"), std::string::npos) << r.out;

    // the error heat map of levelforge's exact level set of builtin:sphere against the same mesh
    const std::string exact = (dir / "exact.vdb").string();
    r = runCli(dir, {"mesh-to-sdf", "builtin:sphere", exact, "--voxel-size", "0.05", "--quiet"});
    ASSERT_EQ(r.code, 0) << r.command << "\n" << r.err;
    const std::string err = (dir / "err.png").string();
    r = runCli(dir, {"slice", exact, err, "--error-against", "builtin:sphere", "--quiet"});
    ASSERT_EQ(r.code, 0) << r.command << "\n" << r.err;
    EXPECT_LT(numberAfter(r.out, ": max "), 1e-3) << r.out; // NaN (no such line) fails too
    EXPECT_NE(r.out.find("error against"), std::string::npos) << r.out;
    EXPECT_GT(pngSize(err)[0], 0u);
    // the analytic sphere against the icosphere mesh: the facets lie up to ~0.02 voxel inside the sphere
    r = runCli(dir, {"slice", vdb, err, "--error-against", "builtin:sphere", "--quiet"});
    ASSERT_EQ(r.code, 0) << r.command << "\n" << r.err;
    EXPECT_GT(numberAfter(r.out, ": max "), 0.005) << r.out;
    EXPECT_LT(numberAfter(r.out, ": max "), 0.05) << r.out;
}

TEST(CliMeshSlice, BadInputsGiveOneErrorLineAndNoOutput)
{
    const fs::path dir = scratchDir("cli_mesh_slice_bad");
    const std::string vdb = (dir / "sphere.vdb").string();
    writeSphere(vdb);
    const std::string png = (dir / "out.png").string();
    const std::string obj = (dir / "out.obj").string();

    // a slice outside the grid
    expectCleanFailure(runCli(dir, {"slice", vdb, png, "--index", "40", "--quiet"}), png, "outside the active");
    expectCleanFailure(runCli(dir, {"slice", vdb, png, "--axis", "x", "--world", "-3", "--quiet"}), png,
                       "outside the active");
    expectCleanFailure(runCli(dir, {"slice", vdb, png, "--index", "1", "--world", "0", "--quiet"}), png, "--world");
    // unknown extensions
    const std::string jpg = (dir / "out.jpg").string();
    expectCleanFailure(runCli(dir, {"slice", vdb, jpg, "--quiet"}), jpg, "unknown extension '.jpg'");
    const std::string xyz = (dir / "out.xyz").string();
    expectCleanFailure(runCli(dir, {"sdf-to-mesh", vdb, xyz, "--quiet"}), xyz, "unknown extension '.xyz'");
    // no level set: a file with a vector grid only
    openvdb::initialize();
    auto vec = openvdb::Vec3SGrid::create();
    vec->tree().setValue(openvdb::Coord(0), openvdb::Vec3s(1, 0, 0));
    vec->setName("velocity");
    const std::string vecPath = (dir / "vec.vdb").string();
    levelforge::writeGridsAtomic(vecPath, openvdb::GridPtrVec{vec});
    expectCleanFailure(runCli(dir, {"slice", vecPath, png, "--quiet"}), png, "no float level-set grid");
    expectCleanFailure(runCli(dir, {"sdf-to-mesh", vecPath, obj, "--quiet"}), obj, "no float level set or fog volume");
    expectCleanFailure(runCli(dir, {"sdf-to-mesh", vdb, obj, "--grid-name", "nope", "--quiet"}), obj, "'nope'");
    // an empty level set
    auto empty = openvdb::FloatGrid::create(0.15f);
    empty->setGridClass(openvdb::GRID_LEVEL_SET);
    empty->setName("surface");
    const std::string emptyPath = (dir / "empty.vdb").string();
    levelforge::writeGridsAtomic(emptyPath, openvdb::GridPtrVec{empty});
    expectCleanFailure(runCli(dir, {"slice", emptyPath, png, "--quiet"}), png, "no active values");
    expectCleanFailure(runCli(dir, {"sdf-to-mesh", emptyPath, obj, "--quiet"}), obj, "no surface");
    // bad parameter values and a missing mesh for the error map
    expectCleanFailure(runCli(dir, {"sdf-to-mesh", vdb, obj, "--adaptivity", "2", "--quiet"}), obj, "--adaptivity");
    expectCleanFailure(runCli(dir, {"slice", vdb, png, "--pixels-per-voxel", "0", "--quiet"}), png,
                       "--pixels-per-voxel");
    const std::string missing = (dir / "missing.obj").string();
    expectCleanFailure(runCli(dir, {"slice", vdb, png, "--error-against", missing, "--quiet"}), png, missing);
    // nothing else was left in the folder (no temporary files)
    for (const auto& e : fs::directory_iterator(dir)) {
        const std::string name = e.path().filename().string();
        EXPECT_TRUE(name == "sphere.vdb" || name == "vec.vdb" || name == "empty.vdb") << name;
    }
}

#endif // LEVELFORGE_CLI_PATH
