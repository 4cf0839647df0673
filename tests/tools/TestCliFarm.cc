// SPDX-License-Identifier: Apache-2.0
// Issue 20, item 2: farm task ranges. --task-index / --task-count (and Slurm's or the generic
// environment variables) give each task a contiguous share of --frames; every frame belongs to
// exactly one task. The example scheduler scripts of examples/farm run with the variables set by hand.
#include "CliRunner.h"
#include "TestUtil.h"

#include "FrameRunner.h"

#include <nlohmann/json.hpp>

#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <set>
#include <string>
#include <vector>

namespace fs = std::filesystem;
using levelforge_test::scratchDir;

namespace {

using levelforge::ops::CommonOptions;
using levelforge::ops::taskFrames;
using levelforge::ops::taskShare;
using levelforge::ops::UsageError;

TEST(FarmTasks, EveryFrameBelongsToExactlyOneTask)
{
    for (int n = 0; n <= 61; ++n) {
        std::vector<int> frames;
        for (int f = 0; f < n; ++f) frames.push_back(1001 + 3 * f);
        for (int count = 1; count <= 13; ++count) {
            std::vector<int> all;
            size_t smallest = size_t(-1), largest = 0;
            for (int i = 0; i < count; ++i) {
                const std::vector<int> mine = taskFrames(frames, i, count);
                smallest = std::min(smallest, mine.size());
                largest = std::max(largest, mine.size());
                all.insert(all.end(), mine.begin(), mine.end()); // in task order
            }
            EXPECT_EQ(all, frames) << n << " frames, " << count << " tasks"; // once each, in order
            EXPECT_LE(largest - smallest, 1u) << n << " frames, " << count << " tasks";
        }
    }
}

/// Clears the scheduler variables a test may set.
struct CleanEnvironment
{
    CleanEnvironment() { clear(); }
    ~CleanEnvironment() { clear(); }
    static void clear()
    {
        for (const char* v : {"SLURM_ARRAY_TASK_ID", "SLURM_ARRAY_TASK_MIN", "SLURM_ARRAY_TASK_MAX",
                              "SLURM_ARRAY_TASK_COUNT", "SLURM_ARRAY_TASK_STEP", "LEVELFORGE_TASK_INDEX", "LEVELFORGE_TASK_COUNT"})
            ::unsetenv(v);
    }
};

TEST(FarmTasks, TaskFromOptionsSlurmAndGenericEnvironment)
{
    const CleanEnvironment clean;
    CommonOptions c;
    EXPECT_EQ(taskShare(c).count, 1);
    EXPECT_EQ(taskShare(c).source, "");
    ::setenv("SLURM_ARRAY_TASK_ID", "12", 1);
    ::setenv("SLURM_ARRAY_TASK_MIN", "10", 1);
    ::setenv("SLURM_ARRAY_TASK_MAX", "19", 1);
    auto t = taskShare(c);
    EXPECT_EQ(t.index, 2);
    EXPECT_EQ(t.count, 10);
    EXPECT_EQ(t.source, "SLURM_ARRAY_TASK_ID=12");
    ::setenv("SLURM_ARRAY_TASK_COUNT", "4", 1); // COUNT wins over MAX - MIN + 1 (arrays with steps)
    EXPECT_EQ(taskShare(c).count, 4);
    c.taskIndex = 0;
    c.taskCount = 2; // the options win over the environment
    t = taskShare(c);
    EXPECT_EQ(t.index, 0);
    EXPECT_EQ(t.count, 2);
    c = CommonOptions();
    ::setenv("SLURM_ARRAY_TASK_ID", "x", 1);
    EXPECT_THROW(taskShare(c), UsageError);
    ::setenv("SLURM_ARRAY_TASK_ID", "15", 1); // index 5 of 4
    EXPECT_THROW(taskShare(c), UsageError);
    CleanEnvironment::clear();
    ::setenv("LEVELFORGE_TASK_INDEX", "1", 1);
    EXPECT_THROW(taskShare(c), UsageError); // no count
    ::setenv("LEVELFORGE_TASK_COUNT", "3", 1);
    EXPECT_EQ(taskShare(c).index, 1);
    c.taskIndex = 1; // an index without a count
    EXPECT_THROW(taskShare(c), UsageError);
}

TEST(FarmTasks, SlurmArraysWithAStep)
{
    // sbatch --array=10-40:10: task ids 10, 20, 30, 40 are tasks 0..3 of 4
    const CleanEnvironment clean;
    const CommonOptions c;
    ::setenv("SLURM_ARRAY_TASK_MIN", "10", 1);
    ::setenv("SLURM_ARRAY_TASK_MAX", "40", 1);
    ::setenv("SLURM_ARRAY_TASK_STEP", "10", 1);
    for (int id = 10, expected = 0; id <= 40; id += 10, ++expected) {
        ::setenv("SLURM_ARRAY_TASK_ID", std::to_string(id).c_str(), 1);
        const auto t = taskShare(c);
        EXPECT_EQ(t.index, expected) << id;
        EXPECT_EQ(t.count, 4) << id;
    }
    ::setenv("SLURM_ARRAY_TASK_COUNT", "4", 1);
    ::setenv("SLURM_ARRAY_TASK_ID", "40", 1);
    EXPECT_EQ(taskShare(c).index, 3);
    ::setenv("SLURM_ARRAY_TASK_ID", "25", 1); // not on the step
    EXPECT_THROW(taskShare(c), UsageError);
    ::setenv("SLURM_ARRAY_TASK_STEP", "1", 1); // a plain range
    ::setenv("SLURM_ARRAY_TASK_ID", "12", 1);
    ::setenv("SLURM_ARRAY_TASK_COUNT", "31", 1);
    EXPECT_EQ(taskShare(c).index, 2);
}

#ifdef LEVELFORGE_CLI_PATH

using levelforge_test::CliRun;
using levelforge_test::readText;

std::set<int> framesWritten(const fs::path& dir, const std::string& prefix)
{
    std::set<int> frames;
    for (const auto& e : fs::directory_iterator(dir)) {
        const std::string name = e.path().filename().string();
        int f = 0;
        if (name.rfind(prefix, 0) == 0 && e.path().extension() == ".vdb" &&
            std::sscanf(name.c_str() + prefix.size(), "%d", &f) == 1)
            frames.insert(f);
    }
    return frames;
}

TEST(CliFarm, TaskOptionsConvertTheTasksShare)
{
    const CleanEnvironment clean;
    const fs::path dir = scratchDir("farm_options");
    const std::string out = (dir / "out_$F4.vdb").string();
    CliRun r = levelforge_test::runLevelforge(dir / "t1", {"mesh-to-sdf", "builtin:sphere", out, "--voxel-size", "0.1",
                                                          "--frames", "1-7", "--task-index", "1", "--task-count", "3", "--quiet"});
    ASSERT_EQ(r.code, 0) << r.err;
    EXPECT_NE(r.err.find("levelforge: task 1 of 3 (--task-index): frames 3-4 (2)"), std::string::npos) << r.err;
    EXPECT_EQ(framesWritten(dir, "out_"), (std::set<int>{3, 4}));
    r = levelforge_test::runLevelforge(dir / "t2", {"mesh-to-sdf", "builtin:sphere", out, "--task-index", "1", "--task-count", "3"});
    EXPECT_EQ(r.code, 2);
    EXPECT_NE(r.err.find("give --frames"), std::string::npos) << r.err;
    r = levelforge_test::runLevelforge(dir / "t3", {"mesh-to-sdf", "builtin:sphere", out, "--frames", "1-7", "--task-index", "3",
                                                    "--task-count", "3"});
    EXPECT_EQ(r.code, 2);
    EXPECT_NE(r.err.find("the task index must be in [0, 3), got 3"), std::string::npos) << r.err;
    // a task beyond the frames has nothing to do, and says so
    r = levelforge_test::runLevelforge(dir / "t4", {"mesh-to-sdf", "builtin:sphere", out, "--voxel-size", "0.1", "--frames", "1-2",
                                                    "--task-index", "0", "--task-count", "5", "--quiet"});
    EXPECT_EQ(r.code, 0) << r.err;
    EXPECT_NE(r.err.find("task 0 of 5 (--task-index): no frames"), std::string::npos) << r.err;
}

#ifdef LEVELFORGE_SOURCE_DIR
/// Runs a script of examples/farm with @p env prepended (variables set by hand).
CliRun runScript(const fs::path& dir, const std::string& env, const std::string& script, const std::string& args = "")
{
    CliRun r;
    r.command = "env LEVELFORGE=" + levelforge_test::shellQuote(LEVELFORGE_CLI_PATH) + " " + env + " bash " +
                levelforge_test::shellQuote(std::string(LEVELFORGE_SOURCE_DIR) + "/examples/farm/" + script) + " " + args;
    const std::string errFile = (dir.parent_path() / (dir.filename().string() + ".stderr")).string();
    const int status = std::system(("cd " + levelforge_test::shellQuote(dir.parent_path().string()) + " && " + r.command +
                                    " >/dev/null 2>" + levelforge_test::shellQuote(errFile)).c_str());
    r.code = (status != -1 && WIFEXITED(status)) ? WEXITSTATUS(status) : -1;
    r.err = readText(errFile);
    return r;
}

TEST(CliFarm, SlurmArrayScriptCoversEveryFrameOnce)
{
    const CleanEnvironment clean;
    const fs::path dir = scratchDir("farm_slurm");
    const std::string common = "FRAMES=1-7 IN=builtin:sphere OUT=" + levelforge_test::shellQuote((dir / "vdb" / "s_$F4.vdb").string()) +
                               " VOXEL_SIZE=0.1 REPORTS=" + levelforge_test::shellQuote((dir / "reports").string()) +
                               " SLURM_ARRAY_TASK_MIN=0 SLURM_ARRAY_TASK_COUNT=3";
    size_t reported = 0;
    for (int task = 0; task < 3; ++task) {
        const CliRun r = runScript(dir / ("task" + std::to_string(task)), common + " SLURM_ARRAY_TASK_ID=" + std::to_string(task),
                                   "slurm-array.sbatch");
        ASSERT_EQ(r.code, 0) << r.command << "\n" << r.err;
        const nlohmann::json rep = nlohmann::json::parse(readText(dir / "reports" / ("task_" + std::to_string(task) + ".json")));
        EXPECT_EQ(rep.at("summary").at("task_index"), task);
        reported += rep.at("frames").size();
    }
    EXPECT_EQ(reported, 7u);
    EXPECT_EQ(framesWritten(dir / "vdb", "s_"), (std::set<int>{1, 2, 3, 4, 5, 6, 7}));
}

TEST(CliFarm, GenericScriptReadsOtherSchedulers)
{
    const CleanEnvironment clean;
    const fs::path dir = scratchDir("farm_generic");
    const std::string args = "mesh-to-sdf builtin:sphere " + levelforge_test::shellQuote((dir / "g_$F4.vdb").string()) +
                             " --voxel-size 0.1 --frames 1-8 --quiet";
    // Grid Engine: qsub -t 1-4 (1-based ids)
    for (int id = 1; id <= 4; ++id) {
        const CliRun r = runScript(dir / ("sge" + std::to_string(id)),
                                   "SGE_TASK_ID=" + std::to_string(id) + " SGE_TASK_FIRST=1 SGE_TASK_LAST=4 SGE_TASK_STEPSIZE=1",
                                   "farm-task.sh", args);
        ASSERT_EQ(r.code, 0) << r.command << "\n" << r.err;
        EXPECT_NE(r.err.find("task " + std::to_string(id - 1) + " of 4"), std::string::npos) << r.err;
    }
    EXPECT_EQ(framesWritten(dir, "g_"), (std::set<int>{1, 2, 3, 4, 5, 6, 7, 8}));
    // LSF: 1-based LSB_JOBINDEX with the count given
    const CliRun lsf = runScript(dir / "lsf", "LSB_JOBINDEX=2 TASK_COUNT=4", "farm-task.sh",
                                 "mesh-to-sdf builtin:sphere " + levelforge_test::shellQuote((dir / "l_$F4.vdb").string()) +
                                     " --voxel-size 0.1 --frames 1-8 --quiet");
    ASSERT_EQ(lsf.code, 0) << lsf.err;
    EXPECT_EQ(framesWritten(dir, "l_"), (std::set<int>{3, 4}));
}
#endif // LEVELFORGE_SOURCE_DIR

#endif // LEVELFORGE_CLI_PATH

} // namespace
