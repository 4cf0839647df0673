// SPDX-License-Identifier: Apache-2.0
#include "GridParams.h"

namespace levelforge::ops {

std::vector<Param> gridParams(const GridParamSet& set)
{
    std::vector<Param> spec;
    if (set.resolution) {
        spec.push_back(Param::floating("voxel-size", "Voxel Size", set.voxelSizeHelp)
                       .above(0.0)
                       .exclusiveWith("voxel-count"));
        spec.push_back(Param::integer("voxel-count", "Voxel Count", set.voxelCountHelp)
                       .defaultValue(set.voxelCount)
                       .range(1, 100000)
                       .exclusiveWith("voxel-size"));
    }
    if (set.bands) {
        spec.push_back(Param::floating("exterior-band", "Exterior Band Voxels", set.exteriorHelp)
                       .defaultValue(set.band)
                       .range(0.0, set.maxBand, Bound::Exclusive, Bound::Inclusive));
        Param interior = Param::floating("interior-band", "Interior Band Voxels", set.interiorHelp)
                             .defaultValue(set.band)
                             .range(0.0, set.maxBand, Bound::Exclusive, Bound::Inclusive);
        if (!set.interiorExcludes.empty()) interior.exclusiveWith(set.interiorExcludes);
        spec.push_back(interior);
        if (set.worldUnits)
            spec.push_back(Param::flag("world-units", "Use World Space Units",
                                   "Read the band widths in world units instead of voxels"));
    }
    spec.push_back(Param::integer("max-voxels", "Max Voxels",
                                  "Refuse, before allocating, work whose voxel budget (the band's voxels plus "
                                  "working memory at 4 bytes a voxel) exceeds this; 0: no limit")
                       .defaultValue(set.maxVoxels)
                       .range(0.0, 9.0e18));
    spec.push_back(Param::string("grid-name", "Grid Name", "Name of the grid in the .vdb file")
                   .defaultValue(set.gridName));
    return spec;
}

void readGridParams(const OperatorArgs& args, GridSpec& grid)
{
    const OperatorSpec& spec = args.spec();
    if (spec.findParam("voxel-size")) {
        if (args.isSet("voxel-size")) {
            grid.voxelSize = args.getFloat("voxel-size");
        } else {
            grid.voxelCount = static_cast<int>(args.getInt("voxel-count"));
        }
    }
    if (spec.findParam("exterior-band")) {
        grid.exteriorWidth = args.getFloat("exterior-band");
        grid.interiorWidth = args.getFloat("interior-band");
    }
    if (spec.findParam("world-units"))
        grid.units = args.getBool("world-units") ? WidthUnits::World : WidthUnits::Voxels;
    if (spec.findParam("max-voxels")) grid.maxVoxels = static_cast<uint64_t>(args.getInt("max-voxels"));
    if (spec.findParam("grid-name")) grid.gridName = args.getString("grid-name");
}

} // namespace levelforge::ops
