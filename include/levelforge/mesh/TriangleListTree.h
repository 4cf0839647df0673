// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Per-boundary-cell triangle lists stored in a sparse VDB tree (Chang et al. §3.2).
///
/// Built in two passes, as the paper prescribes, with no per-cell allocation:
///   pass 1 voxelizes every triangle (MicrotriangleVoxelizer.h) and counts, per boundary cell,
///          how many triangles overlap it (the cells are the active voxels of a UInt32Tree);
///   then   cells are numbered in leaf order and one index array is allocated (prefix sums);
///   pass 2 drops each triangle id into its cells' slots; every list is finally sorted by
///          triangle id so the structure is identical for any thread count.
/// Unlike the paper, pass 2 does not voxelize again: pass 1 keeps the cells it found, in one
/// buffer per chunk of 256 triangles (12 bytes per list entry, freed during pass 2). That
/// halves the voxelization time for a transient memory cost of about 3× the index array.
/// The tree maps a cell (cell space: voxel ijk ↔ cell ijk) to its ordinal; the ordinal indexes
/// `begin`, whose consecutive entries delimit the list in `ids`.
#pragma once

#include <levelforge/mesh/MicrotriangleVoxelizer.h>
#include <levelforge/core/TriangleMesh.h>

#include <openvdb/openvdb.h>
#include <openvdb/util/NullInterrupter.h>

#include <cstdint>
#include <vector>

namespace levelforge {

class TriangleListTree
{
public:
    using TreeType = openvdb::UInt32Tree;

    /// `cellPoints` are the mesh vertices in cell space; `triangles` index them; only the
    /// triangles listed in `use` (ids into `triangles`) are voxelized. Throws InterruptedError.
    static TriangleListTree build(const std::vector<Vec3d>& cellPoints,
                                  const std::vector<Vec3I>& triangles,
                                  const std::vector<uint32_t>& use,
                                  VoxelizerCounters* counters = nullptr,
                                  openvdb::util::NullInterrupter* interrupter = nullptr);

    /// Active voxels = boundary cells; value = cell ordinal.
    const TreeType& tree() const { return *mTree; }
    TreeType::Ptr treePtr() const { return mTree; }
    uint64_t cellCount() const { return mBegin.empty() ? 0 : mBegin.size() - 1; }
    uint64_t entryCount() const { return mIds.size(); }

    /// The triangle ids overlapping the cell with this ordinal: [first, last).
    const uint32_t* listBegin(uint32_t ordinal) const { return mIds.data() + mBegin[ordinal]; }
    const uint32_t* listEnd(uint32_t ordinal) const { return mIds.data() + mBegin[ordinal + 1]; }
    uint32_t listSize(uint32_t ordinal) const { return uint32_t(mBegin[ordinal + 1] - mBegin[ordinal]); }

    /// Wall-clock seconds of build(): pass 1 (voxelization and counting) and the rest (numbering,
    /// pass 2, sorting).
    double secondsVoxelize() const { return mSecondsVoxelize; }
    double secondsLists() const { return mSecondsLists; }

    /// Bytes held by the tree and the arrays.
    size_t memoryUsage() const;

private:
    TreeType::Ptr mTree;
    std::vector<uint64_t> mBegin; ///< size cellCount()+1
    std::vector<uint32_t> mIds;
    double mSecondsVoxelize = 0.0, mSecondsLists = 0.0;
};

} // namespace levelforge
