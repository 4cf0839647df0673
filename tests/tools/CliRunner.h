// SPDX-License-Identifier: Apache-2.0
// Runs the `levelforge` program (LEVELFORGE_CLI_PATH) as a real process with stdout and stderr
// captured, for the end-to-end CLI tests.
#pragma once

#include "TestUtil.h"

#include <levelforge/io/VdbIO.h>

#include <openvdb/openvdb.h>

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include <sys/wait.h>

namespace levelforge_test {

/// The whole text of a file ("" when it cannot be read).
inline std::string readText(const std::filesystem::path& path)
{
    std::ifstream in(path);
    return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

/// @p s quoted for /bin/sh.
inline std::string shellQuote(const std::string& s)
{
    std::string q = "'";
    for (char c : s) q += (c == '\'') ? std::string("'\\''") : std::string(1, c);
    return q + "'";
}

/// The float grid of a file that holds exactly one grid; null otherwise.
inline openvdb::FloatGrid::Ptr readSingleFloatGrid(const std::string& path)
{
    const auto grids = levelforge::readGrids(path);
    if (grids->size() != 1) return nullptr;
    return openvdb::gridPtrCast<openvdb::FloatGrid>((*grids)[0]);
}

/// What one run of the program gave.
struct CliRun
{
    int code = -1;
    std::string out, err, command;
};

#ifdef LEVELFORGE_CLI_PATH
/// Runs `levelforge <args>`; stdout and stderr go through files next to @p dir
/// (dir.stdout, dir.stderr).
inline CliRun runLevelforge(const std::filesystem::path& dir, const std::vector<std::string>& args)
{
    CliRun r;
    r.command = shellQuote(LEVELFORGE_CLI_PATH);
    for (const std::string& a : args) r.command += " " + shellQuote(a);
    const std::filesystem::path outFile = dir.parent_path() / (dir.filename().string() + ".stdout");
    const std::filesystem::path errFile = dir.parent_path() / (dir.filename().string() + ".stderr");
    const int status =
        std::system((r.command + " >" + shellQuote(outFile.string()) + " 2>" + shellQuote(errFile.string())).c_str());
    r.code = (status != -1 && WIFEXITED(status)) ? WEXITSTATUS(status) : -1;
    r.out = readText(outFile);
    r.err = readText(errFile);
    return r;
}
#endif

/// A failed command as every CLI test wants it: non-zero status, exactly one line from the
/// program on stderr and that line an error mentioning @p mention, and no @p output file.
inline void expectCleanFailure(const CliRun& r, const std::string& output, const std::string& mention)
{
    EXPECT_NE(r.code, 0) << r.command;
    EXPECT_EQ(countLines(r.err, "levelforge: "), 1) << r.err;
    EXPECT_EQ(countLines(r.err, "levelforge: error:"), 1) << r.err;
    EXPECT_NE(r.err.find(mention), std::string::npos) << r.err;
    EXPECT_FALSE(std::filesystem::exists(output)) << output;
}

} // namespace levelforge_test
