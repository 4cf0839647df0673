// SPDX-License-Identifier: Apache-2.0
// Two-pass triangle lists in a VDB tree (Chang et al. §3.2). See TriangleListTree.h.
#include "detail/Timer.h"

#include <levelforge/core/Exceptions.h>
#include <levelforge/core/Progress.h>
#include <levelforge/mesh/TriangleListTree.h>

#include <openvdb/tree/LeafManager.h>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/enumerable_thread_specific.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <memory>

namespace levelforge {

namespace trianglelist_internal {

using TreeT = TriangleListTree::TreeType;
using LeafT = TreeT::LeafNodeType;

/// Triangles are voxelized in fixed chunks; each chunk keeps the cells it found (one buffer per
/// chunk, no per-cell allocation) so that pass 2 scatters without voxelizing again.
constexpr size_t kChunk = 256;

struct Chunk
{
    std::vector<openvdb::Coord> cells; // cells of the chunk's triangles, triangle after triangle
    std::vector<uint32_t> count;       // number of cells of each triangle of the chunk
};

/// Merges `src`'s counts into `dst` (leaves are moved when `dst` has none at that origin).
void mergeCounts(TreeT& dst, TreeT& src)
{
    // Every stolen leaf is owned until dst takes it: a failed allocation in addLeaf (a parent
    // node) frees the rest instead of leaking them.
    std::vector<std::unique_ptr<LeafT>> owned;
    owned.reserve(src.leafCount());
    {
        std::vector<LeafT*> leaves;
        leaves.reserve(owned.capacity());
        src.stealNodes(leaves);
        for (LeafT* leaf : leaves) owned.emplace_back(leaf); // capacity reserved: no throw
    }
    for (std::unique_ptr<LeafT>& leaf : owned) {
        if (LeafT* mine = dst.probeLeaf(leaf->origin())) {
            for (auto it = leaf->cbeginValueOn(); it; ++it) {
                const openvdb::Index n = it.pos();
                mine->setValueOn(n, mine->getValue(n) + *it);
            }
            leaf.reset();
        } else {
            dst.addLeaf(leaf.get());
            (void)leaf.release();
        }
    }
}

} // namespace trianglelist_internal

TriangleListTree TriangleListTree::build(const std::vector<Vec3d>& cellPoints,
                                         const std::vector<Vec3I>& triangles,
                                         const std::vector<uint32_t>& use,
                                         VoxelizerCounters* counters,
                                         openvdb::util::NullInterrupter* interrupter)
{
    using namespace trianglelist_internal;
    const auto t0 = detail::Clock::now();
    std::atomic<bool> stop{false};
    const size_t nChunks = (use.size() + kChunk - 1) / kChunk;
    std::vector<Chunk> chunks(nChunks);

    // Pass 1: voxelize, keep each chunk's cells, count triangles per cell in per-thread trees.
    struct Local
    {
        TreeT::Ptr tree{new TreeT(0u)};
        VoxelizerCounters counters;
    };
    tbb::enumerable_thread_specific<Local> locals;
    std::atomic<size_t> done{0};
    tbb::parallel_for(tbb::blocked_range<size_t>(0, nChunks, 1), [&](const tbb::blocked_range<size_t>& r) {
        if (stop.load(std::memory_order_relaxed)) return;
        Local& local = locals.local();
        openvdb::tree::ValueAccessor<TreeT> acc(*local.tree);
        for (size_t c = r.begin(); c != r.end(); ++c) {
            Chunk& chunk = chunks[c];
            const size_t first = c * kChunk, last = std::min(use.size(), first + kChunk);
            chunk.count.resize(last - first);
            for (size_t i = first; i < last; ++i) {
                const Vec3I& t = triangles[use[i]];
                const size_t before = chunk.cells.size();
                voxelizeTriangle(cellPoints[t[0]], cellPoints[t[1]], cellPoints[t[2]], chunk.cells, &local.counters);
                chunk.count[i - first] = uint32_t(chunk.cells.size() - before);
                for (size_t k = before; k < chunk.cells.size(); ++k) acc.modifyValue(chunk.cells[k], [](uint32_t& v) { ++v; });
            }
            chunk.cells.shrink_to_fit();
        }
        const size_t d = done.fetch_add(r.size()) + r.size();
        if (interrupter && interrupter->wasInterrupted(int(15 * d / std::max<size_t>(1, nChunks)))) stop = true;
    });
    if (stop) throw InterruptedError("interrupted while voxelizing triangles");

    TriangleListTree result;
    result.mTree.reset(new TreeT(0u));
    for (Local& local : locals) { // merge order does not change the sums
        mergeCounts(*result.mTree, *local.tree);
        if (counters) counters->add(local.counters);
    }
    TreeT& tree = *result.mTree;
    result.mSecondsVoxelize = detail::secondsSince(t0);
    const auto t1 = detail::Clock::now();

    // Number the cells in leaf order; prefix sums give each list's first slot.
    openvdb::tree::LeafManager<TreeT> leafs(tree);
    const size_t nLeaves = leafs.leafCount();
    std::vector<uint64_t> cellBase(nLeaves + 1, 0), entryBase(nLeaves + 1, 0);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, nLeaves, 64), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t l = r.begin(); l != r.end(); ++l) {
            uint64_t cells = 0, entries = 0;
            for (auto it = leafs.leaf(l).cbeginValueOn(); it; ++it) { ++cells; entries += *it; }
            cellBase[l + 1] = cells;
            entryBase[l + 1] = entries;
        }
    });
    for (size_t l = 0; l < nLeaves; ++l) {
        cellBase[l + 1] += cellBase[l];
        entryBase[l + 1] += entryBase[l];
    }
    const uint64_t nCells = cellBase[nLeaves], nEntries = entryBase[nLeaves];
    if (nCells >= 0xffffffffull || nEntries >= (1ull << 40))
        throw ResourceLimitError("too many boundary cells (" + std::to_string(nCells) +
                                 "): use a larger voxel size");
    result.mBegin.resize(nCells + 1);
    result.mIds.resize(nEntries);
    result.mBegin[nCells] = nEntries;
    tbb::parallel_for(tbb::blocked_range<size_t>(0, nLeaves, 64), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t l = r.begin(); l != r.end(); ++l) {
            uint64_t ord = cellBase[l], pos = entryBase[l];
            for (auto it = leafs.leaf(l).beginValueOn(); it; ++it) {
                result.mBegin[ord] = pos;
                pos += *it;
                it.setValue(uint32_t(ord));
                ++ord;
            }
        }
    });

    // Pass 2: fill from the kept cells. Atomic cursors per cell; each list is sorted afterwards
    // so the result does not depend on the thread schedule.
    std::unique_ptr<std::atomic<uint32_t>[]> cursor(new std::atomic<uint32_t>[nCells]());
    tbb::parallel_for(tbb::blocked_range<size_t>(0, nChunks, 1), [&](const tbb::blocked_range<size_t>& r) {
        openvdb::tree::ValueAccessor<const TreeT> acc(tree);
        for (size_t c = r.begin(); c != r.end(); ++c) {
            Chunk& chunk = chunks[c];
            size_t k = 0;
            for (size_t i = 0; i < chunk.count.size(); ++i) {
                const uint32_t id = use[c * kChunk + i];
                for (uint32_t j = 0; j < chunk.count[i]; ++j, ++k) {
                    const uint32_t ord = acc.getValue(chunk.cells[k]);
                    const uint32_t slot = cursor[ord].fetch_add(1, std::memory_order_relaxed);
                    result.mIds[result.mBegin[ord] + slot] = id;
                }
            }
            std::vector<openvdb::Coord>().swap(chunk.cells);
        }
    });
    if (interrupter && interrupter->wasInterrupted(19)) throw InterruptedError("interrupted while building triangle lists");
    tbb::parallel_for(tbb::blocked_range<size_t>(0, nCells, 4096), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t o = r.begin(); o != r.end(); ++o)
            std::sort(result.mIds.begin() + result.mBegin[o], result.mIds.begin() + result.mBegin[o + 1]);
    });
    result.mSecondsLists = detail::secondsSince(t1);
    return result;
}

size_t TriangleListTree::memoryUsage() const
{
    return (mTree ? size_t(mTree->memUsage()) : 0) + mBegin.capacity() * sizeof(uint64_t) +
           mIds.capacity() * sizeof(uint32_t);
}

} // namespace levelforge
