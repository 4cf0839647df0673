// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Feature voxels, classification and signing of a dense volume: the inputs and the
///        sign every dense distance transform shares.
///
/// Paper: R. Satherley and M. W. Jones, "Vector-City Vector Distance Transform", Computer Vision
/// and Image Understanding 82 (2001), §2, Eq. 2–6.
///
///   insideMask()          Eq. 2: a voxel is inside when f >= iso.
///   transverseFeatures()  Eq. 3: an inside voxel is a feature (transverse) when its 26-bit flag
///                         is neither all 0 nor all 1 — at least one of its 26 neighbours is
///                         inside and at least one outside. Voxels beyond the volume count as
///                         outside. (Eq. 3 tests "<= tau" where Eq. 2 tests ">= tau"; we use the
///                         inside mask of Eq. 2 for both, so f == iso is inside everywhere.)
///   classification()      Eq. 5: 0 for a feature voxel, -1 when all 26 neighbours are inside
///                         (interior), +1 otherwise. A feature voxel is 0 even if all its
///                         neighbours are inside (features given by another rule).
///   applySign()           Eq. 6: signed = unsigned * C(p).
///
/// The chamfer (ChamferDistanceTransform.h), vector (VectorDistanceTransform.h) and exact
/// (ExactDistanceTransform.h) transforms take the feature voxels as their seeds; their unsigned
/// distances are signed by applySign() with the classification.
#pragma once

#include <levelforge/core/DenseVolume.h>

#include <cstdint>

namespace levelforge {

/// @brief Eq. 2: the inside mask of a scalar field.
/// @param[in] field  the sampled field
/// @param[in] iso    the iso-value τ
/// @return 1 where f >= iso, else 0 (NaN samples are outside); same dims, spacing, origin.
/// @throws InvalidArgumentError (empty volume, bad spacing, size mismatch, NaN iso).
MaskVolume insideMask(const ScalarVolume& field, float iso);

/// @brief Eq. 3: the transverse feature voxels of an inside mask.
/// @param[in] inside  inside mask (non-zero = inside)
/// @return 1 at inside voxels with at least one inside and one outside voxel among their 26
///         neighbours (beyond the volume = outside), else 0; same dims, spacing, origin.
/// @throws InvalidArgumentError (empty volume, bad spacing, size mismatch).
MaskVolume transverseFeatures(const MaskVolume& inside);

/// @brief Eq. 5: the class (sign) of every voxel.
/// @param[in] inside    inside mask (non-zero = inside)
/// @param[in] features  feature voxels (non-zero = feature), same dims as @p inside
/// @return 0 at features, -1 where all 26 neighbours are inside (beyond the volume = outside),
///         +1 elsewhere; the geometry of @p inside.
/// @throws InvalidArgumentError (invalid volume, or dims that differ).
DenseVolume<int8_t> classification(const MaskVolume& inside, const MaskVolume& features);

/// @brief Eq. 6: signs an unsigned distance field by the classification.
/// @param[in] unsignedDistance  distances >= 0 (may be +inf)
/// @param[in] sign              classification(), same dims
/// @return unsignedDistance * sign per voxel (a 0 class gives +0, +inf stays +inf for +1);
///         the geometry of @p unsignedDistance.
/// @throws InvalidArgumentError (invalid volume, or dims that differ).
ScalarVolume applySign(const ScalarVolume& unsignedDistance, const DenseVolume<int8_t>& sign);

} // namespace levelforge
