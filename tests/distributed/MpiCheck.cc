// SPDX-License-Identifier: Apache-2.0
// levelforge_mpi_check: run under `mpirun -n K` (tests/CMakeLists.txt, Distributed.MpiLibrary*).
// Every rank calls distributedMeshToSdf(); rank 0 checks the result against meshToSdf() bit for
// bit (tree, tiles, metadata) for several brick sizes and options; then a failure on the last rank
// alone must reach every rank as the same typed error naming that rank. Exit status 0 when all
// holds (on every rank), 1 otherwise. Also one file per rank (distributedMeshToSdfPieces()),
// merged on rank 0 (mergeBrickPieces()), against meshToSdf().
#include "distributed/GridIdentity.h"

#include <levelforge/core/Exceptions.h>
#include <levelforge/distributed/DistributedMeshToSdf.h>
#include <levelforge/reference/MeshShapes.h>

#include <cstdio>
#include <filesystem>
#include <string>

using namespace levelforge;

int main()
{
    const int rank = distributedRank(), ranks = distributedSize();
    int failures = 0;
    const TriangleMesh knot = makeTorusKnot();
    struct Case
    {
        const char* name;
        int brickLog2;
        MeshToSdfOptions options;
    };
    std::vector<Case> cases;
    {
        MeshToSdfOptions o;
        o.voxelCount = 100;
        cases.push_back({"knot 100, bricks 8", 3, o});
        cases.push_back({"knot 100, bricks 128", 7, o});
        o.exteriorWidth = 4.0;
        o.interiorWidth = 1.5;
        o.fillInterior = true;
        cases.push_back({"knot 100, 4/1.5 voxels, filled, bricks 16", 4, o});
        MeshToSdfOptions u;
        u.voxelCount = 80;
        u.sign = SignMode::Unsigned;
        cases.push_back({"knot 80 unsigned, bricks 32", 5, u});
    }
    for (const Case& c : cases) {
        DistributedStats st;
        const openvdb::FloatGrid::Ptr g = distributedMeshToSdf(knot, c.options, c.brickLog2, &st);
        if (rank != 0) {
            if (g) { std::fprintf(stderr, "rank %d: %s: a grid on a rank other than 0\n", rank, c.name); ++failures; }
            continue;
        }
        const openvdb::FloatGrid::Ptr single = meshToSdf(knot, c.options);
        const std::string diff = g ? levelforge_test::gridDifference(*single, *g) : "no grid on rank 0";
        if (!diff.empty()) ++failures;
        std::printf("%s on %d ranks (%llu bricks): %s\n", c.name, ranks, (unsigned long long)st.bricks,
                    diff.empty() ? "identical" : diff.c_str());
    }
    // one file per rank, then the merge on rank 0 (no MPI in it): the same grid
    {
        const Case& c = cases[2]; // widths 4 / 1.5, filled, bricks of 16
        const std::filesystem::path dir =
            std::filesystem::temp_directory_path() / ("levelforge_mpi_check_" + std::to_string(ranks));
        std::string diff;
        try {
            runOnAllRanks([&] {
                if (rank == 0) std::filesystem::create_directories(dir);
            });
            const std::string manifest = distributedMeshToSdfPieces(knot, c.options, (dir / "out.vdb").string(),
                                                                    c.brickLog2);
            if (rank == 0) {
                diff = levelforge_test::gridDifference(*meshToSdf(knot, c.options), *mergeBrickPieces(manifest));
                if (!diff.empty()) ++failures;
                std::printf("%s on %d ranks, one file per rank, merged: %s\n", c.name, ranks,
                            diff.empty() ? "identical" : diff.c_str());
            }
            runOnAllRanks([&] {
                if (rank == 0) std::filesystem::remove_all(dir);
            });
        } catch (const std::exception& e) {
            std::fprintf(stderr, "rank %d: one file per rank: %s\n", rank, e.what());
            ++failures;
        }
    }
    // a failure on the last rank alone: every rank gets it, typed, naming the rank
    try {
        runOnAllRanks([&] {
            if (rank == ranks - 1) throw IoError("injected failure");
        });
        std::fprintf(stderr, "rank %d: the injected failure was not reported\n", rank);
        ++failures;
    } catch (const IoError& e) {
        const std::string expect =
            ranks > 1 ? "rank " + std::to_string(ranks - 1) + " of " + std::to_string(ranks) + ": injected failure"
                      : "injected failure";
        if (e.what() != expect) {
            std::fprintf(stderr, "rank %d: unexpected message '%s'\n", rank, e.what());
            ++failures;
        }
    }
    // and the ranks go on together afterwards
    try {
        runOnAllRanks([] {});
    } catch (const std::exception& e) {
        std::fprintf(stderr, "rank %d: %s\n", rank, e.what());
        ++failures;
    }
    if (rank == 0) std::printf("%s\n", failures ? "FAILED" : "all identical");
    return failures ? 1 : 0;
}
