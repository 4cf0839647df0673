// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Scalar grids of .vdb files as dense volumes or sparse float grids: readVdbVolume() and
///        readVdbScalarGrid().
#include "io/VolumeIOInternal.h"

#include <levelforge/io/VdbIO.h>

#include <openvdb/tools/Dense.h>
#include <openvdb/tree/LeafManager.h>

#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <type_traits>

namespace levelforge {

namespace volumeio_internal {

// -------------------------------------------------------------------------------------- vdb

/// Index coordinates a dense box may reach: every corner of the box (the active voxels grown by
/// the padding) within +-2^30, so that its extent and OpenVDB's box arithmetic (copyToDense()
/// splits boxes at (min + max) / 2) stay inside int.
constexpr int64_t kMaxDenseCoord = int64_t(1) << 30;

std::string coordText(const openvdb::Coord& c)
{
    return "(" + std::to_string(c.x()) + ", " + std::to_string(c.y()) + ", " + std::to_string(c.z()) + ")";
}

/// The dense box of a grid: its active-voxel bounding box grown by @a padding voxels on every
/// side, checked against the int range before any arithmetic on it.
template<typename GridT>
openvdb::CoordBBox denseBox(const std::string& path, const GridT& grid, int padding)
{
    const openvdb::CoordBBox active = grid.evalActiveVoxelBoundingBox();
    if (active.empty() || grid.activeVoxelCount() == 0) {
        throwInvalid(path, "grid '" + grid.getName() + "' has no active voxels");
    }
    const int64_t pad = std::max(0, padding);
    for (int k = 0; k < 3; ++k) {
        if (int64_t(active.min()[k]) - pad < -kMaxDenseCoord || int64_t(active.max()[k]) + pad > kMaxDenseCoord) {
            throwInvalid(path, "grid '" + grid.getName() + "': the active voxels span " + coordText(active.min()) +
                                   " - " + coordText(active.max()) +
                                   (pad > 0 ? " (grown by " + std::to_string(pad) + " voxels of padding)" : std::string()) +
                                   ", beyond the index range +-2^30 a dense volume can be made of");
        }
    }
    openvdb::CoordBBox box = active;
    box.expand(int(pad));
    return box;
}

template<typename GridT>
ScalarVolume denseFromGrid(const std::string& path, const GridT& grid, const openvdb::CoordBBox& bbox, uint64_t maxVoxels)
{
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

/// Where the first non-finite value of a grid is (background, a tile, or a voxel), empty when
/// there is none. For double grids a finite value beyond the float range counts too (it would
/// become Inf as float). Leaves are checked in parallel (LeafManager), the first bad leaf in
/// tree order is reported, so the message does not depend on the thread count; tiles (few,
/// internal nodes) in one pass.
template<typename GridT>
std::string firstNonFinite(const GridT& grid)
{
    using TreeT = typename GridT::TreeType;
    using ValueT = typename GridT::ValueType;
    if constexpr (!std::is_floating_point_v<ValueT>) {
        (void)grid;
        return {};
    } else {
        auto bad = [](ValueT v) {
            if constexpr (std::is_same_v<ValueT, float>) return !std::isfinite(v);
            else return !(std::fabs(v) <= double(std::numeric_limits<float>::max())); // NaN, Inf, beyond float
        };
        auto valueText = [](ValueT v) {
            return std::isfinite(v) ? formatDouble(double(v)) + ", beyond the float range" : formatDouble(double(v));
        };
        const TreeT& tree = grid.tree();
        if (bad(tree.background())) return "the background value is not finite (" + valueText(tree.background()) + ")";
        // tiles of the internal nodes and the root (leaf voxels excluded)
        typename TreeT::ValueAllCIter tile = tree.cbeginValueAll();
        tile.setMaxDepth(TreeT::ValueAllCIter::LEAF_DEPTH - 1);
        for (; tile; ++tile) {
            if (!bad(*tile)) continue;
            openvdb::CoordBBox b;
            tile.getBoundingBox(b);
            return std::string(tile.isValueOn() ? "active" : "inactive") + " tile " + coordText(b.min()) + " - " +
                   coordText(b.max()) + " holds a non-finite value (" + valueText(*tile) + ")";
        }
        openvdb::tree::LeafManager<const TreeT> leaves(tree);
        const size_t none = leaves.leafCount();
        const size_t first = tbb::parallel_reduce(
            tbb::blocked_range<size_t>(0, leaves.leafCount()), none,
            [&](const tbb::blocked_range<size_t>& r, size_t best) {
                for (size_t i = r.begin(); i < r.end() && i < best; ++i) {
                    const ValueT* v = leaves.leaf(i).buffer().data();
                    bool any = false;
                    for (openvdb::Index n = 0; n < TreeT::LeafNodeType::SIZE; ++n) any |= bad(v[n]);
                    if (any) return i;
                }
                return best;
            },
            [](size_t a, size_t b) { return std::min(a, b); });
        if (first == none) return {};
        const auto& leaf = leaves.leaf(first);
        for (openvdb::Index n = 0; n < TreeT::LeafNodeType::SIZE; ++n) {
            const ValueT v = leaf.getValue(n);
            if (!bad(v)) continue;
            return std::string(leaf.isValueOn(n) ? "active" : "inactive") + " voxel " +
                   coordText(leaf.offsetToGlobalCoord(n)) + " holds a non-finite value (" + valueText(v) + ")";
        }
        return {};
    }
}

/// Throws InvalidVolumeError naming the file, the grid and the first non-finite value.
void requireFiniteValues(const std::string& path, const openvdb::GridBase& grid, VolumeValueType type)
{
    std::string where;
    if (type == VolumeValueType::Float32) where = firstNonFinite(static_cast<const openvdb::FloatGrid&>(grid));
    else if (type == VolumeValueType::Float64) where = firstNonFinite(static_cast<const openvdb::DoubleGrid&>(grid));
    if (!where.empty()) throwInvalid(path, "grid '" + grid.getName() + "': " + where);
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
    openvdb::CoordBBox bbox;
    auto dense = [&](const auto& grid) {
        bbox = denseBox(path, grid, options.vdbPadding);
        vol = denseFromGrid(path, grid, bbox, options.maxVoxels);
    };
    switch (info.sourceType) {
    case VolumeValueType::Float32: dense(static_cast<const openvdb::FloatGrid&>(*chosen)); break;
    case VolumeValueType::Float64:
        // a double beyond the float range must not reach the conversion to float
        requireFiniteValues(path, *chosen, info.sourceType);
        dense(static_cast<const openvdb::DoubleGrid&>(*chosen));
        break;
    case VolumeValueType::Int32: dense(static_cast<const openvdb::Int32Grid&>(*chosen)); break;
    default: dense(static_cast<const openvdb::Int64Grid&>(*chosen)); break;
    }
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
    // NaN / Inf (or, for double grids, beyond the float range) anywhere: background, tiles, voxels.
    volumeio_internal::requireFiniteValues(path, *chosen, local.sourceType);
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
