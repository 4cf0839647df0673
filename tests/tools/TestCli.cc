// SPDX-License-Identifier: Apache-2.0
// End-to-end tests of the `levelforge` executable: real processes, real files.
#include "CliRunner.h"
#include "TestUtil.h"

#include <levelforge/io/MeshIO.h>
#include <levelforge/reference/MeshShapes.h>
#include <levelforge/io/VdbIO.h>

#include <openvdb/openvdb.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <sys/wait.h>
#include <fcntl.h>
#include <unistd.h>

namespace fs = std::filesystem;
using levelforge_test::scratchDir;

#ifdef LEVELFORGE_CLI_PATH

using levelforge_test::countLines;

namespace {

using levelforge_test::CliRun;
using levelforge_test::readText;
using levelforge_test::runLevelforge;
std::string quote(const std::string& s) { return levelforge_test::shellQuote(s); }

std::vector<std::string> listDir(const fs::path& dir)
{
    std::vector<std::string> names;
    for (const auto& entry : fs::directory_iterator(dir)) names.push_back(entry.path().filename());
    std::sort(names.begin(), names.end());
    return names;
}

/// Unit icosphere and a box as OBJ files in `dir`.
std::string writeSphere(const fs::path& dir)
{
    const std::string path = (dir / "sphere.obj").string();
    levelforge::writeMesh(levelforge::makeIcosphere(levelforge::Vec3d(0.0), 1.0, 3), path);
    return path;
}

std::string writeText(const fs::path& path, const std::string& text)
{
    std::ofstream(path) << text;
    return path.string();
}

openvdb::FloatGrid::Ptr readSingleLevelSet(const std::string& path) { return levelforge_test::readSingleFloatGrid(path); }

} // namespace

TEST(Cli, MeshToSdfWritesALevelSetWithMetadata)
{
    const fs::path dir = scratchDir("cli_sphere");
    const std::string mesh = writeSphere(dir);
    const std::string out = (dir / "sphere.vdb").string();
    const CliRun r = runLevelforge(dir, {"mesh-to-sdf", mesh, out, "--voxel-size", "0.05"});
    ASSERT_EQ(r.code, 0) << r.command << "\n" << r.err;
    EXPECT_EQ(countLines(r.err, "levelforge: error:"), 0) << r.err;
    EXPECT_NE(r.out.find(out), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("active voxels"), std::string::npos) << r.out;
    EXPECT_EQ(listDir(dir), (std::vector<std::string>{"sphere.obj", "sphere.vdb"}));

    auto grid = readSingleLevelSet(out);
    ASSERT_TRUE(grid);
    EXPECT_EQ(grid->getName(), "surface");
    EXPECT_EQ(grid->getGridClass(), openvdb::GRID_LEVEL_SET);
    EXPECT_NEAR(grid->voxelSize()[0], 0.05, 1e-12);
    EXPECT_GT(grid->activeVoxelCount(), 1000u);
    EXPECT_NEAR(grid->background(), 3 * 0.05, 1e-6);
    EXPECT_FLOAT_EQ(grid->metaValue<float>("levelforge:exterior_band_voxels"), 3.0f);
    EXPECT_FLOAT_EQ(grid->metaValue<float>("levelforge:interior_band_voxels"), 3.0f);
    EXPECT_NE(grid->metaValue<std::string>("levelforge:source").find("sphere.obj"),
              std::string::npos);
    EXPECT_EQ(grid->metaValue<std::string>("levelforge:generator"),
              levelforge::generatorString());
    EXPECT_FALSE(grid->metaValue<std::string>("levelforge:method").empty());
    // Inside is negative, outside positive (sphere of radius ~1 around the origin).
    EXPECT_LT(grid->tree().getValue(openvdb::Coord(0, 0, 0)), 0.0f);
    EXPECT_GT(grid->tree().getValue(openvdb::Coord(40, 0, 0)), 0.0f);
    const float nearSurface = grid->tree().getValue(openvdb::Coord(20, 0, 0)); // x = 1.0
    EXPECT_LT(std::abs(nearSurface), 0.05f);

    // `info` describes it.
    const CliRun info = runLevelforge(dir, {"info", out});
    ASSERT_EQ(info.code, 0) << info.err;
    for (const char* expected : {"grid 'surface'", "level set", "voxel size", "active voxels",
                                 "index bbox", "background", "band (voxels)", "memory",
                                 "levelforge:generator"}) {
        EXPECT_NE(info.out.find(expected), std::string::npos) << expected << "\n" << info.out;
    }
}

TEST(Cli, MeshToSdfOptions)
{
    const fs::path dir = scratchDir("cli_options");
    const std::string mesh = writeSphere(dir);
    const std::string out = (dir / "custom.vdb").string();
    const CliRun r = runLevelforge(dir, {"mesh-to-sdf", mesh, out, "--voxel-count", "32",
                                   "--exterior-band", "2", "--interior-band", "1.5",
                                   "--grid-name", "sdf", "--quiet", "--report"});
    ASSERT_EQ(r.code, 0) << r.command << "\n" << r.err;
    EXPECT_EQ(r.err.find("%"), std::string::npos) << "--quiet still printed progress: " << r.err;
    auto grid = readSingleLevelSet(out);
    ASSERT_TRUE(grid);
    EXPECT_EQ(grid->getName(), "sdf");
    EXPECT_FLOAT_EQ(grid->metaValue<float>("levelforge:exterior_band_voxels"), 2.0f);
    EXPECT_FLOAT_EQ(grid->metaValue<float>("levelforge:interior_band_voxels"), 1.5f);
    // 32 voxels along the longest axis of a ~2-unit-wide sphere.
    EXPECT_NEAR(grid->voxelSize()[0], 2.0 / 32.0, 0.01);
    EXPECT_NEAR(grid->background(), 2.0 * grid->voxelSize()[0], 1e-6);
    openvdb::CoordBBox bbox = grid->evalActiveVoxelBoundingBox();
    EXPECT_LE(bbox.dim().asVec3d().length(), std::sqrt(3.0) * 40.0);

    const CliRun info = runLevelforge(dir, {"info", out, "--grid", "sdf"});
    EXPECT_EQ(info.code, 0) << info.err;
    EXPECT_NE(info.out.find("grid 'sdf'"), std::string::npos) << info.out;
    const CliRun noGrid = runLevelforge(dir, {"info", out, "--grid", "nope"});
    EXPECT_EQ(noGrid.code, 1);
    EXPECT_EQ(countLines(noGrid.err, "levelforge: error:"), 1) << noGrid.err;
}

TEST(Cli, MeshToSdfWorldUnitBands)
{
    // --world-units reads the bands in world units: 0.15 and 0.1 at voxel size 0.05 are the
    // 3- and 2-voxel bands, voxel for voxel.
    const fs::path dir = scratchDir("cli_world_units");
    const std::string mesh = writeSphere(dir);
    const std::string voxels = (dir / "voxels.vdb").string(), world = (dir / "world.vdb").string();
    const CliRun a = runLevelforge(dir, {"mesh-to-sdf", mesh, voxels, "--voxel-size", "0.05", "--exterior-band",
                                         "3", "--interior-band", "2", "--quiet"});
    const CliRun b = runLevelforge(dir, {"mesh-to-sdf", mesh, world, "--voxel-size", "0.05", "--exterior-band",
                                         "0.15", "--interior-band", "0.1", "--world-units", "--quiet"});
    ASSERT_EQ(a.code, 0) << a.err;
    ASSERT_EQ(b.code, 0) << b.err;
    auto ga = readSingleLevelSet(voxels), gb = readSingleLevelSet(world);
    ASSERT_TRUE(ga && gb);
    EXPECT_FLOAT_EQ(gb->metaValue<float>("levelforge:exterior_band_voxels"), 3.0f);
    EXPECT_FLOAT_EQ(gb->metaValue<float>("levelforge:interior_band_voxels"), 2.0f);
    EXPECT_EQ(ga->activeVoxelCount(), gb->activeVoxelCount());
    auto acc = gb->getConstAccessor();
    uint64_t differ = 0;
    for (auto it = ga->cbeginValueOn(); it; ++it) {
        float v = 0.0f;
        if (!acc.probeValue(it.getCoord(), v) || v != *it) ++differ;
    }
    EXPECT_EQ(differ, 0u);
}

TEST(Cli, BuiltinMesh)
{
    const fs::path dir = scratchDir("cli_builtin");
    const std::string out = (dir / "knot.vdb").string();
    const CliRun r = runLevelforge(dir, {"mesh-to-sdf", "builtin:torus-knot", out, "--voxel-count", "48",
                                   "--quiet"});
    ASSERT_EQ(r.code, 0) << r.command << "\n" << r.err;
    auto grid = readSingleLevelSet(out);
    ASSERT_TRUE(grid);
    EXPECT_GT(grid->activeVoxelCount(), 0u);
    const CliRun bad = runLevelforge(dir, {"mesh-to-sdf", "builtin:teapot", (dir / "t.vdb").string()});
    EXPECT_NE(bad.code, 0);
    EXPECT_EQ(countLines(bad.err, "levelforge: error:"), 1) << bad.err;
    EXPECT_FALSE(fs::exists(dir / "t.vdb"));
}

TEST(Cli, FailuresExitNonZeroWithOneLineAndNoOutput)
{
    const fs::path dir = scratchDir("cli_failures");
    const fs::path inputs = dir / "inputs";
    const fs::path outputs = dir / "outputs";
    fs::create_directories(inputs);
    fs::create_directories(outputs);
    const std::string sphere = writeSphere(inputs);
    const std::string nanFile = writeText(inputs / "nan.obj",
                                          "v 0 0 0\nv 1 0 0\nv nan 1 0\nv 0 0 1\n"
                                          "f 1 2 3\nf 1 3 4\nf 1 4 2\nf 2 4 3\n");
    const std::string badIndex = writeText(inputs / "bad_index.obj",
                                           "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n");
    const std::string empty = writeText(inputs / "empty.obj", "");
    const std::string noFaces = writeText(inputs / "no_faces.obj", "v 0 0 0\nv 1 0 0\n");
    const std::string garbage = writeText(inputs / "garbage.stl", "this is not a mesh\n");
    { std::ofstream(dir / "plainfile") << "x"; }

    const std::string out = (outputs / "out.vdb").string();
    struct Case
    {
        std::string what;
        std::vector<std::string> args;
        std::string outputPath;
    };
    const std::vector<Case> cases = {
        {"missing input", {"mesh-to-sdf", (inputs / "missing.obj").string(), out}, out},
        {"NaN vertex", {"mesh-to-sdf", nanFile, out, "--voxel-size", "0.1"}, out},
        {"bad index", {"mesh-to-sdf", badIndex, out, "--voxel-size", "0.1"}, out},
        {"empty file", {"mesh-to-sdf", empty, out}, out},
        {"no faces", {"mesh-to-sdf", noFaces, out}, out},
        {"not a mesh", {"mesh-to-sdf", garbage, out}, out},
        {"voxel size 0", {"mesh-to-sdf", sphere, out, "--voxel-size", "0"}, out},
        {"voxel size -1", {"mesh-to-sdf", sphere, out, "--voxel-size", "-1"}, out},
        {"voxel size nan", {"mesh-to-sdf", sphere, out, "--voxel-size", "nan"}, out},
        {"huge exterior band", {"mesh-to-sdf", sphere, out, "--exterior-band", "1e9"}, out},
        {"huge interior band", {"mesh-to-sdf", sphere, out, "--interior-band", "1e9"}, out},
        {"too many voxels", {"mesh-to-sdf", sphere, out, "--voxel-size", "1e-5", "--quiet"}, out},
        {"both voxel size and count",
         {"mesh-to-sdf", sphere, out, "--voxel-size", "0.1", "--voxel-count", "10"}, out},
        {"missing output directory",
         {"mesh-to-sdf", sphere, (outputs / "no" / "dir" / "out.vdb").string(), "--voxel-size",
          "0.1"},
         (outputs / "no" / "dir" / "out.vdb").string()},
        {"output under a regular file",
         {"mesh-to-sdf", sphere, (dir / "plainfile" / "out.vdb").string(), "--voxel-size", "0.1"},
         (dir / "plainfile" / "out.vdb").string()},
        {"output is a directory", {"mesh-to-sdf", sphere, outputs.string(), "--voxel-size", "0.1"},
         ""},
        {"info on a missing file", {"info", (inputs / "missing.vdb").string()}, ""},
        {"info on a mesh", {"info", sphere}, ""},
    };
    const std::vector<std::string> inputsBefore = listDir(inputs);
    for (const Case& c : cases) {
        const CliRun r = runLevelforge(dir, c.args);
        EXPECT_NE(r.code, 0) << c.what << ": " << r.command;
        EXPECT_TRUE(r.code == 1 || r.code == 2) << c.what << ": exit " << r.code << "\n" << r.err;
        EXPECT_EQ(countLines(r.err, "levelforge: error: "), 1) << c.what << "\n" << r.err;
        EXPECT_EQ(r.err.find("terminate called"), std::string::npos) << c.what << "\n" << r.err;
        if (!c.outputPath.empty()) {
            EXPECT_FALSE(fs::exists(c.outputPath)) << c.what;
        }
        EXPECT_TRUE(fs::is_empty(outputs)) << c.what << ": output directory is not empty";
    }
    EXPECT_EQ(listDir(inputs), inputsBefore);
}

TEST(Cli, InterruptedRunWritesNothing)
{
    const fs::path dir = scratchDir("cli_interrupt");
    const std::string mesh = writeSphere(dir);
    const std::string out = (dir / "slow.vdb").string();
    // A conversion that takes far longer than a second, stopped by SIGTERM after half a second.
    const std::string script = quote(LEVELFORGE_CLI_PATH) + " mesh-to-sdf " + quote(mesh) + " " +
                               quote(out) + " --voxel-size 0.0015 --quiet & pid=$!; sleep 0.5; " +
                               "kill -TERM $pid; wait $pid";
    const fs::path errFile = dir / "stderr.txt";
    const int status = std::system(("bash -c " + quote(script) + " 2>" + quote(errFile.string())).c_str());
    ASSERT_TRUE(WIFEXITED(status));
    const std::string err = readText(errFile);
    EXPECT_EQ(WEXITSTATUS(status), 130) << err;
    EXPECT_EQ(countLines(err, "levelforge: error: interrupted"), 1) << err;
    EXPECT_FALSE(fs::exists(out));
    EXPECT_EQ(listDir(dir), (std::vector<std::string>{"sphere.obj", "stderr.txt"}));
}

TEST(Cli, OutputThatIsAnInputIsRefused)
{
    const fs::path dir = scratchDir("cli_same_file");
    const std::string mesh = (dir / "m.ply").string();
    levelforge::writeMesh(levelforge::makeIcosphere(levelforge::Vec3d(0.0), 1.0, 2), mesh);
    const std::string before = readText(mesh);
    ASSERT_FALSE(before.empty());
    fs::create_symlink("m.ply", dir / "link.vdb");
    fs::create_hard_link(mesh, dir / "hard.vdb");
    const std::vector<std::string> names = listDir(dir);

    for (const std::string& out : {mesh, (dir / "link.vdb").string(), (dir / "hard.vdb").string(),
                                   (dir / "." / "m.ply").string()}) {
        const CliRun r = runLevelforge(dir, {"mesh-to-sdf", mesh, out, "--voxel-count", "16",
                                             "--quiet"});
        EXPECT_NE(r.code, 0) << r.command;
        EXPECT_EQ(countLines(r.err, "levelforge: error: "), 1) << r.err;
        EXPECT_NE(r.err.find("output '" + out + "' is the same file as the input; choose another name"),
                  std::string::npos)
            << r.err;
        EXPECT_EQ(readText(mesh), before) << out << ": the input was changed";
        EXPECT_EQ(listDir(dir), names) << out;
    }
    EXPECT_TRUE(fs::is_symlink(dir / "link.vdb"));

    // Two inputs: the message names the one at fault.
    const std::string a = (dir / "a.vdb").string();
    ASSERT_EQ(runLevelforge(dir, {"mesh-to-sdf", "builtin:sphere", a, "--voxel-count", "16",
                                  "--quiet"}).code, 0);
    const std::string aBefore = readText(a);
    const CliRun csg = runLevelforge(dir, {"csg", a, a, a});
    EXPECT_NE(csg.code, 0);
    EXPECT_EQ(countLines(csg.err, "levelforge: error: "), 1) << csg.err;
    EXPECT_NE(csg.err.find("is the same file as the input <a>"), std::string::npos) << csg.err;
    EXPECT_EQ(readText(a), aBefore);
}

TEST(Cli, OutputToDevNullDiscardsIt)
{
    struct stat before {};
    ASSERT_EQ(::stat("/dev/null", &before), 0);
    const fs::path dir = scratchDir("cli_dev_null");
    const CliRun r = runLevelforge(dir, {"mesh-to-sdf", "builtin:sphere", "/dev/null",
                                         "--voxel-count", "16", "--quiet"});
    EXPECT_EQ(r.code, 0) << r.command << "\n" << r.err;
    EXPECT_EQ(countLines(r.err, "levelforge: error: "), 0) << r.err;
    struct stat after {};
    ASSERT_EQ(::lstat("/dev/null", &after), 0);
    EXPECT_TRUE(S_ISCHR(after.st_mode)) << "/dev/null was replaced";
    EXPECT_EQ(after.st_rdev, before.st_rdev);
    EXPECT_EQ(after.st_ino, before.st_ino);
}

TEST(Cli, OutputThatIsNotARegularFileIsRefused)
{
    const fs::path dir = scratchDir("cli_not_regular");
    const fs::path outputs = dir / "outputs";
    fs::create_directories(outputs / "sub.vdb");
    const fs::path fifo = outputs / "pipe.vdb";
    ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);

    struct Case
    {
        std::string path, what;
    };
    std::vector<Case> cases = {{(outputs / "sub.vdb").string(), "is a directory"},
                               {outputs.string(), "is a directory"},
                               {fifo.string(), "is a FIFO"}};
    // A character device node of our own (root only): /dev/full's numbers, in the scratch dir.
    const fs::path device = outputs / "full.vdb";
    if (::mknod(device.c_str(), S_IFCHR | 0666, makedev(1, 7)) == 0) {
        cases.push_back({device.string(), "is a character device"});
    }
    const std::vector<std::string> names = listDir(outputs);
    for (const Case& c : cases) {
        // `timeout` only keeps a broken build from hanging the suite on the FIFO; no timing is
        // asserted.
        const fs::path errFile = dir / "stderr.txt";
        const std::string command = "timeout 300 " + quote(LEVELFORGE_CLI_PATH) +
                                    " mesh-to-sdf builtin:sphere " + quote(c.path) +
                                    " --voxel-count 16 --quiet </dev/null >/dev/null 2>" +
                                    quote(errFile.string());
        const int status = std::system(command.c_str());
        ASSERT_TRUE(WIFEXITED(status)) << command;
        const int code = WEXITSTATUS(status);
        const std::string err = readText(errFile);
        EXPECT_NE(code, 0) << c.path;
        EXPECT_NE(code, 124) << c.path << ": the command hung";
        EXPECT_EQ(countLines(err, "levelforge: error: "), 1) << err;
        EXPECT_NE(err.find("'" + c.path + "' " + c.what), std::string::npos) << err;
        EXPECT_NE(err.find("not a regular file"), std::string::npos) << err;
        EXPECT_EQ(listDir(outputs), names) << c.path;
    }
    struct stat st {};
    ASSERT_EQ(::lstat(fifo.c_str(), &st), 0);
    EXPECT_TRUE(S_ISFIFO(st.st_mode));
    if (::lstat(device.c_str(), &st) == 0) {
        EXPECT_TRUE(S_ISCHR(st.st_mode));
    }
    EXPECT_TRUE(fs::is_directory(outputs / "sub.vdb"));
}

TEST(Cli, StaleTemporaryFilesOfTheOutputAreRemoved)
{
    const fs::path dir = scratchDir("cli_stale_tmp");
    const pid_t child = ::fork(); // a PID that no longer exists
    if (child == 0) ::_exit(0);
    ASSERT_GT(child, 0);
    ::waitpid(child, nullptr, 0);
    const std::string stale = ".out.vdb." + std::to_string(child) + "-0123abcd.tmp";
    const std::string other = ".other.vdb." + std::to_string(child) + "-0123abcd.tmp";
    std::ofstream(dir / stale) << "";
    std::ofstream(dir / other) << "";
    const CliRun r = runLevelforge(dir, {"mesh-to-sdf", "builtin:sphere", (dir / "out.vdb").string(),
                                         "--voxel-count", "16", "--quiet"});
    ASSERT_EQ(r.code, 0) << r.err;
    EXPECT_EQ(listDir(dir), (std::vector<std::string>{other, "out.vdb"}));
}

TEST(Cli, HelpAndUsage)
{
    const fs::path dir = scratchDir("cli_help");
    CliRun r = runLevelforge(dir, {"--help"});
    EXPECT_EQ(r.code, 0);
    EXPECT_NE(r.out.find("mesh-to-sdf"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("info"), std::string::npos) << r.out;
    r = runLevelforge(dir, {"mesh-to-sdf", "--help"});
    EXPECT_EQ(r.code, 0);
    for (const char* opt : {"--voxel-size", "--voxel-count", "--exterior-band", "--interior-band",
                            "--grid-name", "--quiet", "--report"}) {
        EXPECT_NE(r.out.find(opt), std::string::npos) << opt << "\n" << r.out;
    }
    r = runLevelforge(dir, {});
    EXPECT_EQ(r.code, 2);
    EXPECT_EQ(countLines(r.err, "levelforge: error: "), 1) << r.err;
    r = runLevelforge(dir, {"frobnicate"});
    EXPECT_EQ(r.code, 2);
    EXPECT_EQ(countLines(r.err, "levelforge: error: "), 1) << r.err;
}

#else
TEST(Cli, NotBuilt) { GTEST_SKIP() << "the levelforge executable is not part of this build"; }
#endif
