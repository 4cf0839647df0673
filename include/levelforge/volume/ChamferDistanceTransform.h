// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Dense chamfer distance transforms (city-block, chessboard, quasi-Euclidean and
///        complete 3x3x3, quasi-Euclidean 5x5x5 masks).
///
/// Paper: R. Satherley and M. W. Jones, "Vector-City Vector Distance Transform", Computer Vision
/// and Image Understanding 82 (2001), §2.1, Table 1. Chamfer masks: A. Rosenfeld and
/// J. L. Pfaltz, "Sequential operations in digital picture processing" (1966) (city-block,
/// chessboard); G. Borgefors, "Distance transformations in arbitrary dimensions" (1984) and
/// "On digital distance transforms in three dimensions" (1996) (quasi-Euclidean and complete
/// 3x3x3, 5x5x5).
///
/// The feature voxels, the classification and the signing every dense transform shares
/// (insideMask(), transverseFeatures(), classification(), applySign(); Eq. 2–6) are in
/// VolumeFeatures.h, included here.
///
/// Chamfer transforms (Eq. 4, 7): D = 0 at features, +inf elsewhere, then two raster passes of a
/// distance matrix: forward (z+, y+, x+) with the half of the mask already visited (offsets with
/// dz < 0, or dz = 0 and dy < 0, or dz = dy = 0 and dx < 0), then backward with the other half.
/// Neighbourhoods and weights (world units, spacing s = (sx, sy, sz)):
///   CityBlock        6 face neighbours, a = s along the axis. Exactly the L1 world metric.
///   Chessboard       18 face + edge neighbours (Fig. 4b: a and b, both one step); anisotropic:
///                    a = s along the axis, b = max(s_i, s_j) over the two axes of the edge
///                    step (our choice: the L-infinity analogue; isotropic a = b = s).
///   QuasiEuclidean3  18 face + edge neighbours, Euclidean weights a = s_i, b = sqrt(s_i^2+s_j^2).
///   Complete3        all 26 neighbours, Euclidean weights a, b, c = sqrt(sx^2+sy^2+sz^2).
///   QuasiEuclidean5  Fig. 5 (our reading): the 26 neighbours plus every permutation and sign
///                    of (2,1,0), (2,1,1), (2,2,1) — 98 neighbours, Euclidean weights; the
///                    positions that are double steps ((2,0,0), (2,2,0), (2,2,2)) are unused.
/// Exactness: for these regular masks the two passes give exactly the shortest path length in
/// the weighted neighbourhood graph from the nearest feature (checked against Dijkstra in the
/// tests), i.e. the chamfer metric; that metric only approximates Euclidean distance (Table 1:
/// city-block overestimates up to sqrt(3) times, chessboard underestimates).
///
/// Parallelism: on request (ChamferOptions::threads) each pass runs as a deterministic
/// row-pipelined wavefront per slice; results are bit-identical for any thread count. Serial by
/// default (see VectorDistanceTransform.h).
#pragma once

#include <levelforge/core/DenseVolume.h>
#include <levelforge/volume/VolumeFeatures.h>

#include <openvdb/util/NullInterrupter.h>

namespace levelforge {

/// The chamfer masks of Table 1 (see the file comment for their neighbourhoods and weights).
enum class ChamferMetric
{
    CityBlock,
    Chessboard,
    QuasiEuclidean3,
    Complete3,
    QuasiEuclidean5
};

/// @brief The display name of a metric, as the paper's tables name it.
/// @param[in] metric  a chamfer metric
/// @return "City-block", "Chess board", "Quasi-Euclidean 3^3", "Complete 3^3" or
///         "Quasi-Euclidean 5^3" ("unknown" for a value outside the enum).
const char* chamferMetricName(ChamferMetric metric);

/// Options of chamferDistanceTransform().
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

/// @brief Unsigned chamfer distance from every voxel to the nearest feature voxel.
/// @param[in] features  feature voxels (mask != 0)
/// @param[in] metric    the chamfer mask
/// @param[in] options   interrupter, lanes
/// @return distances in world units under @p metric (+inf everywhere when there is no
///         feature); same dims, spacing, origin.
/// @throws InvalidArgumentError (empty, bad spacing, size mismatch);
/// @throws InterruptedError.
ScalarVolume chamferDistanceTransform(const MaskVolume& features, ChamferMetric metric,
                                      const ChamferOptions& options = {});

} // namespace levelforge
