// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief The one parameter group of levelforge::GridSpec, declared once and reused by every
///        operator that makes a grid (mesh-to-sdf, mesh-to-adf, volume-to-sdf): --voxel-size /
///        --voxel-count, --exterior-band / --interior-band, --world-units, --grid-name, --quiet.
#pragma once

#include "Operator.h"

#include <levelforge/core/GridSpec.h>

#include <string>
#include <vector>

namespace levelforge::ops {

/// Which GridSpec parameters an operator declares, and their per-operator defaults and words.
struct GridParamSet
{
    /// --voxel-size / --voxel-count (mutually exclusive). Off for inputs that bring their own
    /// voxel size (volumes, grids).
    bool resolution = true;
    std::string voxelSizeHelp = "Voxel edge length, in world units";
    std::string voxelCountHelp = "Voxels along the longest axis of the mesh bounding box; "
                                 "used when --voxel-size is not given";
    int voxelCount = 256;
    /// --exterior-band / --interior-band (and --world-units when worldUnits).
    bool bands = true;
    std::string exteriorHelp = "Half-width of the band outside the surface, in voxels";
    std::string interiorHelp = "Half-width of the band inside the surface, in voxels";
    double band = 3.0;
    double maxBand = 1000.0;
    /// --interior-band excludes this flag (e.g. "fill-interior"); empty: none.
    std::string interiorExcludes;
    bool worldUnits = false;
    /// --max-voxels default (GridSpec::maxVoxels: the voxel budget, band voxels plus working
    /// memory at 4 bytes a voxel; 0: no limit).
    double maxVoxels = 2e9;
    /// --grid-name default.
    std::string gridName = "surface";
};

/// @brief The parameters of @p set, in the order above, for OperatorSpec::params():
///        `OperatorSpec(...).params(gridParams({...}))`.
/// @param[in] set  which parameters, their defaults and help
/// @return the parameter declarations
std::vector<Param> gridParams(const GridParamSet& set);

/// @brief Reads the GridSpec parameters @p args' operator declares into @p grid (voxel size or
///        count, widths and units, grid name); leaves the rest of @p grid as it is.
/// @param[in]     args  parsed arguments of an operator declared with gridParams()
/// @param[in,out] grid  the spec to fill
void readGridParams(const OperatorArgs& args, GridSpec& grid);

} // namespace levelforge::ops
