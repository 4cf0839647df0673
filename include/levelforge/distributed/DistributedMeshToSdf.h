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
/// Or, one file per rank (distributedMeshToSdfPieces()): every rank writes its own leaves,
/// unfinished, to its own .vdb next to the output (`out.rank0003.vdb`, atomically) and rank 0 a
/// JSON manifest (`out.vdb.manifest.json`) with everything the finish needs; no rank ever holds
/// more than its part. mergeBrickPieces() (`levelforge merge`, no MPI needed) then reads the
/// pieces one at a time, moves their leaves into one tree and finishes it exactly as the gather
/// does: the merged grid equals meshToSdf()'s bit for bit too.
///
/// What is not distributed (yet): each rank holds the whole mesh (read by every rank; the
/// triangles are selected after reading, no byte-range reads); the finish (flood fill, interior
/// fill) runs on one process that holds the whole output (rank 0 of the gather, or the merge);
/// the winding-number sign, expansions (sweep, vector), the scan method, reference transforms
/// and the extra grids (fog, primitive index, attributes) are refused with InvalidArgumentError.
/// See docs/distributed.md.
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

/// @brief What the finish of a brick union needs besides the leaves: what a mesh and a
///        MeshToSdfOptions resolve to (brickFinishFor()), and what a manifest records.
struct BrickFinish
{
    double voxelSize = 0.0;                  ///< world units (resolveVoxelSize())
    float exteriorBandVoxels = 3.0f;         ///< final band half-width outside, voxels
    float interiorBandVoxels = 3.0f;         ///< final band half-width inside, voxels
    SignMode sign = SignMode::Pseudonormal;  ///< Pseudonormal or Unsigned (never Auto)
    bool fillInterior = false;               ///< MeshToSdfOptions::fillInterior
    std::string gridName = "surface";        ///< the grid's name
    std::string source;                      ///< the "levelforge:source" metadata
    std::string method = "chang2008-exact-band"; ///< the "levelforge:method" metadata
};

/// @brief The finish of a conversion of @p mesh with @p options (checkDistributable() resolves
///        the sign). @throws InvalidArgumentError what checkDistributable() refuses
BrickFinish brickFinishFor(const TriangleMesh& mesh, const MeshToSdfOptions& options);

/// @brief finishBrickUnion() without the mesh: merges the parts (consumed; the first one's tree
///        is the base when it holds leaves only) and finishes as meshToSdf() does.
/// @throws InvalidArgumentError no parts, two parts hold the same leaf, parts whose background,
///         transform or sign differ, a sign other than @p finish's
openvdb::FloatGrid::Ptr finishBrickUnion(const BrickFinish& finish, std::vector<openvdb::FloatGrid::Ptr>& parts,
                                         MeshToSdfStats* stats = nullptr);

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

// ---------------------------------------------------------------- one file per rank

/// @brief The file of rank @p rank's piece for the output @p output: the output's stem, then
///        ".rank" and the rank in at least 4 digits, then its extension (".vdb" when it has
///        none): "dir/out.vdb" -> "dir/out.rank0003.vdb".
std::string pieceFileName(const std::string& output, int rank);
/// @brief The manifest of the pieces of @p output: @p output + ".manifest.json".
std::string manifestFileName(const std::string& output);

/// One rank's piece in a manifest.
struct BrickPiece
{
    int rank = 0;
    std::string file;                         ///< as written in the manifest (relative: to the manifest's folder)
    std::vector<openvdb::Coord> bricks;       ///< origins of the rank's bricks (index space)
    uint64_t leaves = 0, activeVoxels = 0;    ///< what the piece holds
    uint64_t bytes = 0;                       ///< the file's size
};

/// @brief A manifest of pieces (the JSON file is described in docs/distributed.md).
struct BrickManifest
{
    std::string id;          ///< this run's id: every piece carries it ("levelforge:piece_of")
    std::string generator;   ///< the program that wrote it (generatorString())
    std::string output;      ///< the output the pieces make (a file name, for the user)
    int ranks = 1;
    int brickLog2 = 7;
    float background = 0.0f; ///< every piece's background (world units)
    openvdb::math::Transform::Ptr transform; ///< every piece's transform
    BrickFinish finish;      ///< how the union is finished
    std::vector<BrickPiece> pieces; ///< one per rank, in rank order
};

/// Grid metadata of a piece: the manifest's id, the piece's rank and the number of ranks.
inline constexpr const char* kPieceOfMetadata = "levelforge:piece_of";
inline constexpr const char* kPieceRankMetadata = "levelforge:piece_rank";
inline constexpr const char* kPieceRanksMetadata = "levelforge:piece_ranks";

/// @brief A new id for a run's manifest and pieces (32 hexadecimal digits, random).
std::string newPieceRunId();

/// @brief Writes one rank's part (as meshToSdfBricks() made it: values and active states as
///        computed, no flood fill) to @p path atomically, marked with @p id, @p rank and
///        @p ranks (grid metadata above). The part itself is not changed.
/// @return the piece's entry for the manifest (file: @p path's file name; bricks left empty)
/// @throws IoError the file cannot be written (nothing is left behind)
BrickPiece writeBrickPiece(const std::string& path, const openvdb::FloatGrid& part, const std::string& id, int rank,
                           int ranks);

/// @brief Writes @p manifest as JSON to @p path atomically.
/// @throws IoError the file cannot be written (nothing is left behind)
void writeBrickManifest(const std::string& path, const BrickManifest& manifest);

/// @brief Reads and checks a manifest (every field present and of its type, one piece per rank
///        in rank order, distinct files, a uniform linear transform).
/// @throws IoError naming @p path and the problem: missing or unreadable, not JSON, not a
///         levelforge manifest, a missing or bad field
BrickManifest readBrickManifest(const std::string& path);

/// Options of mergeBrickPieces().
struct MergeOptions
{
    /// Checked between pieces; stops with InterruptedError.
    openvdb::util::NullInterrupter* interrupter = nullptr;
};

/// What mergeBrickPieces() did.
struct MergeStats
{
    int pieces = 0;
    uint64_t leaves = 0, activeVoxels = 0, filledVoxels = 0, bytesRead = 0;
    double secondsRead = 0, secondsFinish = 0, seconds = 0;
};

/// @brief `levelforge merge`: reads the pieces of @p manifestPath one at a time (each checked
///        against the manifest), moves their leaves into one tree and finishes it as
///        finishBrickUnion() does. The result equals the single-process meshToSdf() bit for bit.
///        Needs no MPI.
/// @throws IoError naming the file and the problem: the manifest (see readBrickManifest()), a
///         piece missing or unreadable, not one float grid, not a piece of this manifest (id,
///         rank, number of ranks), another transform, background or sign, other leaf or voxel
///         counts than the manifest's, a leaf outside its rank's bricks or in two pieces
/// @throws InterruptedError the interrupter asked to stop
openvdb::FloatGrid::Ptr mergeBrickPieces(const std::string& manifestPath, const MergeOptions& options = {},
                                         MergeStats* stats = nullptr);

/// @brief distributedMeshToSdf() writing one file per rank instead of gathering: every rank
///        writes its piece to pieceFileName(output, rank), then rank 0 writes the manifest to
///        manifestFileName(output) (an earlier manifest there is removed first). Collective.
///        If any rank fails, every rank throws the same error (runOnAllRanks()) and the pieces
///        written by this call are removed: no manifest, no piece is left.
/// @param[in]  output     the .vdb that `levelforge merge` will make; names the pieces and manifest
/// @param[out] stats      optional (rankBytes: each piece's file size; no final grid: sdf holds
///                        this rank's band stage)
/// @return the manifest's path, on every rank
/// @throws what meshToSdf() throws, IoError for the files, on every rank; InvalidArgumentError
///         when built without MPI
std::string distributedMeshToSdfPieces(const TriangleMesh& mesh, const MeshToSdfOptions& options,
                                       const std::string& output, int brickLog2 = 7,
                                       DistributedStats* stats = nullptr);

} // namespace levelforge
