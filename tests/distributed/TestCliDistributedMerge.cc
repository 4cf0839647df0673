// SPDX-License-Identifier: Apache-2.0
// `mpirun -n K levelforge mesh-to-sdf --distributed --distributed-output per-rank`, then
// `levelforge merge`: the merged file equals the single-process file bit for bit (tree, tiles,
// metadata) for K = 1..4, with the interior fill and with empty ranks; a failure on any rank, early
// or after the pieces were written, leaves no manifest and no piece; a bad manifest or a missing
// piece makes merge fail with one error line and no output. Skipped without MPI (merge itself is
// then still tested on pieces written in one process, TestDistributedMerge.cc).
#include "TestUtil.h"
#include "distributed/GridIdentity.h"
#include "distributed/MpiRunner.h"
#include "distributed/PieceWriter.h"
#include "tools/CliRunner.h"

#include <levelforge/distributed/DistributedMeshToSdf.h>
#include <levelforge/reference/MeshShapes.h>

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

namespace fs = std::filesystem;
using namespace levelforge_test;

#if defined(LEVELFORGE_CLI_PATH)
namespace {

/// The files of @p dir whose names start with "out." (the output, its pieces, its manifest).
std::vector<std::string> outputFiles(const fs::path& dir)
{
    std::vector<std::string> names;
    for (const auto& e : fs::directory_iterator(dir))
        if (e.path().filename().string().rfind("out.", 0) == 0) names.push_back(e.path().filename().string());
    std::sort(names.begin(), names.end());
    return names;
}

/// Converts @p mesh alone, then per rank under mpirun on each of @p rankCounts and merges: every
/// merged file must equal the single-process one.
void expectMergedIdentical(const std::string& name, const std::string& mesh, std::vector<std::string> options,
                           std::vector<int> rankCounts)
{
    const fs::path dir = scratchDir("distributed_merge_" + name);
    std::vector<std::string> single{"mesh-to-sdf", mesh, (dir / "single.vdb").string(), "--quiet"};
    single.insert(single.end(), options.begin(), options.end());
    const CliRun s = runLevelforge(dir / "single", single);
    ASSERT_EQ(s.code, 0) << s.err;
    const openvdb::FloatGrid::Ptr reference = readSingleFloatGrid((dir / "single.vdb").string());
    ASSERT_TRUE(reference);
    ASSERT_GT(reference->activeVoxelCount(), 1000u);
    for (int ranks : rankCounts) {
        const fs::path sub = dir / ("k" + std::to_string(ranks));
        fs::create_directories(sub);
        const std::string out = (sub / "out.vdb").string();
        std::vector<std::string> args{"mesh-to-sdf", mesh, out, "--distributed", "--distributed-output", "per-rank",
                                      "--quiet"};
        args.insert(args.end(), options.begin(), options.end());
        const CliRun r = runMpi(sub, ranks, cli(args));
        ASSERT_EQ(r.code, 0) << r.command << "\n" << r.err;
        EXPECT_EQ(countLines(r.out, "levelforge: wrote"), 1) << "only rank 0 prints:\n" << r.out;
        // the manifest and one piece per rank, no .vdb of the output yet
        std::vector<std::string> expect{"out.vdb.manifest.json"};
        for (int k = 0; k < ranks; ++k) expect.push_back("out.rank000" + std::to_string(k) + ".vdb");
        std::sort(expect.begin(), expect.end());
        EXPECT_EQ(outputFiles(sub), expect) << ranks << " ranks";
        const CliRun m = runLevelforge(sub / "merge", {"merge", out + ".manifest.json", out, "--quiet"});
        ASSERT_EQ(m.code, 0) << m.err;
        EXPECT_NE(m.out.find("merged: " + std::to_string(ranks) + (ranks == 1 ? " piece" : " pieces")),
                  std::string::npos)
            << m.out;
        const openvdb::FloatGrid::Ptr g = readSingleFloatGrid(out);
        ASSERT_TRUE(g) << out;
        EXPECT_EQ(gridDifference(*reference, *g), "") << name << ", " << ranks << " ranks";
    }
}

} // namespace

TEST(CliDistributedMerge, TorusKnotPerRankMergedIdenticalOnOneToFourRanks)
{
    LF_NEED_MPI();
    expectMergedIdentical("knot", "builtin:torus-knot", {"--voxel-count", "120", "--brick-size", "16"}, {1, 2, 3, 4});
}

TEST(CliDistributedMerge, FillInteriorAndUnequalWidthsMergedIdentical)
{
    LF_NEED_MPI();
    expectMergedIdentical("knot_fill", "builtin:torus-knot",
                          {"--voxel-count", "300", "--exterior-band", "4", "--interior-band", "2", "--fill-interior"},
                          {2, 3});
}

TEST(CliDistributedMerge, EmptyRanksMergedIdentical)
{
    LF_NEED_MPI();
    const fs::path dir = scratchDir("distributed_merge_cube_mesh");
    // a cube from 0.2 to 0.6 at voxel size 0.01: all in brick [0, 127], so two of three ranks are empty
    std::ofstream obj(dir / "cube.obj");
    obj << "v 0.2 0.2 0.2\nv 0.6 0.2 0.2\nv 0.6 0.6 0.2\nv 0.2 0.6 0.2\n"
           "v 0.2 0.2 0.6\nv 0.6 0.2 0.6\nv 0.6 0.6 0.6\nv 0.2 0.6 0.6\n"
           "f 1 4 3\nf 1 3 2\nf 5 6 7\nf 5 7 8\nf 1 2 6\nf 1 6 5\nf 2 3 7\nf 2 7 6\nf 3 4 8\nf 3 8 7\nf 4 1 5\nf 4 5 8\n";
    obj.close();
    expectMergedIdentical("cube", (dir / "cube.obj").string(), {"--voxel-size", "0.01", "--fill-interior"}, {3});
}

TEST(CliDistributedMerge, UnwritableOutputLeavesNoManifestAndNoPiece)
{
    LF_NEED_MPI();
    const fs::path dir = scratchDir("distributed_merge_unwritable");
    // no such directory: every rank's check fails
    const std::string missing = (dir / "no_such_dir" / "out.vdb").string();
    CliRun r = runMpi(dir, 3, cli({"mesh-to-sdf", "builtin:torus-knot", missing, "--voxel-count", "64",
                                   "--distributed", "--distributed-output", "per-rank", "--quiet"}));
    EXPECT_NE(r.code, 0);
    EXPECT_EQ(countLines(r.err, "levelforge: error:"), 1) << r.err;
    EXPECT_FALSE(fs::exists(dir / "no_such_dir"));
    // rank 2's piece cannot be written (a directory is in its place): one line naming rank 2
    const fs::path sub = dir / "blocked";
    fs::create_directories(sub / "out.rank0002.vdb");
    const std::string out = (sub / "out.vdb").string();
    r = runMpi(sub, 3, cli({"mesh-to-sdf", "builtin:torus-knot", out, "--voxel-count", "64", "--distributed",
                            "--distributed-output", "per-rank", "--quiet"}));
    EXPECT_NE(r.code, 0);
    EXPECT_EQ(countLines(r.err, "levelforge: error:"), 1) << r.err;
    EXPECT_NE(r.err.find("rank 2 of 3"), std::string::npos) << r.err;
    EXPECT_EQ(outputFiles(sub), std::vector<std::string>{"out.rank0002.vdb"}) << "only the obstacle is left";
}

TEST(CliDistributedMerge, LateFailureRemovesEveryWrittenPiece)
{
    LF_NEED_MPI();
    // failures injected after pieces were written (LEVELFORGE_DISTRIBUTED_INJECT): rank 1 right
    // after its own piece, then rank 0's manifest after every piece
    for (const std::string inject : {"piece:1", "manifest"}) {
        const fs::path dir = scratchDir("distributed_merge_late_" + std::string(inject == "manifest" ? "m" : "p"));
        // an earlier run's manifest at the same place is removed too (its pieces are being replaced)
        std::ofstream(dir / "out.vdb.manifest.json") << "{}";
        const CliRun r = runMpi(dir, 3,
                                cli({"mesh-to-sdf", "builtin:torus-knot", (dir / "out.vdb").string(), "--voxel-count",
                                     "64", "--distributed", "--distributed-output", "per-rank", "--quiet"}),
                                "LEVELFORGE_DISTRIBUTED_INJECT=" + inject);
        EXPECT_NE(r.code, 0) << inject;
        EXPECT_EQ(countLines(r.err, "levelforge: error:"), 1) << r.err;
        EXPECT_NE(r.err.find("injected failure"), std::string::npos) << r.err;
        EXPECT_EQ(outputFiles(dir), std::vector<std::string>{}) << inject << ": no manifest, no piece";
    }
}

TEST(CliDistributedMerge, BadManifestOrMissingPieceWritesNothing)
{
    LF_NEED_MPI();
    const fs::path dir = scratchDir("distributed_merge_bad");
    const std::string out = (dir / "out.vdb").string(), manifest = out + ".manifest.json";
    const CliRun r = runMpi(dir, 2, cli({"mesh-to-sdf", "builtin:torus-knot", out, "--voxel-count", "64",
                                         "--distributed", "--distributed-output", "per-rank", "--quiet"}));
    ASSERT_EQ(r.code, 0) << r.err;
    const std::string merged = (dir / "merged.vdb").string();
    // a corrupted manifest
    const std::string text = readText(manifest);
    std::ofstream(dir / "bad.json") << text.substr(0, text.size() - 20);
    CliRun m = runLevelforge(dir / "m1", {"merge", (dir / "bad.json").string(), merged, "--quiet"});
    expectCleanFailure(m, merged, "bad.json");
    // a missing piece
    fs::rename(dir / "out.rank0001.vdb", dir / "away.vdb");
    m = runLevelforge(dir / "m2", {"merge", manifest, merged, "--quiet"});
    expectCleanFailure(m, merged, "out.rank0001.vdb");
    EXPECT_NE(m.err.find("no such file"), std::string::npos) << m.err;
    fs::rename(dir / "away.vdb", dir / "out.rank0001.vdb");
    m = runLevelforge(dir / "m3", {"merge", manifest, merged, "--quiet"});
    EXPECT_EQ(m.code, 0) << m.err;
    EXPECT_TRUE(fs::exists(merged));
}
#endif

#if defined(LEVELFORGE_CLI_PATH)
TEST(CliDistributedMerge, MergeOperatorNeedsNoMpi)
{
    // pieces written in this process (as 3 ranks would), merged by the program: with or without MPI
    const fs::path dir = scratchDir("distributed_merge_no_mpi");
    const CliRun s = runLevelforge(dir / "single", {"mesh-to-sdf", "builtin:torus-knot", (dir / "single.vdb").string(),
                                                    "--voxel-count", "96", "--fill-interior", "--quiet"});
    ASSERT_EQ(s.code, 0) << s.err;
    levelforge::MeshToSdfOptions o;
    o.voxelCount = 96;
    o.fillInterior = true;
    const std::string manifest = writePieces(levelforge::makeBuiltinMesh("builtin:torus-knot"), o, 3, 4, dir);
    const std::string out = (dir / "merged.vdb").string();
    const CliRun m = runLevelforge(dir / "merge", {"merge", manifest, out, "--quiet"});
    ASSERT_EQ(m.code, 0) << m.err;
    EXPECT_EQ(countLines(m.out, "levelforge: wrote " + out), 1) << m.out;
    const openvdb::FloatGrid::Ptr a = readSingleFloatGrid((dir / "single.vdb").string()), b = readSingleFloatGrid(out);
    ASSERT_TRUE(a && b);
    EXPECT_EQ(gridDifference(*a, *b), "");
    // the in-memory slot of a pipeline is no manifest
    const CliRun u = runLevelforge(dir / "slot", {"merge", "@pieces", out + ".2.vdb"});
    EXPECT_NE(u.code, 0);
    EXPECT_FALSE(fs::exists(out + ".2.vdb"));
}

TEST(CliDistributedMerge, PerRankOutputNeedsDistributed)
{
    const fs::path dir = scratchDir("distributed_merge_usage");
    const CliRun r = runLevelforge(dir / "run", {"mesh-to-sdf", "builtin:torus-knot", (dir / "o.vdb").string(),
                                                 "--voxel-count", "32", "--distributed-output", "per-rank"});
    EXPECT_EQ(r.code, 2) << r.err;
    EXPECT_NE(r.err.find("--distributed-output is an option of --distributed"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(dir / "o.vdb"));
}
#endif
