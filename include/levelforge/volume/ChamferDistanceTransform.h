// levelforge — feature voxels, classification and signing (Satherley & Jones §2, Eq. 2–6), and
// the dense chamfer distance transforms (§2.1, Table 1).
//
// Paper: R. Satherley and M. W. Jones, "Vector-City Vector Distance Transform", CVIU 82 (2001).
// Chamfer masks: Rosenfeld & Pfaltz 1966 (city-block, chessboard), Borgefors 1984/1996
// (quasi-Euclidean and complete 3x3x3, 5x5x5).
//
// Feature voxels (shared by every dense transform):
//   insideMask()          Eq. 2: a voxel is inside when f >= iso.
//   transverseFeatures()  Eq. 3: an inside voxel is a feature (transverse) when its 26-bit flag
//                         is neither all 0 nor all 1 — at least one of its 26 neighbours is
//                         inside and at least one outside. Voxels beyond the volume count as
//                         outside. (Eq. 3 tests "<= tau" where Eq. 2 tests ">= tau"; we use the
//                         inside mask of Eq. 2 for both, so f == iso is inside everywhere.)
//   classification()      Eq. 5: 0 for a feature voxel, -1 when all 26 neighbours are inside
//                         (interior), +1 otherwise. A feature voxel is 0 even if all its
//                         neighbours are inside (features given by another rule).
//   applySign()           Eq. 6: signed = unsigned * C(p).
//
// Chamfer transforms (Eq. 4, 7): D = 0 at features, +inf elsewhere, then two raster passes of a
// distance matrix: forward (z+, y+, x+) with the half of the mask already visited (offsets with
// dz < 0, or dz = 0 and dy < 0, or dz = dy = 0 and dx < 0), then backward with the other half.
// Neighbourhoods and weights (world units, spacing s = (sx, sy, sz)):
//   CityBlock        6 face neighbours, a = s along the axis. Exactly the L1 world metric.
//   Chessboard       18 face + edge neighbours (Fig. 4b: a and b, both one step); anisotropic:
//                    a = s along the axis, b = max(s_i, s_j) over the two axes of the edge
//                    step (our choice: the L-infinity analogue; isotropic a = b = s).
//   QuasiEuclidean3  18 face + edge neighbours, Euclidean weights a = s_i, b = sqrt(s_i^2+s_j^2).
//   Complete3        all 26 neighbours, Euclidean weights a, b, c = sqrt(sx^2+sy^2+sz^2).
//   QuasiEuclidean5  Fig. 5 (our reading): the 26 neighbours plus every permutation and sign
//                    of (2,1,0), (2,1,1), (2,2,1) — 98 neighbours, Euclidean weights; the
//                    positions that are double steps ((2,0,0), (2,2,0), (2,2,2)) are unused.
// Exactness: for these regular masks the two passes give exactly the shortest path length in
// the weighted neighbourhood graph from the nearest feature (checked against Dijkstra in the
// tests), i.e. the chamfer metric; that metric only approximates Euclidean distance (Table 1:
// city-block overestimates up to sqrt(3) times, chessboard underestimates).
//
// Parallelism: on request (ChamferOptions::threads) each pass runs as a deterministic
// row-pipelined wavefront per slice (vector_transform_internal::runRowWavefront); results are
// bit-identical for any thread count. Serial by default (see VectorDistanceTransform.h).
#pragma once

#include <levelforge/core/DenseVolume.h>

#include <openvdb/util/NullInterrupter.h>

#include <cstdint>
#include <vector>

namespace levelforge {

// ------------------------------------------------------------------ feature voxels (Eq. 2–6)

/// Eq. 2: 1 where f >= iso, else 0. Same dims, spacing, origin. NaN samples are outside.
/// Throws InvalidArgumentError (empty volume, bad spacing, size mismatch, NaN iso).
MaskVolume insideMask(const ScalarVolume& field, float iso);

/// Eq. 3: 1 at inside voxels with at least one inside and one outside voxel among their 26
/// neighbours (beyond the volume = outside). Throws InvalidArgumentError as above.
MaskVolume transverseFeatures(const MaskVolume& inside);

/// Eq. 5: 0 at features, -1 where all 26 neighbours are inside (beyond the volume = outside),
/// +1 elsewhere. inside and features must have equal dims (InvalidArgumentError otherwise).
DenseVolume<int8_t> classification(const MaskVolume& inside, const MaskVolume& features);

/// Eq. 6: unsignedDistance * sign per voxel (a 0 class gives +0, +inf stays +inf for +1).
/// Throws InvalidArgumentError on a dims mismatch.
ScalarVolume applySign(const ScalarVolume& unsignedDistance, const DenseVolume<int8_t>& sign);

// ------------------------------------------------------------------ chamfer transforms

enum class ChamferMetric
{
    CityBlock,
    Chessboard,
    QuasiEuclidean3,
    Complete3,
    QuasiEuclidean5
};

/// "City-block", "Chess board", "Quasi-Euclidean 3^3", "Complete 3^3", "Quasi-Euclidean 5^3".
const char* chamferMetricName(ChamferMetric metric);

struct ChamferOptions
{
    /// Optional interruption (checked once per slice); not owned.
    openvdb::util::NullInterrupter* interrupter = nullptr;
    /// Wavefront lanes: 1 (default) = serial, 0 = automatic (the TBB concurrency, capped by
    /// tbb::global_control, when a slice has at least 128 x 128 voxels, else 1), n > 1 = at most
    /// n. The row wavefront synchronises once per row chunk and only pays on idle cores
    /// (docs/distance-transforms.md, "Parallelism and determinism"). The result does not depend
    /// on it.
    int threads = 1;
};

/// Unsigned chamfer distance (world units) from every voxel to the nearest feature voxel
/// (mask != 0) under `metric`; +inf everywhere when there is no feature. Same dims, spacing,
/// origin. Throws InvalidArgumentError (empty, bad spacing, size mismatch) or InterruptedError.
ScalarVolume chamferDistanceTransform(const MaskVolume& features, ChamferMetric metric,
                                      const ChamferOptions& options = {});

namespace chamfer_internal {

struct Step
{
    int8_t x, y, z;
};

/// The full (symmetric) neighbourhood of a metric, in a fixed order.
std::vector<Step> neighbourhood(ChamferMetric metric);

/// Weight of one mask step, world units (see the file comment).
double stepWeight(ChamferMetric metric, const Step& step, const openvdb::Vec3d& spacing);

} // namespace chamfer_internal
} // namespace levelforge
