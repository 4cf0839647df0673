// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Dense vector distance transforms: VCVDT (4 and 8 passes) of Satherley & Jones and
///        Mullikin's EVDT (two-slice and full-grid), on a vector volume or from a binary mask.
///
/// Paper: R. Satherley and M. W. Jones, "Vector-City Vector Distance Transform", Computer Vision
/// and Image Understanding 82 (2001) — §2.2 (Eq. 8–10), §3 (VCVDT, Fig. 8 and 10), §3.1 (vector
/// storage, Table 4–6), §3.2 (error analysis, Fig. 12 error wake), §4 (sub-voxel shells).
/// EVDT: J. C. Mullikin, "The vector distance transform in two and three dimensions", CVGIP:
/// Graphical Models and Image Processing 54(6), 1992 (3-D extension of Danielsson's 4SSED).
///
/// Every voxel holds a ClosestVector: the offset, in VOXEL units, from its centre to the closest
/// feature point found so far, together with its squared WORLD length d2 (Leymarie–Levine: the
/// length is kept with the vector and never recomputed for the centre). Propagation (Eq. 9):
/// a pass visits the voxels of a slice in a raster order and, for each voxel p, tries every
/// listed neighbour q = p + o: the candidate vector is V(q) + o (it points from p to q's feature
/// point), and it replaces V(p) when its d2 is strictly smaller. Candidates are tried in the
/// order of the pass table below, so ties keep the earlier one — the result is fully determined.
/// d2 = X*X + (Y*Y + Z*Z) with X = x*sx, Y = y*sy, Z = z*sz in single precision (spacing in
/// world units), so anisotropic voxels are handled exactly as Euclidean world distance.
///
/// The pass masks of the paper's figures are not in our copy of the text; the pass tables listed
/// here are OUR READING of §2.2/§3 and define the methods (the implementation holds them as
/// constant tables and checks at compile time that each has the shape its row kernel runs):
///  - VCVDT4 (Fig. 8): forward sweep z = 0..nz-1, per slice F1 (rows y+, x+; neighbours
///    (0,0,-1), (0,-1,0), (-1,0,0)) then F2 over the same slice (rows y-, x-; (0,+1,0), (+1,0,0));
///    backward sweep z = nz-1..0, B1 (y-, x-; (0,0,+1), (0,+1,0), (+1,0,0)) then B2 (y+, x+;
///    (0,-1,0), (-1,0,0)). F1 and B1 are the two city-block chamfer passes; the vertical
///    neighbour is checked once per sweep.
///  - VCVDT8 (Fig. 10, like Ragnemalm's corner EDT): the same sweeps, four in-slice passes from
///    the four corners: P1 (y+, x+; vertical, (0,-1,0), (-1,0,0)), P2 (y+, x-; (0,-1,0), (+1,0,0)),
///    P3 (y-, x-; (0,+1,0), (+1,0,0)), P4 (y-, x+; (0,+1,0), (-1,0,0)); vertical = (0,0,-1) in the
///    forward sweep and (0,0,+1) in the backward sweep, checked only in P1.
///  - EVDT (Fig. 7, Mullikin's six passes): forward sweep, per slice F1 (y+, x+; (0,0,-1),
///    (0,-1,0), (-1,0,0)) with F2 (x-; (+1,0,0)) run on each row right after F1 has finished it
///    (Danielsson's 4SSED forward scan), then F3 (y-, x-; (0,+1,0), (+1,0,0)); backward sweep
///    B1 (y-, x-; (0,0,+1), (0,+1,0), (+1,0,0)) with B2 (x+; (-1,0,0)) after each row, then
///    B3 (y+, x+; (0,-1,0), (-1,0,0)).
///    EVDT keeps vectors for two slices only (Mullikin's memory saving): the forward sweep and the
///    backward sweep each start from the input vectors, each holds the current and the previous
///    slice, and the result is the shorter of the two per voxel. "If the forward and backward
///    passes are computed separately, the two implementations produce identical distance
///    fields" (§3.1): this is that separate computation, and it reproduces the error wake of
///    §3.2 / Fig. 12 (the backward sweep never sees the forward sweep's vectors).
///    EVDTFullGrid runs the same six passes in place on the complete vector grid.
///
/// What is exact and what is approximate: every output vector points to a real seed point
/// (a feature voxel centre or a sub-voxel seed), so distances never underestimate the distance
/// to the seed set; they overestimate where a voxel's closest seed cannot be reached through
/// the masks (Voronoi-corner configurations, Eq. 11; one-voxel-thin diagonal Voronoi tiles that
/// the 4-neighbour passes cannot enter; the two-slice wake). Measured on the 80^3 sphere
/// (docs/benchmarks.md, "Volume distance transforms"): average error per voxel 0.0007
/// (VCVDT8), 0.0008 (EVDT full grid), 0.0017 (EVDT), 0.0022 (VCVDT4); VCVDT8 errors within
/// +-0.27 voxel. For exact distances to
/// feature voxel centres use exactDistanceTransform() (ExactDistanceTransform.h).
///
/// Sub-voxel seeds (§4): vectorDistanceTransform() propagates whatever vectors are set, so a
/// shell of closest-surface-point vectors (fractional, voxel units) propagates like binary
/// features. Unknown voxels hold x = y = z = d2 = +inf; voxels no seed can reach stay +inf.
///
/// Implementation (none of it changes a bit of the result; the test
/// MatchesALiteralReadingOfThePassTables compares with the tables read literally): while it runs, the transform keeps each row in
/// groups of 8 voxels along x (x[8], y[8], z[8], d2[8], in place in the same bytes; a row is
/// regrouped when the forward sweep first reads it and restored when the backward sweep has read
/// it for the last time, also on interruption). A pass on a row is split into the element-wise
/// candidates (vertical and previous row: 8 voxels per SIMD step) and the in-row chain (the
/// previous voxel, sequential). x86-64 CPUs with AVX2 run an AVX2 build of the same code (no FMA:
/// bit-identical).
///
/// From a mask, vectorDistanceTransform(const MaskVolume&) gives the distances in one go, bit for
/// bit as the vector-volume route, without building the vector volume: the passes run on two
/// slice buffers that stay in cache and only a 16-bit integer vector per voxel (6 bytes) is kept
/// between the sweeps; d2 is recomputed with the passes' own formula on the way back.
///
/// Parallelism: each in-slice pass is a 2-D raster with dependencies on x-1 and y-1 (in pass
/// order). Lanes (plain std::thread) own COLUMNS: lane t runs every pass of every slice on its
/// x-range, whose previous rows and previous slices are its own; only the in-row chain crosses
/// into the next lane's range, one vector per row and pass, published with an atomic progress
/// counter. Every voxel therefore sees exactly the values of the serial order: results are
/// bit-identical for any lane count (T = the TBB arena's concurrency, capped by
/// tbb::global_control). The lanes wait for each other about once per slice (where the x order
/// of the passes reverses); lanes are real threads, not TBB tasks, so the waits cannot deadlock.
/// EVDT's row-interleaved passes (F2/B2) leave nothing to split; EVDT and EVDTFullGrid run on one
/// lane. Measured in docs/benchmarks.md ("Volume distance transforms").
#pragma once

#include <levelforge/core/DenseVolume.h>

#include <openvdb/util/NullInterrupter.h>

#include <cstdint>

namespace levelforge {

/// Offset from a voxel centre to its closest feature point, in VOXEL units (may be fractional),
/// and its squared WORLD length d2 = (x*sx)^2 + (y*sy)^2 + (z*sz)^2. Unknown: all four +inf.
struct ClosestVector
{
    float x, y, z;
    float d2;
};
static_assert(sizeof(ClosestVector) == 16, "ClosestVector must stay 16 bytes");

/// A dense volume of closest vectors (the state the vector transforms propagate).
using VectorVolume = DenseVolume<ClosestVector>;

/// The vector transforms (see the file comment for their pass tables).
enum class VectorTransformMethod
{
    EVDT,          ///< Mullikin's six passes, two vector slices (forward and backward sweeps separate)
    EVDTFullGrid,  ///< the same six passes on the complete vector grid
    VCVDT4,        ///< vector-city VDT, four passes (Fig. 8)
    VCVDT8         ///< vector-city VDT, eight passes (Fig. 10), the most accurate
};

/// @brief The display name of a method.
/// @param[in] method  a vector transform method
/// @return "EVDT", "EVDTFullGrid", "VCVDT4" or "VCVDT8" ("unknown" for a value outside the enum).
const char* vectorTransformMethodName(VectorTransformMethod method);

/// Options of vectorDistanceTransform().
struct VectorTransformOptions
{
    /// The pass tables to run.
    VectorTransformMethod method = VectorTransformMethod::VCVDT8;
    /// Optional interruption (checked at the start of every slice of each sweep); not owned.
    openvdb::util::NullInterrupter* interrupter = nullptr;
    /// Lanes (threads). 1 (default) = serial; 0 = automatic (the TBB concurrency, capped by
    /// tbb::global_control, when a slice has at least 128 x 128 voxels, else 1); n > 1 = at most
    /// n (and at most one lane per 32 columns). The result does not depend on it. Serial is the
    /// default because the gain is modest and not guaranteed: on the idle cores of a 2-core
    /// machine 2 lanes ran 1.0-1.5x as fast as 1 (about 1.1-1.2x in most runs; the lanes wait
    /// for each other where a pass reverses the x order) and up to 1.2x slower when another
    /// process held a core (docs/benchmarks.md, "Volume distance transforms").
    int threads = 1;
};

/// What a vector transform did.
struct VectorTransformStats
{
    double seconds = 0;        ///< wall time of the propagation
    uint64_t voxels = 0;       ///< voxels in the volume
    uint64_t seeds = 0;        ///< voxels with a finite vector on input
    uint64_t unreached = 0;    ///< voxels still +inf on output (no seed at all)
    int passesPerVoxel = 0;    ///< in-slice passes that visit each voxel (4, 6 or 8)
    int lanes = 1;             ///< lanes (threads) that ran the passes
    /// Voxels per second of wall time (0 when no time was measured).
    double voxelsPerSecond() const { return seconds > 0 ? double(voxels) / seconds : 0.0; }
};

/// @brief The seed vectors of a binary volume (Eq. 8).
/// @param[in] features  feature voxels (mask != 0)
/// @return (0,0,0,0) at feature voxels, +inf elsewhere; same dims, spacing, origin.
/// @throws InvalidArgumentError for an empty volume, bad spacing or a data/dims size mismatch.
VectorVolume initVectorVolume(const MaskVolume& features);

/// @brief Propagates the vectors in place with the chosen method (see the file comment).
///
/// Every finite input vector is a seed; its d2 must be its squared world length (as
/// initVectorVolume() and the shell builders set it).
/// @param[in,out] vectors  the seeds on input, the propagated closest vectors on output
/// @param[in]     options  method, interrupter, lanes
/// @param[out]    stats    optional: what the transform did
/// @throws InvalidArgumentError (empty volume, spacing <= 0 or NaN, data size != dims);
/// @throws InterruptedError (the volume is then partially propagated, in its normal layout).
void vectorDistanceTransform(VectorVolume& vectors, const VectorTransformOptions& options = {},
                             VectorTransformStats* stats = nullptr);

/// @brief The lengths of the vectors.
/// @param[in] vectors  closest vectors (d2 in world units²)
/// @return sqrt(d2) per voxel, world units (+inf where unreached); same dims, spacing, origin.
/// @throws InvalidArgumentError for an empty volume, bad spacing or a data/dims size mismatch.
ScalarVolume vectorLength(const VectorVolume& vectors);

/// @brief Distances in one go: from the feature voxels of a binary volume to every voxel
///        centre, in world units, by the chosen method.
///
/// The result is bit for bit vectorLength() of initVectorVolume() propagated by
/// vectorDistanceTransform() with the same options, but the 16-byte vector volume is never
/// built: the full-grid methods (VCVDT4, VCVDT8, EVDTFullGrid) run their passes on two slice
/// buffers that stay in cache and keep only a 6-byte integer vector per voxel between the sweeps
/// (vectors to voxel centres have integer components), so they read and write about 17 bytes per
/// voxel instead of about 100, and hold 10 bytes per voxel instead of 20. (EVDT, and volumes with
/// a dimension above 32767, take the vector-volume route.)
/// @param[in]  features  feature voxels (mask != 0)
/// @param[in]  options   method, interrupter, lanes
/// @param[out] stats     optional: what the transform did; seconds covers the whole call,
///                       allocations included
/// @return the distances, world units (+inf where unreached); same dims, spacing, origin.
/// @throws InvalidArgumentError (empty volume, bad spacing, size mismatch);
/// @throws InterruptedError.
ScalarVolume vectorDistanceTransform(const MaskVolume& features, const VectorTransformOptions& options = {},
                                     VectorTransformStats* stats = nullptr);

/// @brief Squared world length of a vector in voxel units, computed exactly as the passes do:
///        X * X + (Y * Y + Z * Z) in single precision.
/// @param[in] x, y, z  the vector, voxel units
/// @param[in] spacing  voxel spacing, world units
/// @return the squared length, world units².
inline float vectorLengthSquared(float x, float y, float z, const openvdb::Vec3f& spacing)
{
    const float X = x * spacing[0], Y = y * spacing[1], Z = z * spacing[2];
    return X * X + (Y * Y + Z * Z);
}

} // namespace levelforge
