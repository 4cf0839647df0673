// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Resampling of a grid onto another transform: another voxel size, or the transform of a
///        reference grid (Houdini: *VDB Resample*; vdb_tool: -resample; OpenVDB:
///        tools::resampleToMatch).
///
/// Two roads, as in Houdini (whose "Rebuild SDF" toggle is on by default):
///   - level sets (a FloatGrid of class GRID_LEVEL_SET) are rebuilt on the target transform by
///     rebuildLevelSet() (levelset/RebuildLevelSet.h): the zero iso-surface is extracted with
///     tools::volumeToMesh and the band on the target is the exact distance to it, with the
///     input's band width in voxels (exterior: background / h; interior: the levelforge
///     metadata when present, else the same). OpenVDB's resampleToMatch also rebuilds level
///     sets (its interpolation order is then unused), but with the approximate meshToVolume;
///     here the distances to the extracted surface are exact. The target must be a similarity
///     transform (rotation, uniform scale, translation).
///   - every other grid (fog, density, velocity, or a level set with LevelSetResample::
///     Interpolate) is interpolated with OpenVDB's tools::resampleToMatch (GridTransformer for
///     affine transforms, which low-pass filters by mip-mapping when the target is coarser;
///     GridResampler otherwise) at the chosen order: point (nearest voxel), linear (trilinear)
///     or quadratic (triquadratic through the 3×3×3 nearest voxels, OpenVDB's
///     QuadraticSampler). An interpolated level set keeps its world-unit values and background,
///     so its band shrinks in voxels when the voxels grow and it is no longer an exact distance
///     where the surface bends at the voxel scale.
///
/// What is exact and what is approximate: interpolation reproduces the sampler's polynomial
/// exactly (linear fields are reproduced by the linear and quadratic orders; measured errors on
/// a sphere are in tests/levelset/TestResampleGrid.cc); the rebuild is exact up to the
/// extracted surface, which is within a fraction of a voxel of the true zero set (see
/// RebuildLevelSet.h). An identical target transform gives a deep copy.
#pragma once

#include <levelforge/levelset/RebuildLevelSet.h>

#include <openvdb/openvdb.h>
#include <openvdb/util/NullInterrupter.h>

#include <string>

namespace levelforge {

/// Interpolation order of resampleGrid() (Houdini's "Interpolation").
enum class ResampleOrder
{
    Point,    ///< the nearest voxel (tools::PointSampler)
    Linear,   ///< trilinear (tools::BoxSampler)
    Quadratic ///< triquadratic (tools::QuadraticSampler)
};

/// "point" / "linear" / "quadratic"; throws InvalidArgumentError otherwise.
ResampleOrder resampleOrderFromString(const std::string& name);

/// What resampleGrid() does with level sets.
enum class LevelSetResample
{
    Rebuild,    ///< exact band on the target (rebuildLevelSet(); Houdini's "Rebuild SDF")
    Interpolate ///< interpolate the values like any other grid
};

/// @brief Options of resampleGrid().
struct ResampleGridOptions
{
    ResampleOrder order = ResampleOrder::Linear;
    LevelSetResample levelSets = LevelSetResample::Rebuild;
    /// Rebuild only: refuse bands with more voxels than this (ResourceLimitError); 0: no limit.
    uint64_t maxVoxels = 2'000'000'000ull;
    /// Progress 0–100; a true answer throws InterruptedError. Not owned.
    openvdb::util::NullInterrupter* interrupter = nullptr;
};

/// @brief True if resampleGrid() can resample @p grid: a float, double, vec3s or vec3d grid.
bool isResamplable(const openvdb::GridBase& grid);

/// @brief Resamples @p grid onto @p target (see the file comment).
/// @param[in]  grid     a float, double, vec3s or vec3d grid; not modified
/// @param[in]  target   the output transform
/// @param[in]  options  order, level-set road, voxel budget, interrupter
/// @param[out] how      optional: "rebuilt", "interpolated (linear)", ... or "copied"
/// @return a new grid of the same type, name, class, background and metadata on @p target
/// @throws InvalidArgumentError a grid type that cannot be resampled; a level set to rebuild
///         onto a target that is not a similarity transform, or without a zero crossing
/// @throws ResourceLimitError the rebuilt band would pass maxVoxels
/// @throws InterruptedError the interrupter asked to stop
openvdb::GridBase::Ptr resampleGrid(const openvdb::GridBase& grid, const openvdb::math::Transform& target,
                                    const ResampleGridOptions& options, std::string* how = nullptr);

} // namespace levelforge
