// Two-pass triangle lists in a VDB tree (Chang et al. §3.2). See TriangleListTree.h.
#include <levelforge/Exceptions.h>
#include <levelforge/Progress.h>
#include <levelforge/TriangleListTree.h>

#include <openvdb/tree/LeafManager.h>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <atomic>
#include <memory>

namespace levelforge {

namespace trianglelist_internal {

using TreeT = TriangleListTree::TreeType;
using LeafT = TreeT::LeafNodeType;

/// Pass 1 body: counts triangles per cell in a private tree; joins by merging leaves.
struct CountBody
{
    const std::vector<Vec3d>& pts;
    const std::vector<Vec3I>& tris;
    const std::vector<uint32_t>& use;
    std::atomic<bool>& stop;
    openvdb::util::NullInterrupter* interrupter;
    TreeT::Ptr tree;
    VoxelizerCounters counters;
    std::vector<openvdb::Coord> cells;

    CountBody(const std::vector<Vec3d>& p, const std::vector<Vec3I>& t, const std::vector<uint32_t>& u,
              std::atomic<bool>& s, openvdb::util::NullInterrupter* i)
        : pts(p), tris(t), use(u), stop(s), interrupter(i), tree(new TreeT(0u)) {}
    CountBody(CountBody& o, tbb::split)
        : pts(o.pts), tris(o.tris), use(o.use), stop(o.stop), interrupter(o.interrupter), tree(new TreeT(0u)) {}

    void operator()(const tbb::blocked_range<size_t>& r)
    {
        if (stop.load(std::memory_order_relaxed)) return;
        if (interrupter && interrupter->wasInterrupted(int(10 * r.begin() / std::max<size_t>(1, use.size())))) {
            stop = true;
            return;
        }
        openvdb::tree::ValueAccessor<TreeT> acc(*tree);
        for (size_t i = r.begin(); i != r.end(); ++i) {
            const Vec3I& t = tris[use[i]];
            cells.clear();
            voxelizeTriangle(pts[t[0]], pts[t[1]], pts[t[2]], cells, &counters);
            for (const openvdb::Coord& c : cells) acc.modifyValue(c, [](uint32_t& v) { ++v; });
        }
    }

    void join(CountBody& o)
    {
        counters.add(o.counters);
        std::vector<LeafT*> leaves;
        o.tree->stealNodes(leaves);
        for (LeafT* leaf : leaves) {
            if (LeafT* mine = tree->probeLeaf(leaf->origin())) {
                for (auto it = leaf->cbeginValueOn(); it; ++it) {
                    const openvdb::Index n = it.pos();
                    mine->setValueOn(n, mine->getValue(n) + *it);
                }
                delete leaf;
            } else {
                tree->addLeaf(leaf);
            }
        }
    }
};

} // namespace trianglelist_internal

TriangleListTree TriangleListTree::build(const std::vector<Vec3d>& cellPoints,
                                         const std::vector<Vec3I>& triangles,
                                         const std::vector<uint32_t>& use,
                                         VoxelizerCounters* counters,
                                         openvdb::util::NullInterrupter* interrupter)
{
    using namespace trianglelist_internal;
    std::atomic<bool> stop{false};

    // Pass 1: topology + counts.
    CountBody body(cellPoints, triangles, use, stop, interrupter);
    tbb::parallel_reduce(tbb::blocked_range<size_t>(0, use.size(), 512), body);
    if (stop) throw InterruptedError("interrupted while voxelizing triangles");
    if (counters) counters->add(body.counters);

    TriangleListTree result;
    result.mTree = body.tree;
    TreeT& tree = *result.mTree;

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

    // Pass 2: fill. Atomic cursors per cell; the order inside a list is fixed afterwards.
    std::unique_ptr<std::atomic<uint32_t>[]> cursor(new std::atomic<uint32_t>[nCells]());
    tbb::parallel_for(tbb::blocked_range<size_t>(0, use.size(), 512), [&](const tbb::blocked_range<size_t>& r) {
        if (stop.load(std::memory_order_relaxed)) return;
        if (interrupter && interrupter->wasInterrupted(int(10 + 10 * r.begin() / std::max<size_t>(1, use.size())))) {
            stop = true;
            return;
        }
        thread_local std::vector<openvdb::Coord> cells;
        openvdb::tree::ValueAccessor<const TreeT> acc(tree);
        for (size_t i = r.begin(); i != r.end(); ++i) {
            const uint32_t id = use[i];
            const Vec3I& t = triangles[id];
            cells.clear();
            voxelizeTriangle(cellPoints[t[0]], cellPoints[t[1]], cellPoints[t[2]], cells, nullptr);
            for (const openvdb::Coord& c : cells) {
                const uint32_t ord = acc.getValue(c);
                const uint32_t slot = cursor[ord].fetch_add(1, std::memory_order_relaxed);
                result.mIds[result.mBegin[ord] + slot] = id;
            }
        }
    });
    if (stop) throw InterruptedError("interrupted while building triangle lists");
    tbb::parallel_for(tbb::blocked_range<size_t>(0, nCells, 4096), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t o = r.begin(); o != r.end(); ++o)
            std::sort(result.mIds.begin() + result.mBegin[o], result.mIds.begin() + result.mBegin[o + 1]);
    });
    return result;
}

size_t TriangleListTree::memoryUsage() const
{
    return (mTree ? size_t(mTree->memUsage()) : 0) + mBegin.capacity() * sizeof(uint64_t) +
           mIds.capacity() * sizeof(uint32_t);
}

} // namespace levelforge
