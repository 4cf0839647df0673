// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief GridSpec: the settings every conversion shares (voxel size or count, band widths in
///        voxels or world units, grid name, voxel budget, interrupter). Every options struct of
///        the library derives from it, so the same field has the same name, unit and meaning
///        everywhere, and the operators declare these parameters once.
#pragma once

#include <levelforge/core/TriangleMesh.h>

#include <openvdb/util/NullInterrupter.h>

#include <cstdint>
#include <string>

namespace levelforge {

/// Units of GridSpec::exteriorWidth / interiorWidth (and of other widths an options struct
/// declares next to them, e.g. ExpandLevelSetOptions::boundingBoxMargin).
enum class WidthUnits
{
    Voxels, ///< voxel edge lengths (Houdini's default)
    World   ///< world units (Houdini's "Use World Space Units")
};

/// The output grid every conversion makes, and the limits it works under.
///
/// Which fields an operation reads is stated in its options struct: mesh inputs use all of
/// them; volume and grid inputs take the voxel size from the input (voxelSize and voxelCount
/// must stay 0 there); the ADF covers a padded domain instead of a band and ignores the widths.
struct GridSpec
{
    /// Voxel edge length, world units. If <= 0 (default) it is derived from voxelCount.
    double voxelSize = 0.0;
    /// Voxels along the longest axis of the input's bounding box; used when voxelSize <= 0.
    int voxelCount = 0;
    /// Half-width of the band outside the surface, in `units` (OpenVDB's default: 3 voxels).
    double exteriorWidth = 3.0;
    /// Half-width of the band inside the surface, in `units` (OpenVDB's default: 3 voxels).
    double interiorWidth = 3.0;
    /// Units of exteriorWidth and interiorWidth.
    WidthUnits units = WidthUnits::Voxels;
    /// Name stored in the grid (Houdini's VDB from Polygons uses "surface").
    std::string gridName = "surface";
    /// Voxel budget: refuse (ResourceLimitError) grids with more voxels than this; 0 = no limit.
    /// Each operation says which count it checks (band voxels, dense samples, ...).
    uint64_t maxVoxels = 2'000'000'000ull;
    /// Optional progress / interruption (OpenVDB convention). Not owned.
    openvdb::util::NullInterrupter* interrupter = nullptr;

    /// @brief A width of this spec in voxels.
    /// @param[in] width      exteriorWidth or interiorWidth (or another width in `units`)
    /// @param[in] voxelSize  the resolved voxel edge length, world units (> 0)
    /// @return @p width itself for WidthUnits::Voxels, @p width × (1 / @p voxelSize) for World
    ///         (the product, as expandLevelSet always computed it, so all users agree to the bit).
    double widthInVoxels(double width, double voxelSize) const
    {
        return units == WidthUnits::World ? width * (1.0 / voxelSize) : width;
    }
};

/// @brief The voxel size (world units) a conversion of @p mesh with @p spec uses:
///        spec.voxelSize when > 0, else the longest side of the mesh bounding box divided by
///        spec.voxelCount.
/// @param[in] mesh  the input mesh (only its bounding box is read when voxelSize <= 0)
/// @param[in] spec  voxelSize / voxelCount
/// @return the voxel edge length, world units (> 0)
/// @throws InvalidArgumentError if voxelSize is negative or not finite, or if neither a
///         positive voxel size nor a positive count is given;
/// @throws InvalidMeshError if the count is used and the mesh is empty or its bounding box
///         has zero or non-finite size.
double resolveVoxelSize(const TriangleMesh& mesh, const GridSpec& spec);

} // namespace levelforge
