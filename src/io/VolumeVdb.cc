// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Scalar grids of .vdb files as dense volumes or sparse float grids: readVdbVolume() and
///        readVdbScalarGrid().
#include "io/VolumeIOInternal.h"

#include <levelforge/io/VdbIO.h>

#include <openvdb/tools/Dense.h>

#include <cmath>

namespace levelforge {

namespace volumeio_internal {

// -------------------------------------------------------------------------------------- vdb

template<typename GridT>
ScalarVolume denseFromGrid(const std::string& path, const GridT& grid, uint64_t maxVoxels, int padding)
{
    openvdb::CoordBBox bbox = grid.evalActiveVoxelBoundingBox();
    if (bbox.empty() || grid.activeVoxelCount() == 0) {
        throwInvalid(path, "grid '" + grid.getName() + "' has no active voxels");
    }
    bbox.expand(std::max(0, padding));
    const openvdb::Coord d = bbox.dim();
    const int64_t dims[3] = {d.x(), d.y(), d.z()};
    const char* dimNames[3] = {"x", "y", "z"};
    const uint64_t count = checkDims(path, dims, maxVoxels, dimNames);
    ScalarVolume vol;
    allocate(path, vol, dims, count);
    openvdb::tools::Dense<float, openvdb::tools::LayoutXYZ> dense(bbox, vol.data.data());
    openvdb::tools::copyToDense(grid, dense);
    return vol;
}

/// The scalar grid readVdb() converts (checked: scalar type, axis-aligned positive scale).
openvdb::GridBase::Ptr chooseScalarGrid(const std::string& path, const ReadVolumeOptions& options, VolumeInfo& info)
{
    {
        // Existence and type checks with this module's messages; readGrids() does the rest.
        InputFile probe(path);
    }
    openvdb::GridPtrVecPtr grids = readGrids(path);
    info.format = "vdb";
    auto scalarType = [](const openvdb::GridBase& g, VolumeValueType& t) {
        if (g.isType<openvdb::FloatGrid>()) t = VolumeValueType::Float32;
        else if (g.isType<openvdb::DoubleGrid>()) t = VolumeValueType::Float64;
        else if (g.isType<openvdb::Int32Grid>()) t = VolumeValueType::Int32;
        else if (g.isType<openvdb::Int64Grid>()) t = VolumeValueType::Int64;
        else return false;
        return true;
    };
    openvdb::GridBase::Ptr chosen;
    std::string available;
    for (const auto& g : *grids) {
        if (!g) continue;
        available += (available.empty() ? "" : ", ") + ("'" + g->getName() + "' (" + g->valueType() + ")");
        VolumeValueType t;
        const bool scalar = scalarType(*g, t);
        if (options.vdbGridName.empty() ? (scalar && !chosen) : (g->getName() == options.vdbGridName && !chosen)) {
            if (!scalar) {
                throwInvalid(path, "grid '" + g->getName() + "' holds " + g->valueType() +
                                       " values; only float, double, int32 and int64 grids can be read as volumes");
            }
            chosen = g;
            info.sourceType = t;
        }
    }
    if (!chosen) {
        if (options.vdbGridName.empty()) {
            throwInvalid(path, "no float, double, int32 or int64 grid (grids: " +
                                   (available.empty() ? std::string("none") : available) + ")");
        }
        throwInvalid(path, "no grid named '" + options.vdbGridName + "' (grids: " +
                               (available.empty() ? std::string("none") : available) + ")");
    }
    info.gridName = chosen->getName();

    const openvdb::math::Transform& xf = chosen->transform();
    const std::string gridText = "grid '" + chosen->getName() + "': ";
    if (!xf.isLinear()) {
        throwInvalid(path, gridText + "the transform (" + xf.mapType() +
                               ") is not linear; only axis-aligned scale + translation can be read as a volume");
    }
    const openvdb::Mat4d m = xf.baseMap()->getAffineMap()->getMat4();
    double maxDiag = 0.0;
    for (int a = 0; a < 3; ++a) maxDiag = std::max(maxDiag, std::fabs(m[a][a]));
    for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) {
            if (r != c && std::fabs(m[r][c]) > 1e-9 * maxDiag) {
                throwInvalid(path, gridText + "the transform rotates or shears the voxel axes; only axis-aligned "
                                              "scale + translation can be read as a volume");
            }
        }
        if (!(m[r][r] > 0.0)) {
            throwInvalid(path, gridText + "the transform's scale along axis " + std::to_string(r) + " is " +
                                   formatDouble(m[r][r]) + "; it must be > 0 (no mirroring)");
        }
    }

    return chosen;
}

ScalarVolume readVdb(const std::string& path, const ReadVolumeOptions& options, VolumeInfo& info)
{
    const openvdb::GridBase::Ptr chosen = chooseScalarGrid(path, options, info);
    const openvdb::math::Transform& xf = chosen->transform();
    const std::string gridText = "grid '" + chosen->getName() + "': ";
    const openvdb::Mat4d m = xf.baseMap()->getAffineMap()->getMat4();
    ScalarVolume vol;
    switch (info.sourceType) {
    case VolumeValueType::Float32:
        vol = denseFromGrid(path, static_cast<const openvdb::FloatGrid&>(*chosen), options.maxVoxels, options.vdbPadding); break;
    case VolumeValueType::Float64:
        vol = denseFromGrid(path, static_cast<const openvdb::DoubleGrid&>(*chosen), options.maxVoxels, options.vdbPadding); break;
    case VolumeValueType::Int32:
        vol = denseFromGrid(path, static_cast<const openvdb::Int32Grid&>(*chosen), options.maxVoxels, options.vdbPadding); break;
    default:
        vol = denseFromGrid(path, static_cast<const openvdb::Int64Grid&>(*chosen), options.maxVoxels, options.vdbPadding); break;
    }
    openvdb::CoordBBox bbox = chosen->evalActiveVoxelBoundingBox();
    bbox.expand(std::max(0, options.vdbPadding));
    vol.spacing = openvdb::Vec3d(m[0][0], m[1][1], m[2][2]);
    vol.origin = xf.indexToWorld(bbox.min());
    finish(path, vol, info, gridText.substr(0, gridText.size() - 2));
    return vol;
}

} // namespace volumeio_internal

// ================================================================================== public API

openvdb::FloatGrid::Ptr readVdbScalarGrid(const std::string& path, const ReadVolumeOptions& options, VolumeInfo* info)
{
    if (volumeio_internal::formatFromExtension(path) != volumeio_internal::Format::Vdb)
        volumeio_internal::throwInvalid(path, "not a .vdb file (only OpenVDB grids can be read without densifying)");
    VolumeInfo local;
    const openvdb::GridBase::Ptr chosen = volumeio_internal::chooseScalarGrid(path, options, local);
    openvdb::FloatGrid::Ptr out;
    switch (local.sourceType) {
    case VolumeValueType::Float32:
        out = openvdb::gridPtrCast<openvdb::FloatGrid>(chosen); // read for us: nothing to share
        break;
    case VolumeValueType::Float64:
        out = openvdb::FloatGrid::create(std::make_shared<openvdb::FloatTree>(
            openvdb::gridConstPtrCast<openvdb::DoubleGrid>(chosen)->tree()));
        break;
    case VolumeValueType::Int32:
        out = openvdb::FloatGrid::create(std::make_shared<openvdb::FloatTree>(
            openvdb::gridConstPtrCast<openvdb::Int32Grid>(chosen)->tree()));
        break;
    default:
        out = openvdb::FloatGrid::create(std::make_shared<openvdb::FloatTree>(
            openvdb::gridConstPtrCast<openvdb::Int64Grid>(chosen)->tree()));
        break;
    }
    out->setTransform(chosen->transform().copy());
    out->setName(chosen->getName());
    if (info) *info = std::move(local);
    return out;
}

ScalarVolume readVdbVolume(const std::string& path, const ReadVolumeOptions& options, VolumeInfo* info)
{
    VolumeInfo local;
    ScalarVolume vol = volumeio_internal::readVdb(path, options, local);
    if (info) *info = std::move(local);
    return vol;
}

} // namespace levelforge
