// SPDX-License-Identifier: Apache-2.0
// levelforge operator `info`: describe the grids of a .vdb file (like `vdb_print -l`).
#include "Operator.h"
#include "OperatorIO.h"
#include "Interrupt.h"
#include "OperatorText.h"

#include <levelforge/core/Metadata.h>
#include <levelforge/io/VdbIO.h>

#include <openvdb/openvdb.h>

#include <cstdio>
#include <ostream>
#include <string>

namespace levelforge::ops {
namespace {

std::string bytesText(uint64_t bytes)
{
    char buf[64];
    if (bytes >= (uint64_t(1) << 30)) {
        std::snprintf(buf, sizeof(buf), "%.2f GiB", double(bytes) / double(uint64_t(1) << 30));
    } else if (bytes >= (uint64_t(1) << 20)) {
        std::snprintf(buf, sizeof(buf), "%.2f MiB", double(bytes) / double(uint64_t(1) << 20));
    } else if (bytes >= 1024) {
        std::snprintf(buf, sizeof(buf), "%.2f KiB", double(bytes) / 1024.0);
    } else {
        std::snprintf(buf, sizeof(buf), "%llu B", static_cast<unsigned long long>(bytes));
    }
    return buf;
}

std::string metaText(const openvdb::GridBase& grid, const std::string& key)
{
    const auto m = grid[key];
    return m ? m->str() : std::string();
}

void describeGrid(std::ostream& os, const openvdb::GridBase& grid)
{
    os << "grid '" << grid.getName() << "'\n";
    os << "  type:           " << grid.valueType() << " (" << grid.type() << ")\n";
    os << "  class:          " << openvdb::GridBase::gridClassToString(grid.getGridClass())
       << "\n";
    const openvdb::Vec3d vs = grid.voxelSize();
    os << "  voxel size:     ";
    if (grid.hasUniformVoxels()) {
        os << vs[0];
    } else {
        os << vs;
    }
    os << " (world units)\n";
    os << "  active voxels:  " << withThousands(grid.activeVoxelCount()) << "\n";
    const openvdb::CoordBBox bbox = grid.evalActiveVoxelBoundingBox();
    if (bbox.empty()) {
        os << "  index bbox:     (empty)\n";
    } else {
        const openvdb::Coord dim = bbox.dim();
        os << "  index bbox:     " << bbox.min() << " -> " << bbox.max() << " (" << dim[0] << " x "
           << dim[1] << " x " << dim[2] << ")\n";
        const openvdb::BBoxd world = grid.transform().indexToWorld(bbox);
        os << "  world bbox:     " << world.min() << " -> " << world.max() << "\n";
    }
    const openvdb::Metadata::Ptr background = grid.baseTree().getBackgroundValue();
    os << "  background:     " << (background ? background->str() : std::string("?"));
    if (grid.getGridClass() == openvdb::GRID_LEVEL_SET && background &&
        background->typeName() == openvdb::FloatMetadata::staticTypeName() &&
        grid.hasUniformVoxels() && vs[0] > 0) {
        const float bg = static_cast<const openvdb::FloatMetadata&>(*background).value();
        char buf[64];
        std::snprintf(buf, sizeof(buf), " (%.3g voxels)", double(bg) / vs[0]);
        os << buf;
    }
    os << "\n";
    const std::string ext = metaText(grid, meta::kExteriorBandVoxels);
    const std::string in = metaText(grid, meta::kInteriorBandVoxels);
    if (!ext.empty() || !in.empty()) {
        os << "  band (voxels):  exterior " << (ext.empty() ? "?" : ext) << ", interior "
           << (in.empty() ? "?" : in) << "\n";
    }
    os << "  memory:         " << bytesText(grid.memUsage()) << "\n";
    bool header = false;
    for (auto it = grid.beginMeta(); it != grid.endMeta(); ++it) {
        const std::string& key = it->first;
        if (key == openvdb::GridBase::META_GRID_NAME || key == openvdb::GridBase::META_GRID_CLASS) {
            continue;
        }
        if (!header) os << "  metadata:\n";
        header = true;
        os << "    " << key << ": " << (it->second ? it->second->str() : std::string()) << "\n";
    }
}

void cookInfo(OperatorArgs& args)
{
    const std::string& path = args.input("file");
    openvdb::GridPtrVecPtr grids;
    grids = readGridsInput(args, path);
    const std::string& only = args.getString("grid");
    std::ostream& os = args.out();
    os << path << ": " << grids->size() << (grids->size() == 1 ? " grid" : " grids") << "\n";
    size_t shown = 0;
    for (const openvdb::GridBase::Ptr& grid : *grids) {
        if (!grid || (!only.empty() && grid->getName() != only)) continue;
        describeGrid(os, *grid);
        ++shown;
    }
    if (!only.empty() && shown == 0) {
        throw InvalidArgumentError("'" + path + "' has no grid named '" + only + "'");
    }
}

} // namespace

LEVELFORGE_REGISTER_OPERATOR(
    OperatorSpec("info", "Describe the grids of a .vdb file (like vdb_print -l)")
        .description("For every grid: name, value type, class, voxel size, active voxel count,\n"
                     "index and world bounding boxes, background, band widths, memory, metadata.")
        .input("file", ".vdb file to describe")
        .param(Param::string("grid", "Grid Name", "Describe only the grid with this name")
                   .defaultValue(""))
        .example("levelforge info bunny.vdb")
        .example("levelforge info bunny.vdb --grid surface")
        .cook(cookInfo));

} // namespace levelforge::ops
