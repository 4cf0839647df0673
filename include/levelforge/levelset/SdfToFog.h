// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Signed distance level set → fog (density) volume, as Houdini's *VDB from Polygons*
///        "Build Fog" and openvdb::tools::sdfToFogVolume() make it.
///
/// For a level set φ (world units, negative inside) and an interior band width w (world units):
///
///     fog(x) = clamp(−φ(x) / w, 0, 1)
///
/// so the density is 0 outside and on the surface, ramps linearly to 1 across the interior band
/// and is 1 deeper inside. Voxels and tiles where the density is 0 are inactive (background 0);
/// every other voxel is active, and tiles inside the surface become active tiles of value 1.
/// The result is a GRID_FOG_VOLUME FloatGrid with the level set's transform and name (unless
/// SdfToFogOptions::gridName is given). Exact: each value is the formula above evaluated on the
/// stored φ in float arithmetic (one multiply by −1/w, then a clamp).
///
/// Inside without a value: voxels that are inactive in a leaf and negative, and tiles that are
/// negative, lie deeper than the band and get 1. A level set filled by fillInterior (metadata
/// kFillInteriorMetadata true) holds exactly −background in its active deep voxels; those also
/// get 1 (a band voxel whose exact φ equals −background to the bit would too; band values below
/// −background, with an interior band wider than the exterior one, ramp as usual).
///
/// Parallel over leaves (tree::LeafManager), then a serial pass over the tiles; the result does
/// not depend on the number of threads. The level set is not modified.
#pragma once

#include <openvdb/openvdb.h>
#include <openvdb/util/NullInterrupter.h>

#include <string>

namespace levelforge {

/// Options of sdfToFog().
struct SdfToFogOptions
{
    /// Width of the ramp inside the surface, world units (> 0). 0 (default): the level set's
    /// interior band, meta::kInteriorBandVoxels × voxel size when the levelforge metadata is
    /// present, else its background (OpenVDB's symmetric narrow band, sdfToFogVolume's cutoff).
    double interiorWidthWorld = 0.0;
    /// Name of the fog grid; empty: the level set's name.
    std::string gridName;
    /// Optional interruption (checked once per leaf). Not owned.
    openvdb::util::NullInterrupter* interrupter = nullptr;
};

/// @brief The interior ramp width sdfToFog() uses for @p sdf (see SdfToFogOptions).
/// @param[in] sdf      a level set
/// @param[in] options  interiorWidthWorld, when > 0, wins
/// @return the width, world units (> 0)
/// @throws InvalidArgumentError when the width is not finite and positive (a negative or NaN
///         option, a zero background, or a non-uniform voxel size without an explicit width)
double fogInteriorWidth(const openvdb::FloatGrid& sdf, const SdfToFogOptions& options = {});

/// @brief Converts a signed distance level set to a fog volume (see the file comment).
/// @param[in] sdf      the level set (world-unit values, negative inside); any grid class is
///                     accepted, the values are read as signed distances
/// @param[in] options  ramp width, grid name, interrupter
/// @return a new GRID_FOG_VOLUME FloatGrid, background 0, values in [0, 1], sharing no data with
///         @p sdf (a deep copy of its transform)
/// @throws InvalidArgumentError bad ramp width (see fogInteriorWidth())
/// @throws InterruptedError the interrupter asked to stop
openvdb::FloatGrid::Ptr sdfToFog(const openvdb::FloatGrid& sdf, const SdfToFogOptions& options = {});

} // namespace levelforge
