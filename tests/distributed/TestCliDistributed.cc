// SPDX-License-Identifier: Apache-2.0
// `mpirun -n K levelforge mesh-to-sdf --distributed`, the real program under OpenMPI: the file
// rank 0 writes equals the single-process run's bit for bit (tree and metadata) for K = 1..4, with
// empty ranks, with uneven bricks; a failure on one rank or at the write stops every rank with
// one error line and no file. Skipped when levelforge was built without MPI (then the
// --distributed error is checked instead).
#include "TestUtil.h"
#include "distributed/GridIdentity.h"
#include "distributed/MpiRunner.h"
#include "tools/CliRunner.h"

#include <levelforge/distributed/DistributedMeshToSdf.h>
#include <levelforge/io/MeshIO.h>
#include <levelforge/reference/MeshShapes.h>

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

namespace fs = std::filesystem;
using namespace levelforge_test;

#if defined(LEVELFORGE_CLI_PATH)
namespace {

/// Converts @p mesh once alone and under mpirun with 1..4 ranks; every output must be identical.
void expectIdenticalUnderMpi(const std::string& name, const std::string& mesh, std::vector<std::string> options,
                             std::vector<int> rankCounts = {1, 2, 3, 4})
{
    const fs::path dir = scratchDir("distributed_" + name);
    std::vector<std::string> single{"mesh-to-sdf", mesh, (dir / "single.vdb").string(), "--quiet"};
    single.insert(single.end(), options.begin(), options.end());
    const CliRun s = runLevelforge(dir / "single", single);
    ASSERT_EQ(s.code, 0) << s.err;
    const openvdb::FloatGrid::Ptr reference = readSingleFloatGrid((dir / "single.vdb").string());
    ASSERT_TRUE(reference);
    ASSERT_GT(reference->activeVoxelCount(), 1000u);
    for (int ranks : rankCounts) {
        const std::string out = (dir / ("mpi" + std::to_string(ranks) + ".vdb")).string();
        std::vector<std::string> args{"mesh-to-sdf", mesh, out, "--distributed", "--quiet"};
        args.insert(args.end(), options.begin(), options.end());
        const CliRun r = runMpi(dir, ranks, cli(args));
        ASSERT_EQ(r.code, 0) << r.command << "\n" << r.err;
        EXPECT_EQ(countLines(r.out, "levelforge: wrote"), 1) << "only rank 0 prints:\n" << r.out;
        EXPECT_NE(r.out.find("distributed: " + std::to_string(ranks) + (ranks == 1 ? " rank" : " ranks")),
                  std::string::npos)
            << r.out;
        const openvdb::FloatGrid::Ptr g = readSingleFloatGrid(out);
        ASSERT_TRUE(g) << out;
        EXPECT_EQ(gridDifference(*reference, *g), "") << name << ", " << ranks << " ranks";
    }
}

} // namespace

TEST(CliDistributed, TorusKnotIdenticalOnOneToFourRanks)
{
    LF_NEED_MPI();
    expectIdenticalUnderMpi("knot", "builtin:torus-knot", {"--voxel-count", "120", "--brick-size", "16"});
}

TEST(CliDistributed, DefaultBricksUnevenWidthsAndFillIdentical)
{
    LF_NEED_MPI();
    // 128-voxel bricks over a 300-voxel knot: a few bricks of very different loads
    expectIdenticalUnderMpi("knot_fill", "builtin:torus-knot",
                            {"--voxel-count", "300", "--exterior-band", "4", "--interior-band", "2", "--fill-interior"},
                            {2, 3});
}

TEST(CliDistributed, SharedDataMeshIdentical)
{
    LF_NEED_MPI();
    const std::string data = sharedDataDir();
    const std::string path = data + "/meshes/watertight/spot.obj";
    if (data.empty() || !fs::exists(path)) LF_SHARED_DATA_MISSING("no " << path);
    expectIdenticalUnderMpi("spot", path, {"--voxel-count", "160", "--brick-size", "32", "--sign", "pseudonormal"},
                            {2, 4});
}

TEST(CliDistributed, MeshInOneBrickLeavesRanksEmpty)
{
    LF_NEED_MPI();
    const fs::path dir = scratchDir("distributed_one_brick_mesh");
    // a cube from 0.2 to 0.6 at voxel size 0.01: voxels 17..63 with the band, all in brick [0, 127]
    std::ofstream obj(dir / "cube.obj");
    obj << "v 0.2 0.2 0.2\nv 0.6 0.2 0.2\nv 0.6 0.6 0.2\nv 0.2 0.6 0.2\n"
           "v 0.2 0.2 0.6\nv 0.6 0.2 0.6\nv 0.6 0.6 0.6\nv 0.2 0.6 0.6\n"
           "f 1 4 3\nf 1 3 2\nf 5 6 7\nf 5 7 8\nf 1 2 6\nf 1 6 5\nf 2 3 7\nf 2 7 6\nf 3 4 8\nf 3 8 7\nf 4 1 5\nf 4 5 8\n";
    obj.close();
    expectIdenticalUnderMpi("one_brick", (dir / "cube.obj").string(), {"--voxel-size", "0.01"}, {3});
    const CliRun r = runMpi(dir, 3, cli({"mesh-to-sdf", (dir / "cube.obj").string(), (dir / "r.vdb").string(),
                                         "--voxel-size", "0.01", "--distributed", "--quiet", "--report"}));
    ASSERT_EQ(r.code, 0) << r.err;
    EXPECT_NE(r.out.find("1 bricks"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("    2: 0, 0, 0, 0,"), std::string::npos) << "rank 2 has nothing:\n" << r.out;
}

TEST(CliDistributed, UnwritableOutputStopsEveryRankWithOneError)
{
    LF_NEED_MPI();
    const fs::path dir = scratchDir("distributed_unwritable");
    const std::string out = (dir / "no_such_dir" / "out.vdb").string();
    const CliRun r = runMpi(dir, 3, cli({"mesh-to-sdf", "builtin:torus-knot", out, "--voxel-count", "64",
                                         "--distributed", "--quiet"}));
    EXPECT_NE(r.code, 0);
    EXPECT_EQ(countLines(r.err, "levelforge: error:"), 1) << r.err;
    EXPECT_FALSE(fs::exists(out));
}

TEST(CliDistributed, OneRankThatCannotReadItsFileStopsEveryRank)
{
    LF_NEED_MPI();
    const fs::path dir = scratchDir("distributed_unreadable");
    // each rank reads knot<rank>.obj: rank 2's is missing
    const std::string mesh = (dir / "knot").string();
    levelforge::writeMesh(levelforge::makeBuiltinMesh("builtin:torus-knot"), mesh + "0.obj");
    fs::copy_file(mesh + "0.obj", mesh + "1.obj");
    const std::string out = (dir / "out.vdb").string();
    const std::string command =
        "sh -c " + shellQuote(cli({"mesh-to-sdf"}) + " " + shellQuote(mesh) + "\"$OMPI_COMM_WORLD_RANK\".obj " +
                              shellQuote(out) + " --voxel-count 64 --distributed --quiet");
    const CliRun r = runMpi(dir, 3, command);
    EXPECT_NE(r.code, 0);
    EXPECT_EQ(countLines(r.err, "levelforge: error:"), 1) << r.err;
    EXPECT_NE(r.err.find("rank 2 of 3"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(out));
}

TEST(CliDistributed, RefusesWhatIsNotDistributedYet)
{
    LF_NEED_MPI();
    const fs::path dir = scratchDir("distributed_refuse");
    const std::string out = (dir / "out.vdb").string();
    const CliRun r = runMpi(dir, 2, cli({"mesh-to-sdf", "builtin:torus-knot", out, "--voxel-count", "64",
                                         "--distributed", "--expansion", "sweep", "--quiet"}));
    EXPECT_NE(r.code, 0);
    EXPECT_EQ(countLines(r.err, "levelforge: error:"), 1) << r.err;
    EXPECT_NE(r.err.find("not yet --expansion sweep"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(out));
}

TEST(CliDistributed, WithoutMpiDistributedSaysHowToGetIt)
{
    if (levelforge::mpiAvailable()) GTEST_SKIP() << "built with MPI";
    const fs::path dir = scratchDir("distributed_nompi");
    const CliRun r = runLevelforge(dir / "run", {"mesh-to-sdf", "builtin:torus-knot", (dir / "o.vdb").string(),
                                                 "--voxel-count", "32", "--distributed"});
    EXPECT_NE(r.code, 0);
    EXPECT_EQ(countLines(r.err, "levelforge: error:"), 1) << r.err;
    EXPECT_NE(r.err.find("libopenmpi-dev"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(dir / "o.vdb"));
}
#endif

#if defined(LEVELFORGE_CLI_PATH)
TEST(CliDistributed, FrameSequencesAreRefused)
{
    // frames (in any order per rank with --jobs) would mix their collectives: one mesh per mpirun
    const fs::path dir = scratchDir("distributed_jobs");
    for (const char* jobs : {"1", "2"}) {
        const CliRun r = runLevelforge(dir / "run", {"mesh-to-sdf", "builtin:torus-knot", (dir / "o$F.vdb").string(),
                                                     "--voxel-count", "32", "--distributed", "--frames", "1-2",
                                                     "--jobs", jobs, "--quiet"});
        EXPECT_NE(r.code, 0);
        EXPECT_NE(r.err.find("not a --frames sequence"), std::string::npos) << r.err;
    }
    EXPECT_FALSE(fs::exists(dir / "o1.vdb"));
    EXPECT_FALSE(fs::exists(dir / "o2.vdb"));
}
#endif
