// SPDX-License-Identifier: Apache-2.0
// Issue 18, items 2-5: `levelforge run` pipelines, frame sequences on every operator, plugin
// operators, --report-json and progress, end to end through the real program.
#include "CliRunner.h"
#include "TestUtil.h"

#include "FrameRange.h"
#include "Interrupt.h"
#include "Operator.h"
#include "OperatorRegistry.h"

#include <levelforge/io/MeshIO.h>
#include <levelforge/io/VdbIO.h>
#include <levelforge/reference/MeshShapes.h>

#include <nlohmann/json.hpp>
#include <openvdb/openvdb.h>
#include <openvdb/tools/Interpolation.h>

#include <gtest/gtest.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

namespace fs = std::filesystem;
using levelforge_test::scratchDir;

namespace {

using levelforge::ops::FrameRange;
using levelforge::ops::hasFrameToken;
using levelforge::ops::parseFrameRange;
using levelforge::ops::substituteFrame;

TEST(FrameTokens, HoudiniAndPrintfTokens)
{
    EXPECT_EQ(substituteFrame("out_$F4.vdb", 7), "out_0007.vdb");
    EXPECT_EQ(substituteFrame("out_$F.vdb", 7), "out_7.vdb");
    EXPECT_EQ(substituteFrame("out_${F}_x.vdb", 12), "out_12_x.vdb");
    EXPECT_EQ(substituteFrame("out_%04d.vdb", 7), "out_0007.vdb");
    EXPECT_EQ(substituteFrame("out_%d.vdb", 240), "out_240.vdb");
    EXPECT_EQ(substituteFrame("a_$F2/b_%03d.obj", 5), "a_05/b_005.obj");
    EXPECT_EQ(substituteFrame("out_$F4.vdb", -7), "out_-007.vdb");
    EXPECT_EQ(substituteFrame("100%%_$F.vdb", 3), "100%_3.vdb"); // escapes only where tokens are
    EXPECT_EQ(substituteFrame("plain.vdb", 3), "plain.vdb");
    EXPECT_EQ(substituteFrame("$FPS.vdb", 3), "$FPS.vdb"); // another Houdini variable, not a frame
    EXPECT_FALSE(hasFrameToken("$FPS_100%.vdb"));
    EXPECT_TRUE(hasFrameToken("x$F"));
    EXPECT_TRUE(hasFrameToken("x%04d"));
}

TEST(FrameTokens, Ranges)
{
    FrameRange r = parseFrameRange("1-240:2");
    EXPECT_EQ(r.frames().size(), 120u);
    EXPECT_EQ(r.frames().front(), 1);
    EXPECT_EQ(r.frames().back(), 239);
    EXPECT_EQ(parseFrameRange("7").frames(), std::vector<int>{7});
    EXPECT_EQ(parseFrameRange("-2-1").frames(), (std::vector<int>{-2, -1, 0, 1}));
    EXPECT_EQ(parseFrameRange("1-240:2").text(), "1-240:2");
    for (const char* bad : {"", "a-b", "5-1", "1-10:0", "1-", "1-2000000000"})
        EXPECT_THROW(parseFrameRange(bad), levelforge::ops::UsageError) << bad;
}

TEST(CliProgressBar, BarWithPercentEtaAndDone)
{
    ::setenv("LEVELFORGE_PROGRESS", "bar", 1);
    testing::internal::CaptureStderr();
    {
        levelforge::ops::ProgressPrefixScope prefix("frame 3 (1/2): ");
        levelforge::ops::CliProgress progress(10, true);
        progress.start("band");
        std::this_thread::sleep_for(std::chrono::milliseconds(600)); // stages under 0.5 s print nothing
        EXPECT_FALSE(progress.wasInterrupted(50));
        progress.end();
    }
    const std::string err = testing::internal::GetCapturedStderr();
    ::unsetenv("LEVELFORGE_PROGRESS");
    EXPECT_NE(err.find("\rlevelforge: frame 3 (1/2): band [############------------]  50%  ETA"), std::string::npos) << err;
    EXPECT_NE(err.find("levelforge: frame 3 (1/2): band done ("), std::string::npos) << err;

    ::setenv("LEVELFORGE_PROGRESS", "plain", 1);
    testing::internal::CaptureStderr();
    {
        levelforge::ops::CliProgress progress(10, true);
        progress.start("band");
        std::this_thread::sleep_for(std::chrono::milliseconds(600));
        progress.wasInterrupted(37);
        progress.end();
    }
    const std::string plain = testing::internal::GetCapturedStderr();
    ::unsetenv("LEVELFORGE_PROGRESS");
    EXPECT_NE(plain.find("levelforge: band 30%\n"), std::string::npos) << plain;
    EXPECT_EQ(plain.find('\r'), std::string::npos) << plain;

    testing::internal::CaptureStderr();
    {
        levelforge::ops::SilentProgressScope silent;
        levelforge::ops::CliProgress progress(10, true);
        progress.start("band");
        std::this_thread::sleep_for(std::chrono::milliseconds(600));
        progress.wasInterrupted(50);
        progress.end();
    }
    EXPECT_EQ(testing::internal::GetCapturedStderr(), "");
}

// A plugin's static LEVELFORGE_REGISTER_OPERATOR declarations run inside dlopen(), before the
// loader's version check: while the loader holds a RegistrarCapture they go into its scratch
// registry (never the program's), and an error there is kept instead of thrown out of dlopen.
TEST(CliPlugins, StaticDeclarationsDuringLoadingAreCaptured)
{
    using namespace levelforge::ops;
    const auto noop = [](OperatorArgs&) {};
    OperatorRegistry scratch;
    std::string error;
    {
        const RegistrarCapture capture(scratch);
        const OperatorRegistrar a(OperatorSpec("captured-op", "captured").cook(noop));
        const OperatorRegistrar dup(OperatorSpec("captured-op", "again").cook(noop)); // no throw
        const OperatorRegistrar taken(OperatorSpec("mesh-to-sdf", "a built-in name, in the scratch registry").cook(noop));
        error = capture.error();
    }
    EXPECT_NE(scratch.find("captured-op"), nullptr);
    EXPECT_NE(scratch.find("mesh-to-sdf"), nullptr);
    EXPECT_EQ(OperatorRegistry::global().find("captured-op"), nullptr);
    EXPECT_NE(error.find("operator 'captured-op' is registered twice"), std::string::npos) << error;
    // Outside a capture registrations go to the program's registry, as every built-in operator
    // shows; a test must not add one there (other tests of this process list every operator).
    EXPECT_NE(OperatorRegistry::global().find("mesh-to-sdf"), nullptr);
}

#ifdef LEVELFORGE_CLI_PATH

using levelforge_test::CliRun;
using levelforge_test::countLines;
using levelforge_test::readText;

CliRun run(const fs::path& dir, const std::vector<std::string>& args) { return levelforge_test::runLevelforge(dir, args); }

void writeText(const fs::path& p, const std::string& text)
{
    std::ofstream f(p);
    f << text;
}

openvdb::FloatGrid::Ptr firstFloat(const fs::path& p)
{
    const auto grids = levelforge::readGrids(p.string());
    for (const auto& g : *grids)
        if (g->isType<openvdb::FloatGrid>()) return openvdb::gridPtrCast<openvdb::FloatGrid>(g);
    return nullptr;
}

/// Same transform, background, topology and bit-identical values.
void expectSameGrid(const openvdb::FloatGrid& a, const openvdb::FloatGrid& b)
{
    EXPECT_EQ(a.transform(), b.transform());
    EXPECT_EQ(a.background(), b.background());
    EXPECT_EQ(a.activeVoxelCount(), b.activeVoxelCount());
    EXPECT_EQ(a.tree().leafCount(), b.tree().leafCount());
    EXPECT_TRUE(a.tree().hasSameTopology(b.tree()));
    size_t diff = 0;
    for (auto it = a.tree().cbeginValueAll(); it; ++it) {
        if (it.getVoxelCount() != 1) continue;
        if (b.tree().getValue(it.getCoord()) != *it) ++diff;
    }
    EXPECT_EQ(diff, 0u);
}

/// Meshes sphere_0001.obj ... of radius 0.5 + 0.05 * frame.
void writeSphereFrames(const fs::path& dir, int first, int last)
{
    for (int f = first; f <= last; ++f) {
        const levelforge::TriangleMesh m = levelforge::makeIcosphere(openvdb::Vec3d(0.1, 0.0, -0.05), 0.5 + 0.05 * f, 3);
        char name[64];
        std::snprintf(name, sizeof name, "sphere_%04d.obj", f);
        levelforge::writeMesh(m, (dir / name).string());
    }
}

TEST(CliPipeline, InMemoryStepsGiveTheGridsOfFileSteps)
{
    const fs::path dir = scratchDir("pipeline_memory");
    writeSphereFrames(dir, 1, 1);
    const std::string mesh = (dir / "sphere_0001.obj").string();
    // through files, one process per step
    CliRun r = run(dir / "f1", {"mesh-to-sdf", mesh, (dir / "a.vdb").string(), "--voxel-count", "48", "--quiet"});
    ASSERT_EQ(r.code, 0) << r.err;
    r = run(dir / "f2", {"reshape", (dir / "a.vdb").string(), (dir / "b.vdb").string(), "--op", "dilate", "--offset", "1.5", "--quiet"});
    ASSERT_EQ(r.code, 0) << r.err;
    r = run(dir / "f3", {"csg", (dir / "b.vdb").string(), (dir / "a.vdb").string(), (dir / "c.vdb").string(), "--op", "difference"});
    ASSERT_EQ(r.code, 0) << r.err;
    // the same steps in one process, the intermediate grids in memory
    writeText(dir / "p.json", R"({"description": "dilate, then hollow by a difference",
      "steps": [
        {"op": "mesh-to-sdf", "inputs": [")" + mesh + R"("], "outputs": ["@a"], "params": {"voxel-count": 48, "quiet": true}},
        {"op": "reshape", "inputs": ["@a"], "outputs": ["@b"], "params": {"op": "dilate", "offset": 1.5, "quiet": true}},
        {"op": "csg", "inputs": ["@b", "@a"], "outputs": [")" + (dir / "m.vdb").string() + R"("], "params": {"op": "difference"}}
      ]})");
    r = run(dir / "p", {"run", (dir / "p.json").string(), "--report-json", (dir / "report.json").string()});
    ASSERT_EQ(r.code, 0) << r.err;
    EXPECT_NE(r.err.find("step 3/3 csg done"), std::string::npos) << r.err;
    const auto viaFiles = firstFloat(dir / "c.vdb"), inMemory = firstFloat(dir / "m.vdb");
    ASSERT_TRUE(viaFiles && inMemory);
    expectSameGrid(*viaFiles, *inMemory);
    EXPECT_GT(inMemory->activeVoxelCount(), 1000u);
    // no staging directory is left
    for (const auto& e : fs::directory_iterator(dir)) EXPECT_EQ(e.path().filename().string().find(".levelforge-run"), std::string::npos);
    // the report has every step, its parameters and statistics
    const nlohmann::json rep = nlohmann::json::parse(readText(dir / "report.json"));
    EXPECT_EQ(rep.at("operator"), "run");
    EXPECT_EQ(rep.at("status"), "ok");
    ASSERT_EQ(rep.at("steps").size(), 3u);
    EXPECT_EQ(rep.at("steps")[1].at("operator"), "reshape");
    EXPECT_EQ(rep.at("steps")[1].at("params").at("offset"), 1.5);
    EXPECT_EQ(rep.at("steps")[2].at("outputs").at("output"), (dir / "m.vdb").string());
    EXPECT_GT(rep.at("steps")[0].at("seconds").get<double>(), 0.0);
}

TEST(CliPipeline, BadPipelinesFailBeforeAnyStepWithOneLine)
{
    const fs::path dir = scratchDir("pipeline_bad");
    const std::string out = (dir / "out.vdb").string();
    struct Case
    {
        std::string json, mention;
    };
    const std::vector<Case> cases{
        {R"({"steps": [{"op": "mesh-to-sdf", "inputs": ["builtin:sphere"], "outputs": [")" + out + R"("]},
                       {"op": "no-such-op", "inputs": [], "outputs": []}]})", "step 2: unknown operator 'no-such-op'"},
        {R"({"steps": [{"op": "mesh-to-sdf", "inputs": ["builtin:sphere"], "outputs": [")" + out + R"("], "params": {"voxel-count": -3}}]})",
         "step 1 (mesh-to-sdf): invalid value '-3' for --voxel-count"},
        {R"({"steps": [{"op": "mesh-to-sdf", "inputs": ["builtin:sphere"], "outputs": [")" + out + R"("], "params": {"voxel-cuont": 3}}]})",
         "mesh-to-sdf has no parameter --voxel-cuont"},
        {R"({"steps": [{"op": "mesh-to-sdf", "inputs": ["builtin:sphere"], "outputs": [")" + out + R"("], "params": {"quiet": 1}}]})",
         "is a switch: give true or false"},
        {R"({"steps": [{"op": "reshape", "inputs": ["@band"], "outputs": [")" + out + R"("]}]})", "'@band' is read before any step writes it"},
        {R"({"steps": [{"op": "reshape", "inputs": ["a.vdb", "b.vdb"], "outputs": [")" + out + R"("]}]})", "takes 1 input(s) and 1 output(s)"},
        {R"({"steps": [{"op": "mesh-to-sdf", "input": ["builtin:sphere"]}]})", "unknown key \"input\""},
        {"{\"steps\": [\n  {\"op\": \"info\",,}\n]}", "not valid JSON at line 2"},
        {R"({"steps": []})", "\"steps\" must be a non-empty list"},
    };
    for (size_t i = 0; i < cases.size(); ++i) {
        const fs::path p = dir / ("bad" + std::to_string(i) + ".json");
        writeText(p, cases[i].json);
        const CliRun r = run(dir / ("r" + std::to_string(i)), {"run", p.string()});
        EXPECT_NE(r.code, 0) << cases[i].json;
        EXPECT_EQ(countLines(r.err, "levelforge: "), 1) << r.err;
        EXPECT_NE(r.err.find(cases[i].mention), std::string::npos) << r.err;
        EXPECT_FALSE(fs::exists(out)) << cases[i].json;
    }
    const CliRun missing = run(dir / "missing", {"run", (dir / "nope.json").string()});
    EXPECT_EQ(missing.code, 1);
    EXPECT_NE(missing.err.find("cannot read pipeline"), std::string::npos) << missing.err;
}

TEST(CliPipeline, AFailingStepLeavesNoOutputOfItsFrame)
{
    const fs::path dir = scratchDir("pipeline_fail");
    const std::string first = (dir / "first.vdb").string(), second = (dir / "second.vdb").string();
    // step 2 fails at run time (no grid of that name) after step 1 produced a file
    writeText(dir / "p.json", R"({"steps": [
        {"op": "mesh-to-sdf", "inputs": ["builtin:sphere"], "outputs": [")" + first + R"("], "params": {"voxel-count": 24, "quiet": true}},
        {"op": "reshape", "inputs": [")" + first + R"("], "outputs": [")" + second + R"("], "params": {"grid-name": "nope", "quiet": true}}]})");
    const CliRun r = run(dir / "r", {"run", (dir / "p.json").string()});
    EXPECT_EQ(r.code, 1);
    EXPECT_EQ(countLines(r.err, "levelforge: error:"), 1) << r.err;
    EXPECT_NE(r.err.find("levelforge: error: step 2 (reshape): "), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("nope"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(first));
    EXPECT_FALSE(fs::exists(second));
    for (const auto& e : fs::directory_iterator(dir)) EXPECT_EQ(e.path().filename().string().find(".levelforge-run"), std::string::npos);
}

TEST(CliFrames, EveryOperatorTakesFramesAndParallelFramesAreDeterministic)
{
    const fs::path dir = scratchDir("frames");
    writeSphereFrames(dir, 1, 4);
    const std::string in = (dir / "sphere_$F4.obj").string();
    CliRun r = run(dir / "j1", {"mesh-to-sdf", in, (dir / "one_%04d.vdb").string(), "--voxel-count", "32", "--frames", "1-4", "--quiet"});
    ASSERT_EQ(r.code, 0) << r.err;
    EXPECT_NE(r.out.find("levelforge: frames 1-4: 4 of 4 done"), std::string::npos) << r.out;
    r = run(dir / "j2", {"mesh-to-sdf", in, (dir / "two_$F4.vdb").string(), "--voxel-count", "32", "--frames", "1-4", "--jobs", "2", "--quiet"});
    ASSERT_EQ(r.code, 0) << r.err;
    EXPECT_EQ(countLines(r.err, "levelforge: frame "), 4) << r.err; // one counter line per frame
    for (int f = 1; f <= 4; ++f) {
        char a[32], b[32];
        std::snprintf(a, sizeof a, "one_%04d.vdb", f);
        std::snprintf(b, sizeof b, "two_%04d.vdb", f);
        const auto ga = firstFloat(dir / a), gb = firstFloat(dir / b);
        ASSERT_TRUE(ga && gb) << f;
        expectSameGrid(*ga, *gb);
        // each frame converted its own mesh: the surface crosses at its own radius
        const double r0 = 0.5 + 0.05 * f;
        const openvdb::Vec3d c(0.1, 0.0, -0.05);
        const double phi = openvdb::tools::BoxSampler::sample(ga->tree(), ga->transform().worldToIndex(c + openvdb::Vec3d(r0, 0, 0)));
        EXPECT_NEAR(phi, 0.0, 0.02 * r0) << f;
    }
    // frames of a pipeline, two at a time: reshape every frame of the sequence above
    writeText(dir / "p.json", R"({"steps": [{"op": "reshape", "inputs": [")" + (dir / "one_$F4.vdb").string() +
                                  R"("], "outputs": ["@d"], "params": {"offset": 1, "quiet": true}},
        {"op": "reshape", "inputs": ["@d"], "outputs": [")" + (dir / "back_$F4.vdb").string() + R"("], "params": {"op": "erode", "offset": 1, "quiet": true}}]})");
    r = run(dir / "pr", {"run", (dir / "p.json").string(), "--frames", "2-4:2", "--jobs", "2"});
    ASSERT_EQ(r.code, 0) << r.err;
    EXPECT_TRUE(fs::exists(dir / "back_0002.vdb"));
    EXPECT_TRUE(fs::exists(dir / "back_0004.vdb"));
    EXPECT_FALSE(fs::exists(dir / "back_0003.vdb"));
}

TEST(CliFrames, AMissingFrameIsReportedAndTheOthersGoOn)
{
    const fs::path dir = scratchDir("frames_missing");
    writeSphereFrames(dir, 1, 4);
    fs::remove(dir / "sphere_0003.obj");
    const std::string in = (dir / "sphere_$F4.obj").string(), out = (dir / "out_$F4.vdb").string();
    CliRun r = run(dir / "r", {"mesh-to-sdf", in, out, "--voxel-count", "24", "--frames", "1-4", "--quiet"});
    EXPECT_EQ(r.code, 1);
    EXPECT_EQ(countLines(r.err, "levelforge: error:"), 1) << r.err;
    EXPECT_NE(r.err.find("levelforge: error: frame 3: "), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("sphere_0003.obj"), std::string::npos) << r.err;
    EXPECT_NE(r.out.find("3 of 4 done, 1 failed (3)"), std::string::npos) << r.out;
    EXPECT_TRUE(fs::exists(dir / "out_0001.vdb") && fs::exists(dir / "out_0002.vdb") && fs::exists(dir / "out_0004.vdb"));
    EXPECT_FALSE(fs::exists(dir / "out_0003.vdb"));
    // --stop-on-error: frame 4 is not cooked
    fs::remove(dir / "out_0004.vdb");
    r = run(dir / "s", {"mesh-to-sdf", in, out, "--voxel-count", "24", "--frames", "1-4", "--stop-on-error", "--quiet",
                        "--report-json", (dir / "rep.json").string()});
    EXPECT_EQ(r.code, 1);
    EXPECT_FALSE(fs::exists(dir / "out_0004.vdb"));
    const nlohmann::json rep = nlohmann::json::parse(readText(dir / "rep.json"));
    EXPECT_EQ(rep.at("summary").at("failed"), 1);
    EXPECT_EQ(rep.at("summary").at("not_cooked"), 1);
    EXPECT_EQ(rep.at("frames")[2].at("status"), "failed");
    EXPECT_EQ(rep.at("frames")[2].at("frame"), 3);
}

TEST(CliFrames, TokensAndFramesMustGoTogether)
{
    const fs::path dir = scratchDir("frames_usage");
    CliRun r = run(dir / "a", {"mesh-to-sdf", "builtin:sphere", (dir / "same.vdb").string(), "--frames", "1-3"});
    EXPECT_EQ(r.code, 2);
    EXPECT_NE(r.err.find("needs a frame token"), std::string::npos) << r.err;
    r = run(dir / "b", {"mesh-to-sdf", "builtin:sphere", (dir / "out_$F4.vdb").string()});
    EXPECT_EQ(r.code, 2);
    EXPECT_NE(r.err.find("give --frames"), std::string::npos) << r.err;
    r = run(dir / "c", {"mesh-to-sdf", "builtin:sphere", (dir / "out_$F4.vdb").string(), "--frames", "3-1"});
    EXPECT_EQ(r.code, 2);
    EXPECT_NE(r.err.find("invalid value '3-1' for --frames"), std::string::npos) << r.err;
    r = run(dir / "d", {"reshape", "@band", (dir / "x.vdb").string()});
    EXPECT_NE(r.code, 0);
    EXPECT_NE(r.err.find("only valid in the files of 'levelforge run'"), std::string::npos) << r.err;
    EXPECT_EQ(fs::directory_iterator(dir) == fs::directory_iterator(), false); // the .stdout/.stderr files
    for (const auto& e : fs::directory_iterator(dir)) EXPECT_NE(e.path().extension(), ".vdb") << e.path();
}

TEST(CliPipeline, FrameTokensWithoutFramesAreAUsageError)
{
    // as for every other operator: without --frames the file would be named "out_$F4.vdb"
    const fs::path dir = scratchDir("pipeline_tokens");
    writeText(dir / "p.json", R"({"steps": [{"op": "mesh-to-sdf", "inputs": ["builtin:sphere"], "outputs": ["@a"],
        "params": {"voxel-count": 16, "quiet": true}},
        {"op": "reshape", "inputs": ["@a"], "outputs": [")" + (dir / "out_$F4.vdb").string() + R"("], "params": {"quiet": true}}]})");
    const CliRun r = run(dir / "r", {"run", (dir / "p.json").string()});
    EXPECT_EQ(r.code, 2) << r.err;
    EXPECT_EQ(countLines(r.err, "levelforge: "), 1) << r.err;
    EXPECT_NE(r.err.find("step 2 (reshape): the output '"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("has a frame token; give --frames"), std::string::npos) << r.err;
    for (const auto& e : fs::directory_iterator(dir)) EXPECT_NE(e.path().extension(), ".vdb") << e.path();
}

TEST(CliPipeline, ParametersNamingAnEarlierStepsFileReadTheStagedFile)
{
    // resample --reference names a file that step 1 of the same frame writes: step 3 must read
    // the staged file (the target does not exist until the frame is committed)
    const fs::path dir = scratchDir("pipeline_param_files");
    const std::string ref = (dir / "ref.vdb").string(), out = (dir / "out.vdb").string();
    writeText(dir / "p.json", R"({"steps": [
        {"op": "mesh-to-sdf", "inputs": ["builtin:sphere"], "outputs": [")" + ref + R"("], "params": {"voxel-count": 20, "quiet": true}},
        {"op": "mesh-to-sdf", "inputs": ["builtin:sphere"], "outputs": ["@a"], "params": {"voxel-count": 32, "quiet": true}},
        {"op": "resample", "inputs": ["@a"], "outputs": [")" + out + R"("], "params": {"reference": ")" + ref + R"(", "quiet": true}}]})");
    const CliRun r = run(dir / "r", {"run", (dir / "p.json").string(), "--report-json", (dir / "rep.json").string()});
    ASSERT_EQ(r.code, 0) << r.err;
    const auto a = firstFloat(ref), b = firstFloat(out);
    ASSERT_TRUE(a && b);
    EXPECT_EQ(a->transform(), b->transform());
    // the report names the target, not the staged file
    const std::string report = readText(dir / "rep.json");
    EXPECT_EQ(report.find(".levelforge-run"), std::string::npos) << report;
    EXPECT_NE(report.find("\"reference\": \"" + ref + "\""), std::string::npos) << report;
}

TEST(CliFrames, ReportsTakeFileNamesThatAreNotUtf8)
{
    // a Latin-1 file name is a valid path; the report must not fail on it
    const fs::path dir = scratchDir("report_latin1");
    const std::string out = (dir / "caf\xe9.vdb").string();
    const CliRun r = run(dir / "r", {"mesh-to-sdf", "builtin:sphere", out, "--voxel-count", "16", "--quiet", "--report-json",
                                     (dir / "rep.json").string()});
    EXPECT_EQ(r.code, 0) << r.err;
    EXPECT_TRUE(fs::exists(out));
    const nlohmann::json rep = nlohmann::json::parse(readText(dir / "rep.json"));
    EXPECT_EQ(rep.at("status"), "ok");
}

/// Starts `levelforge <args>` (stderr to @p errFile, stdout discarded); returns its pid.
pid_t startLevelforge(const std::vector<std::string>& args, const fs::path& errFile)
{
    std::vector<std::string> all{LEVELFORGE_CLI_PATH};
    all.insert(all.end(), args.begin(), args.end());
    std::vector<char*> argv;
    for (std::string& a : all) argv.push_back(a.data());
    argv.push_back(nullptr);
    const std::string err = errFile.string();
    const pid_t pid = ::fork();
    if (pid == 0) {
        const int e = ::open(err.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
        const int o = ::open("/dev/null", O_WRONLY);
        if (e < 0 || o < 0) ::_exit(126);
        // a test runner started in the background ignores SIGINT, and so would its children
        ::signal(SIGINT, SIG_DFL);
        ::signal(SIGTERM, SIG_DFL);
        ::dup2(e, STDERR_FILENO);
        ::dup2(o, STDOUT_FILENO);
        ::execv(argv[0], argv.data());
        ::_exit(127);
    }
    return pid;
}

/// The staged file @p name in a staging directory of @p dir, if there is one.
bool stagedFileExists(const fs::path& dir, const std::string& name)
{
    std::error_code ec;
    for (const auto& e : fs::directory_iterator(dir, ec)) {
        if (e.path().filename().string().rfind(".levelforge-run", 0) == 0 && fs::exists(e.path() / name, ec)) return true;
    }
    return false;
}

TEST(CliPipeline, CtrlCLeavesNoStagingDirectoryNoReportAndOneErrorLine)
{
    // step 1 is committed to the staging directory, step 2 computes for a while; then Ctrl-C
    // once (the step stops at its next progress check) or twice (the handler ends the process
    // at once): either way nothing of the frame remains, no report is written after Ctrl-C,
    // and there is one error line, status 130
    for (const int signals : {1, 2}) {
        const fs::path dir = scratchDir("pipeline_ctrl_c_" + std::to_string(signals));
        const std::string first = (dir / "first.vdb").string(), second = (dir / "second.vdb").string();
        writeText(dir / "p.json", R"({"steps": [
            {"op": "mesh-to-sdf", "inputs": ["builtin:sphere"], "outputs": [")" + first + R"("], "params": {"voxel-count": 16, "quiet": true}},
            {"op": "mesh-to-sdf", "inputs": ["builtin:torus-knot"], "outputs": [")" + second + R"("],
             "params": {"voxel-count": 400, "exterior-band": 20, "interior-band": 20, "quiet": true}}]})");
        const fs::path errFile = dir / "err.txt";
        const pid_t pid = startLevelforge({"run", (dir / "p.json").string(), "--report-json", (dir / "rep.json").string()}, errFile);
        ASSERT_GT(pid, 0);
        const auto t0 = std::chrono::steady_clock::now();
        while (!stagedFileExists(dir, "first.vdb") && std::chrono::steady_clock::now() - t0 < std::chrono::seconds(60))
            std::this_thread::sleep_for(std::chrono::milliseconds(5));
        const bool staged = stagedFileExists(dir, "first.vdb");
        std::this_thread::sleep_for(std::chrono::milliseconds(300)); // step 2 is computing
        for (int i = 0; i < signals; ++i) ::kill(pid, SIGINT);
        int status = 0;
        ASSERT_EQ(::waitpid(pid, &status, 0), pid);
        ASSERT_TRUE(staged) << "step 1 never finished";
        const std::string err = readText(errFile);
        ASSERT_TRUE(WIFEXITED(status)) << err;
        EXPECT_EQ(WEXITSTATUS(status), 130) << err;
        EXPECT_EQ(countLines(err, "levelforge: error:"), 1) << err;
        EXPECT_NE(err.find("interrupted"), std::string::npos) << err;
        EXPECT_FALSE(fs::exists(first));
        EXPECT_FALSE(fs::exists(second));
        EXPECT_FALSE(fs::exists(dir / "rep.json"));
        for (const auto& e : fs::directory_iterator(dir))
            EXPECT_EQ(e.path().filename().string().find(".levelforge-run"), std::string::npos) << signals << " signal(s): " << e.path();
    }
}

#ifdef LEVELFORGE_SHELL_PLUGIN
TEST(CliPlugins, TheExamplePluginAddsAnOperator)
{
    const fs::path dir = scratchDir("plugin_shell");
    const std::string solid = (dir / "solid.vdb").string(), hollow = (dir / "hollow.vdb").string();
    CliRun r = run(dir / "a", {"mesh-to-sdf", "builtin:sphere", solid, "--voxel-count", "40", "--exterior-band", "5", "--interior-band", "5", "--quiet"});
    ASSERT_EQ(r.code, 0) << r.err;
    r = run(dir / "b", {"--plugin", LEVELFORGE_SHELL_PLUGIN, "shell", solid, hollow, "--thickness", "2"});
    ASSERT_EQ(r.code, 0) << r.err;
    const auto in = firstFloat(solid), out = firstFloat(hollow);
    ASSERT_TRUE(in && out);
    const double h = in->voxelSize()[0];
    // φ' = |φ| − h at every active voxel of the input's band
    size_t checked = 0;
    for (auto it = in->tree().cbeginValueOn(); it; ++it, ++checked)
        ASSERT_FLOAT_EQ(out->tree().getValue(it.getCoord()), float(std::abs(*it) - float(h))) << it.getCoord();
    EXPECT_GT(checked, 1000u);
    // far inside is outside the shell
    EXPECT_GT(out->tree().getValue(openvdb::Coord(0)), 0.0f);
    // found on LEVELFORGE_OPERATOR_PATH too, and listed in --help
    const fs::path plugins = dir / "plugins";
    fs::create_directories(plugins);
    fs::copy_file(LEVELFORGE_SHELL_PLUGIN, plugins / "libshell.so");
    ::setenv("LEVELFORGE_OPERATOR_PATH", (plugins.string() + ":/nonexistent").c_str(), 1);
    r = run(dir / "c", {"--help"});
    const CliRun opHelp = run(dir / "d", {"shell", "--help"});
    ::unsetenv("LEVELFORGE_OPERATOR_PATH");
    EXPECT_EQ(r.code, 0) << r.err;
    EXPECT_NE(r.out.find("shell"), std::string::npos) << r.out;
    EXPECT_NE(opHelp.out.find("--thickness FLOAT"), std::string::npos) << opHelp.out;
    // in a pipeline
    writeText(dir / "p.json", R"({"steps": [{"op": "mesh-to-sdf", "inputs": ["builtin:sphere"], "outputs": ["@s"],
        "params": {"voxel-count": 40, "exterior-band": 5, "interior-band": 5, "quiet": true}},
        {"op": "shell", "inputs": ["@s"], "outputs": [")" + (dir / "p.vdb").string() + R"("], "params": {"thickness": 2}}]})");
    r = run(dir / "e", {"--plugin", LEVELFORGE_SHELL_PLUGIN, "run", (dir / "p.json").string()});
    ASSERT_EQ(r.code, 0) << r.err;
    expectSameGrid(*out, *firstFloat(dir / "p.vdb"));
}

TEST(CliPlugins, BrokenPluginsAreRefusedWithOneLine)
{
    const fs::path dir = scratchDir("plugin_broken");
    writeText(dir / "text.so", "not a library\n");
    struct Case
    {
        std::string file, mention;
    };
    const std::vector<Case> cases{
        {LEVELFORGE_WRONG_ABI_PLUGIN, "was built for operator ABI 999, this program has 1; rebuild it"},
        {LEVELFORGE_NO_ENTRY_PLUGIN, "not a levelforge operator plugin"},
        {(dir / "text.so").string(), "cannot load plugin"},
        {(dir / "none.so").string(), "no such file"},
    };
    for (size_t i = 0; i < cases.size(); ++i) {
        const std::string out = (dir / ("o" + std::to_string(i) + ".vdb")).string();
        const CliRun r = run(dir / ("r" + std::to_string(i)), {"--plugin", cases[i].file, "mesh-to-sdf", "builtin:sphere", out});
        EXPECT_EQ(r.code, 1) << cases[i].file;
        EXPECT_EQ(countLines(r.err, "levelforge: "), 1) << r.err;
        EXPECT_NE(r.err.find(cases[i].mention), std::string::npos) << r.err;
        EXPECT_NE(r.err.find(cases[i].file), std::string::npos) << r.err;
        EXPECT_FALSE(fs::exists(out));
    }
    // another copy of a loaded plugin: its operator name is taken
    fs::copy_file(LEVELFORGE_SHELL_PLUGIN, dir / "copy.so");
    const CliRun dup = run(dir / "dup", {"--plugin", LEVELFORGE_SHELL_PLUGIN, "--plugin", (dir / "copy.so").string(), "--help"});
    EXPECT_EQ(dup.code, 1);
    EXPECT_NE(dup.err.find("operator 'shell' is already registered"), std::string::npos) << dup.err;
}
#endif // LEVELFORGE_SHELL_PLUGIN

#endif // LEVELFORGE_CLI_PATH

} // namespace
