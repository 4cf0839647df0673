// SPDX-License-Identifier: Apache-2.0
// ADF value pipeline (see AdaptiveDistanceField.h): classifies every storage location of a
// layout's tree (free corner / hanging / unused), asks a sample provider for the free samples
// (leaves, then level-1 and level-2 tiles) and resolves the hanging ones, coarsest cells first,
// so that the reconstruction is C0.
#include "adf/AdfInternal.h"

#include "detail/Timer.h"

#include <levelforge/core/Exceptions.h>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <array>
#include <atomic>
#include <vector>

namespace levelforge {
namespace adf_internal {

namespace {

/// A constrained leaf voxel: its offset and the coarsest touching cell (size, origin relative to
/// the leaf origin: within [-128, 7] on each axis).
struct HangItem
{
    uint16_t off;
    uint8_t size;
    int8_t dx, dy, dz;
};
constexpr int kHangSizes[4] = {128, 8, 4, 2}; // resolution order: coarsest cells first

/// The coarsest in-domain cell touching lattice point p (size 0 when none).
CellInfo coarsestTouching(Reconstruction& r, const CoordBBox& dom, const Coord& p)
{
    CellInfo best;
    for (int d = 0; d < 8; ++d) {
        const Coord c = p - Coord((d >> 2) & 1, (d >> 1) & 1, d & 1);
        if (!inDomainCell(dom, c)) continue;
        const CellInfo X = r.cellAt(c);
        if (X.size > best.size) best = X;
    }
    return best;
}

inline bool isCornerOf(const CellInfo& X, const Coord& p)
{
    for (int k = 0; k < 3; ++k) {
        const int t = p[k] - X.origin[k];
        if (t != 0 && t != X.size) return false;
    }
    return true;
}

} // namespace

PipelineResult fillValues(FloatTree& tree, const Layout& layout, SampleProvider& provider,
                          openvdb::util::NullInterrupter* interrupter)
{
    PipelineResult res;
    const CoordBBox dom = layout.domain;
    const size_t nLeaves = layout.leafOrigins.size();
    std::vector<FloatLeaf*> leaves(nLeaves);
    for (size_t i = 0; i < nLeaves; ++i) leaves[i] = tree.probeLeaf(layout.leafOrigins[i]);

    // ---- leaves: classification (free / hanging), then the provider's free samples
    const auto t0 = detail::Clock::now();
    // constrained voxels per leaf, grouped by the size of their cell (kHangSizes order)
    std::vector<std::vector<HangItem>> hangLeaf(nLeaves);
    std::vector<std::array<uint32_t, 5>> hangBegin(nLeaves);
    std::atomic<bool> stop{false};
    tbb::parallel_for(tbb::blocked_range<size_t>(0, nLeaves, 4), [&](const tbb::blocked_range<size_t>& range) {
        if (stop) return;
        Reconstruction rec(tree, dom);
        uint8_t isFree[512];
        HangItem hang[4][512];
        for (size_t i = range.begin(); i != range.end(); ++i) {
            FloatLeaf* leaf = leaves[i];
            const Coord o = leaf->origin();
            // cell sizes of the 9³ unit cells [o-1, o+7]: the own block and the 7 blocks below
            // it (index bit set = the own block on that axis), each looked up once: a leaf's
            // sizes come from its mask, otherwise one cell (an 8³ tile or a 128³ cell) covers it
            // (the same as Reconstruction::cellAt cell by cell)
            LeafCellSizes blockSizes[8];
            CellInfo blockCell[8];
            bool blockIsLeaf[8];
            for (int b = 0; b < 8; ++b) {
                const Coord c0 = o + Coord((b & 4) ? 0 : -8, (b & 2) ? 0 : -8, (b & 1) ? 0 : -8);
                const FloatLeaf* nl = b == 7 ? leaf : tree.probeConstLeaf(c0);
                blockIsLeaf[b] = nl != nullptr;
                if (nl) blockSizes[b] = LeafCellSizes(nl->getValueMask());
                else blockCell[b] = rec.cellAt(c0);
            }
            CellInfo cells[729];
            for (int x = 0; x < 9; ++x)
                for (int y = 0; y < 9; ++y)
                    for (int z = 0; z < 9; ++z) {
                        const Coord c = o + Coord(x - 1, y - 1, z - 1);
                        CellInfo& X = cells[(x * 9 + y) * 9 + z];
                        const int b = (x > 0 ? 4 : 0) | (y > 0 ? 2 : 0) | (z > 0 ? 1 : 0);
                        if (b != 7 && !inDomainCell(dom, c)) {
                            X = CellInfo{};
                        } else if (blockIsLeaf[b]) {
                            const int sz = blockSizes[b].size(c.x() & 7, c.y() & 7, c.z() & 7);
                            X = {sz, Coord(c.x() & ~(sz - 1), c.y() & ~(sz - 1), c.z() & ~(sz - 1))};
                        } else {
                            X = blockCell[b];
                        }
                    }
            int nHang[4] = {0, 0, 0, 0};
            for (int x = 0; x < 8; ++x)
                for (int y = 0; y < 8; ++y)
                    for (int z = 0; z < 8; ++z) {
                        const int off = (x << 6) | (y << 3) | z;
                        CellInfo S;
                        for (int d = 0; d < 8; ++d) {
                            const CellInfo& X = cells[((x + 1 - ((d >> 2) & 1)) * 9 + (y + 1 - ((d >> 1) & 1))) * 9 + (z + 1 - (d & 1))];
                            if (X.size > S.size) S = X;
                        }
                        const Coord p = o + Coord(x, y, z);
                        isFree[off] = S.size > 0 && isCornerOf(S, p);
                        if (isFree[off] || S.size == 0) continue;
                        // S.size is 2, 4, 8 or 128 here (a size-1 cell has every touching point as corner)
                        const int cls = S.size == 128 ? 0 : S.size == 8 ? 1 : S.size == 4 ? 2 : 3;
                        hang[cls][nHang[cls]++] = {uint16_t(off), uint8_t(S.size), int8_t(S.origin.x() - o.x()),
                                                   int8_t(S.origin.y() - o.y()), int8_t(S.origin.z() - o.z())};
                    }
            std::vector<HangItem>& hl = hangLeaf[i];
            hl.clear();
            hl.reserve(size_t(nHang[0] + nHang[1] + nHang[2] + nHang[3]));
            for (int k = 0; k < 4; ++k) {
                hangBegin[i][size_t(k)] = uint32_t(hl.size());
                hl.insert(hl.end(), hang[k], hang[k] + nHang[k]);
            }
            hangBegin[i][4] = uint32_t(hl.size());
            provider.leafSamples(i, *leaf, isFree, leaf->buffer().data());
        }
        if (interrupter && interrupter->wasInterrupted()) stop = true;
    });
    if (stop) throw InterruptedError("interrupted while computing ADF leaf samples");
    res.secondsLeaves = detail::secondsSince(t0);

    provider.afterLeaves(tree);

    // ---- tiles: level-1 tiles of the internal-1 nodes and level-2 tiles
    const auto t1 = detail::Clock::now();
    struct TilePoint { Coord p; int level; };
    std::vector<TilePoint> tiles;
    for (const Coord& b : layout.subdividedL2) {
        const Internal1* n1 = tree.root().template probeConstNode<Internal1>(b);
        if (!n1) continue;
        for (openvdb::Index n = 0; n < Internal1::NUM_VALUES; ++n)
            if (!n1->isChildMaskOn(n)) tiles.push_back({n1->offsetToGlobalCoord(n), 1});
    }
    for (const Coord& b : layout.tileL2) tiles.push_back({b, 2});
    std::vector<float> tileValue(tiles.size(), 0.0f);
    std::vector<CellInfo> tileHang(tiles.size());
    std::vector<uint8_t> tileKind(tiles.size(), 0); // 0 unused, 1 free, 2 hanging
    tbb::parallel_for(tbb::blocked_range<size_t>(0, tiles.size(), 256), [&](const tbb::blocked_range<size_t>& range) {
        Reconstruction rec(tree, dom);
        for (size_t i = range.begin(); i != range.end(); ++i) {
            const CellInfo S = coarsestTouching(rec, dom, tiles[i].p);
            if (S.size == 0) continue;
            if (isCornerOf(S, tiles[i].p)) {
                tileKind[i] = 1;
                tileValue[i] = float(provider.tileSample(tiles[i].p));
            } else {
                tileKind[i] = 2;
                tileHang[i] = S;
            }
        }
    });
    for (size_t i = 0; i < tiles.size(); ++i)
        if (tileKind[i] == 1) tree.addTile(openvdb::Index(tiles[i].level), tiles[i].p, tileValue[i], false);
    res.secondsTiles = detail::secondsSince(t1);

    // ---- hanging points, coarsest cells first (their corners are final by then)
    const auto t2 = detail::Clock::now();
    for (int cls = 0; cls < 4; ++cls) {
        const int size = kHangSizes[cls];
        std::vector<size_t> tileIdx;
        for (size_t i = 0; i < tiles.size(); ++i)
            if (tileKind[i] == 2 && tileHang[i].size == size) tileIdx.push_back(i);
        // every value of this round is the trilinear value of a cell whose corners are final
        // (free, or constrained by a coarser cell in an earlier round): any order gives the same
        struct Cache
        {
            explicit Cache(Reconstruction r) : rec(r) {}
            Reconstruction rec;
            CellInfo lastS{0, Coord(0)};
            double lastV[8] = {0, 0, 0, 0, 0, 0, 0, 0};
            // the trilinear value of cell S at p, reusing the corner values of the previous cell
            double interp(const CellInfo& S, const Coord& p)
            {
                if (S.size != lastS.size || S.origin != lastS.origin) {
                    for (int c = 0; c < 8; ++c)
                        lastV[c] = rec.value(S.origin + Coord(((c >> 2) & 1) * S.size, ((c >> 1) & 1) * S.size, (c & 1) * S.size));
                    lastS = S;
                }
                const Vec3d t(double(p.x() - S.origin.x()) / S.size, double(p.y() - S.origin.y()) / S.size,
                              double(p.z() - S.origin.z()) / S.size);
                return Reconstruction::trilinear(lastV, t, nullptr);
            }
        };
        tbb::parallel_for(tbb::blocked_range<size_t>(0, nLeaves, 16), [&](const tbb::blocked_range<size_t>& range) {
            Cache cache(Reconstruction(tree, dom));
            for (size_t i = range.begin(); i != range.end(); ++i) {
                const std::vector<HangItem>& hl = hangLeaf[i];
                const uint32_t b = hangBegin[i][size_t(cls)], e = hangBegin[i][size_t(cls) + 1];
                if (b == e) continue;
                float* buf = leaves[i]->buffer().data();
                const Coord o = leaves[i]->origin();
                for (uint32_t k = b; k < e; ++k) {
                    const HangItem& h = hl[k];
                    const int sz = h.size;
                    const int px = h.off >> 6, py = (h.off >> 3) & 7, pz = h.off & 7;
                    if (sz <= 4 && h.dx >= 0 && h.dy >= 0 && h.dz >= 0 && h.dx + sz <= 7 && h.dy + sz <= 7 && h.dz + sz <= 7) {
                        // all corners in the same leaf: read the buffer
                        double v[8];
                        for (int c = 0; c < 8; ++c)
                            v[c] = buf[((h.dx + ((c >> 2) & 1) * sz) << 6) | ((h.dy + ((c >> 1) & 1) * sz) << 3) | (h.dz + (c & 1) * sz)];
                        const Vec3d t(double(px - h.dx) / sz, double(py - h.dy) / sz, double(pz - h.dz) / sz);
                        buf[h.off] = float(Reconstruction::trilinear(v, t, nullptr));
                        continue;
                    }
                    const CellInfo S{sz, o + Coord(h.dx, h.dy, h.dz)};
                    buf[h.off] = float(cache.interp(S, o + Coord(px, py, pz)));
                }
            }
        });
        tbb::parallel_for(tbb::blocked_range<size_t>(0, tileIdx.size(), 1024), [&](const tbb::blocked_range<size_t>& range) {
            Cache cache(Reconstruction(tree, dom));
            for (size_t k = range.begin(); k != range.end(); ++k) {
                const size_t i = tileIdx[k];
                tileValue[i] = float(cache.interp(tileHang[i], tiles[i].p));
            }
        });
        for (size_t i : tileIdx) tree.addTile(openvdb::Index(tiles[i].level), tiles[i].p, tileValue[i], false);
        uint64_t n = tileIdx.size();
        for (size_t i = 0; i < nLeaves; ++i) n += hangBegin[i][size_t(cls) + 1] - hangBegin[i][size_t(cls)];
        res.hanging += n;
    }
    for (size_t i = 0; i < tiles.size(); ++i) {
        if (tileKind[i] == 0) continue;
        if (tiles[i].level == 1) ++res.level1Tiles; else ++res.level2Tiles;
    }
    for (size_t i = 0; i < tiles.size(); ++i) {
        if (tileKind[i] == 0 || !inDomainCell(dom, tiles[i].p)) continue;
        ++res.cells[tiles[i].level == 1 ? 3 : 4];
    }
    res.secondsHanging = detail::secondsSince(t2);
    return res;
}

} // namespace adf_internal
} // namespace levelforge
