// SPDX-License-Identifier: Apache-2.0
// Runs the `levelforge` program under `mpirun` (LEVELFORGE_MPIEXEC) with stdout and stderr
// captured, for the distributed CLI tests (TestCliDistributed.cc, TestCliDistributedMerge.cc).
#pragma once

#include "tools/CliRunner.h"

#include <levelforge/distributed/DistributedMeshToSdf.h>

#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

namespace levelforge_test {

#if defined(LEVELFORGE_CLI_PATH)
/// Runs `mpirun -n ranks <command>` (the command already quoted), OpenMPI as root allowed,
/// oversubscribed; stdout and stderr captured. @p env: assignments put before mpirun.
inline CliRun runMpi(const std::filesystem::path& dir, int ranks, const std::string& command,
                     const std::string& env = "")
{
    CliRun r;
#ifdef LEVELFORGE_MPIEXEC
    r.command = env + (env.empty() ? "" : " ") +
                "OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_rmaps_base_oversubscribe=1 "
                "OMPI_MCA_btl_vader_single_copy_mechanism=none " +
                shellQuote(LEVELFORGE_MPIEXEC) + " --allow-run-as-root --oversubscribe --bind-to none -n " +
                std::to_string(ranks) + " " + command;
#endif
    const std::filesystem::path outFile = dir / "mpi.stdout", errFile = dir / "mpi.stderr";
    const int status = std::system((r.command + " >" + shellQuote(outFile.string()) + " 2>" +
                                    shellQuote(errFile.string()) + " </dev/null").c_str());
    r.code = (status != -1 && WIFEXITED(status)) ? WEXITSTATUS(status) : -1;
    r.out = readText(outFile);
    r.err = readText(errFile);
    return r;
}

/// `levelforge <args>`, quoted for /bin/sh.
inline std::string cli(const std::vector<std::string>& args)
{
    std::string c = shellQuote(LEVELFORGE_CLI_PATH);
    for (const std::string& a : args) c += " " + shellQuote(a);
    return c;
}
#endif

} // namespace levelforge_test

#define LF_NEED_MPI()                                                                             \
    if (!levelforge::mpiAvailable()) GTEST_SKIP() << "levelforge was built without MPI (LEVELFORGE_MPI)"
