// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief The one set of grid metadata keys levelforge writes into `.vdb` files.
///
/// Every key starts with `levelforge:`. Writers and readers of the library, the operators and
/// downstream tools use these constants instead of repeating the strings.
#pragma once

namespace levelforge::meta {

/// Band half-width outside the surface, in voxels (FloatMetadata).
inline constexpr const char* kExteriorBandVoxels = "levelforge:exterior_band_voxels";
/// Band half-width inside the surface, in voxels (FloatMetadata).
inline constexpr const char* kInteriorBandVoxels = "levelforge:interior_band_voxels";
/// Where the field came from: a mesh or volume path, or a built-in shape (StringMetadata).
inline constexpr const char* kSource = "levelforge:source";
/// "levelforge <version>" of the library that wrote the grid (StringMetadata).
inline constexpr const char* kGenerator = "levelforge:generator";
/// The algorithm that made the values, e.g. "chang2008-exact-band" (StringMetadata).
inline constexpr const char* kMethod = "levelforge:method";
/// Iso-value of a volume conversion (FloatMetadata).
inline constexpr const char* kIso = "levelforge:iso";
/// Marks an adaptive distance field and states its layout version (StringMetadata).
inline constexpr const char* kAdf = "levelforge:adf";
/// ADF domain, index space, inclusive (Vec3IMetadata).
inline constexpr const char* kAdfDomainMin = "levelforge:adf_domain_min";
inline constexpr const char* kAdfDomainMax = "levelforge:adf_domain_max";
/// ADF sampling description (StringMetadata).
inline constexpr const char* kAdfSampling = "levelforge:adf_sampling";
/// printf pattern of the ADF per-level stated bound, in voxels (FloatMetadata), %d = level.
inline constexpr const char* kAdfBoundLevelPattern = "levelforge:adf_bound_level%d_voxels";

} // namespace levelforge::meta
