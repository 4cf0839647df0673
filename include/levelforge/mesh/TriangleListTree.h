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

/// @brief The triangle list of every boundary cell (see the file comment).
class TriangleListTree
{
public:
    using TreeType = openvdb::UInt32Tree;

    /// @brief Builds the lists in two passes (see the file comment).
    ///
    /// `cellPoints` are the mesh vertices in cell space; `triangles` index them; only the
    /// triangles listed in `use` (ids into `triangles`) are voxelized. Throws InterruptedError.
    /// Parallel (TBB); the result does not depend on the number of threads.
    /// @param[in]     cellPoints   mesh vertices in cell space (world / voxelSize + 0.5)
    /// @param[in]     triangles    vertex indices into @p cellPoints
    /// @param[in]     use          ids into @p triangles of the triangles to list (e.g. the
    ///                             non-degenerate ones); the lists hold these ids
    /// @param[in,out] counters     optional: the voxelizer counters of all triangles are added
    /// @param[in]     interrupter  optional: polled during pass 1 (progress 0–15%). Not owned.
    /// @return the tree and its lists
    /// @throws InterruptedError the interrupter asked to stop during voxelization
    static TriangleListTree build(const std::vector<Vec3d>& cellPoints,
                                  const std::vector<Vec3I>& triangles,
                                  const std::vector<uint32_t>& use,
                                  VoxelizerCounters* counters = nullptr,
                                  openvdb::util::NullInterrupter* interrupter = nullptr);

    /// @brief The cell tree: active voxels = boundary cells; value = cell ordinal.
    const TreeType& tree() const { return *mTree; }
    TreeType::Ptr treePtr() const { return mTree; }
    uint64_t cellCount() const { return mBegin.empty() ? 0 : mBegin.size() - 1; }
    uint64_t entryCount() const { return mIds.size(); }

    /// @brief The triangle ids overlapping the cell with this ordinal: [first, last).
    /// @param[in] ordinal  the cell's ordinal (its value in tree()), < cellCount()
    /// @return a pointer to the first id of the list (sorted ascending)
    const uint32_t* listBegin(uint32_t ordinal) const { return mIds.data() + mBegin[ordinal]; }
    /// @brief One past the last triangle id of the cell with this ordinal.
    /// @param[in] ordinal  the cell's ordinal (its value in tree()), < cellCount()
    /// @return a pointer one past the list's last id
    const uint32_t* listEnd(uint32_t ordinal) const { return mIds.data() + mBegin[ordinal + 1]; }
    /// @brief The number of triangles overlapping the cell with this ordinal.
    /// @param[in] ordinal  the cell's ordinal (its value in tree()), < cellCount()
    /// @return listEnd(ordinal) - listBegin(ordinal)
    uint32_t listSize(uint32_t ordinal) const { return uint32_t(mBegin[ordinal + 1] - mBegin[ordinal]); }

    /// Wall-clock seconds of build(): pass 1 (voxelization and counting) and the rest (numbering,
    /// pass 2, sorting).
    double secondsVoxelize() const { return mSecondsVoxelize; }
    double secondsLists() const { return mSecondsLists; }

    /// @brief Memory held by the tree and the arrays.
    /// @return bytes (tree memory plus the capacity of the index arrays)
    size_t memoryUsage() const;

private:
    TreeType::Ptr mTree;
    std::vector<uint64_t> mBegin; ///< size cellCount()+1
    std::vector<uint32_t> mIds;
    double mSecondsVoxelize = 0.0, mSecondsLists = 0.0;
};

} // namespace levelforge
