// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief One mesh-to-SDF conversion on many MPI ranks (`mpirun levelforge mesh-to-sdf
///        --distributed`): the index space cut into bricks aligned to VDB nodes, each rank
///        computing its bricks, the union gathered through rank 0, bit-identical to meshToSdf().
///
/// The decomposition (decomposeIntoBricks()): bricks are cubes of 2^brickLog2 voxels aligned to
/// multiples of their width (the default 128 = the level-1 internal nodes of a FloatTree). A
/// cheap first pass over the triangles' bounding boxes estimates the band voxels of each brick:
/// each triangle contributes the volume of its band (area × 2 × band limit; neighbours share the
/// rims, so no end caps) plus one voxel for its own cost, spread over the bricks its box dilated
/// by the limit touches in proportion to the overlap (fixed-point sums: every rank would get the
/// same bricks; rank 0 decides and broadcasts them anyway). The bricks with work, in Morton (Z-curve) order
/// so that each rank's share is compact, are cut into `ranks` consecutive runs of about equal
/// estimated work. Every rank computes the same decomposition from the same mesh: no message.
///
/// Each rank (meshToSdfBricks()) runs the main road (mesh/MeshToLevelSet.h) restricted to its
/// bricks (MeshToLevelSetOptions::onlyLeavesIn): only the triangles whose band can reach its
/// bricks enter its closest-triangle hierarchy, only the candidate leaves in its bricks are
/// searched, and every leaf it computes is bit-identical to the single-process run's.
/// finishBrickUnion() merges the disjoint leaves of all ranks into one tree and finishes it as
/// meshToSdf() does (signed flood fill, interior fill, the same metadata), so the result equals
/// meshToSdf()'s bit for bit (same values, active states, tiles and grid metadata).
///
/// Under MPI (distributedMeshToSdf()): every rank converts its bricks, then sends its leaves to
/// rank 0 in pieces of 8192 leaves (about 17 MiB), each piece a grid serialized with OpenVDB's
/// io::Stream into a buffer, its leaves freed as it goes; rank 0 reads each piece back as it comes,
/// merges and finishes. A failure on any rank (runOnAllRanks()) makes every
/// rank throw the same error, naming the rank that failed.
///
/// What is not distributed (yet): each rank holds the whole mesh (read by every rank; the
/// triangles are selected after reading, no byte-range reads); rank 0 holds the whole output
/// (a gather, not one file per rank); the winding-number sign, expansions (sweep, vector), the
/// scan method, reference transforms and the extra grids (fog, primitive index, attributes) are
/// refused with InvalidArgumentError. See docs/distributed.md.
#pragma once

#include <levelforge/pipeline/MeshToSdf.h>

#include <openvdb/openvdb.h>

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

namespace levelforge {

/// @brief The bricks with work and the rank that owns each (see the file comment).
struct BrickDecomposition
{
    int brickLog2 = 7;                    ///< bricks are 2^brickLog2 voxels wide
    int ranks = 1;                        ///< number of ranks the bricks are shared among
    std::vector<openvdb::Coord> origins;  ///< brick origins (index space), Morton order
    std::vector<double> weights;          ///< estimated band voxels of each brick
    std::vector<int> owner;               ///< the rank of each brick (non-decreasing)

    /// The index-space boxes of the bricks of @p rank (MeshToLevelSetOptions::onlyLeavesIn).
    std::vector<openvdb::CoordBBox> boxesOf(int rank) const;
    /// The estimated band voxels of the bricks of @p rank.
    double loadOf(int rank) const;
};

/// @brief Cuts the index space into bricks and shares them among @p ranks (see the file comment).
/// @param[in] mesh         the mesh (world units)
/// @param[in] voxelSize    world units (resolveVoxelSize())
/// @param[in] limitVoxels  the band limit, voxels (the larger half-width)
/// @param[in] ranks        >= 1
/// @param[in] brickLog2    brick width 2^brickLog2 voxels, 3 (a leaf) to 12 (a level-2 node)
/// @throws InvalidArgumentError bad arguments
BrickDecomposition decomposeIntoBricks(const TriangleMesh& mesh, double voxelSize, double limitVoxels, int ranks,
                                       int brickLog2 = 7);

/// @brief Checks that @p options can be converted brick by brick; throws InvalidArgumentError
///        naming what is not supported (yet) otherwise. The supported set: BandMethod::Chang,
///        Expansion::None, SignMode Pseudonormal or Unsigned (Auto resolving to Pseudonormal:
///        a closed, consistently oriented mesh), with or without fillInterior, any device; no
///        transform, fog, primitive index or attribute grids.
/// @param[in] mesh     the mesh (for Auto's resolution)
/// @param[in] options  the conversion
/// @return the sign mode that will be used (never Auto)
SignMode checkDistributable(const TriangleMesh& mesh, const MeshToSdfOptions& options);

/// @brief The part of meshToSdf() of one rank: its bricks' leaves (unfinished: tiles keep the
///        background). Throws what meshToSdf() throws, and InvalidArgumentError for options
///        checkDistributable() refuses.
/// @param[in]  mesh     the whole mesh
/// @param[in]  options  the conversion (as for meshToSdf())
/// @param[in]  boxes    this rank's bricks (BrickDecomposition::boxesOf())
/// @param[out] stats    optional: the band stage's counters of this part
openvdb::FloatGrid::Ptr meshToSdfBricks(const TriangleMesh& mesh, const MeshToSdfOptions& options,
                                        const std::vector<openvdb::CoordBBox>& boxes,
                                        MeshToSdfStats* stats = nullptr);

/// @brief Merges the parts (disjoint leaves, consumed) and finishes the union as meshToSdf()
///        does: the result equals meshToSdf(mesh, options) bit for bit.
/// @param[in]  mesh     the whole mesh (its source name for the metadata)
/// @param[in]  options  the conversion the parts were made with
/// @param[in]  parts    every rank's meshToSdfBricks() grid; their leaves are moved out
/// @param[out] stats    optional: the final band widths, sign, method, filled voxels
/// @throws InvalidArgumentError two parts hold the same leaf, or parts that do not match
openvdb::FloatGrid::Ptr finishBrickUnion(const TriangleMesh& mesh, const MeshToSdfOptions& options,
                                         std::vector<openvdb::FloatGrid::Ptr>& parts, MeshToSdfStats* stats = nullptr);

/// @brief A grid as bytes (OpenVDB's io::Stream, uncompressed: exact and fast), and back.
std::string serializeGrid(const openvdb::FloatGrid& grid);
/// @throws IoError the bytes are not one FloatGrid written by serializeGrid()
openvdb::FloatGrid::Ptr deserializeGrid(const std::string& bytes);

/// True when levelforge was built with MPI (-DLEVELFORGE_MPI=ON and libopenmpi-dev found).
bool mpiAvailable();

/// @brief This process's rank and the number of ranks of MPI_COMM_WORLD (initializes MPI on
///        first use; finalized at exit). Outside mpirun: rank 0 of 1.
/// @throws InvalidArgumentError levelforge was built without MPI (the message says how to get it)
int distributedRank();
int distributedSize();

/// @brief Runs @p step on every rank; if it throws on any rank, every rank throws the error of
///        the lowest failing rank (same type for levelforge's exceptions, else Error), its message
///        prefixed by "rank R of N: " when N > 1. Collective: every rank must call it.
/// @throws InvalidArgumentError built without MPI
void runOnAllRanks(const std::function<void()>& step);

/// What distributedMeshToSdf() did on each rank (rank 0 has every rank's entries).
struct DistributedStats
{
    int rank = 0, ranks = 1;
    uint64_t bricks = 0;                 ///< bricks with estimated work (all ranks)
    int brickLog2 = 7;
    MeshToSdfStats sdf;                  ///< this rank's band stage; on rank 0, the final grid's too
    double secondsDecompose = 0, secondsGather = 0, secondsFinish = 0, seconds = 0;
    /// Per rank (index = rank; complete on rank 0, this rank's entry elsewhere):
    std::vector<uint64_t> rankBricks, rankTriangles, rankActiveVoxels, rankBytes;
    std::vector<double> rankEstimate;    ///< estimated band voxels
    std::vector<double> rankSeconds;     ///< seconds converting its bricks
    std::vector<double> rankPeakMiB;     ///< peak resident memory (getrusage), MiB, at the end
    std::vector<double> rankPartPeakMiB; ///< the same once its part was computed (before the gather)
};

/// @brief meshToSdf() over all ranks of MPI_COMM_WORLD (see the file comment). Collective.
/// @param[in]  mesh       the whole mesh, on every rank
/// @param[in]  options    the conversion (the same on every rank; checkDistributable())
/// @param[in]  brickLog2  brick width 2^brickLog2 voxels (3 to 12; 7: level-1 internal nodes)
/// @param[out] stats      optional
/// @return the grid on rank 0 (equal to meshToSdf()'s bit for bit), null on the other ranks
/// @throws what meshToSdf() throws, on every rank (runOnAllRanks()); InvalidArgumentError when
///         built without MPI
openvdb::FloatGrid::Ptr distributedMeshToSdf(const TriangleMesh& mesh, const MeshToSdfOptions& options,
                                             int brickLog2 = 7, DistributedStats* stats = nullptr);

} // namespace levelforge
