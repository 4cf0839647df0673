// Adaptively sampled distance fields on the VDB tile hierarchy (Yin, Liu, Wu 2011).
// See AdaptiveDistanceField.h for the design. This file holds the reconstruction (shared by
// the builder, the queries, the level-set conversion and CSG), the value pipeline that fills a
// layout (leaves, level-1 and level-2 tiles) from a sample provider, and the mesh provider
// (type-1/2/3 samples). CSG and the level-set conversion live in AdfCsg.cc.
#include "adf/AdfInternal.h"

#include <levelforge/core/Exceptions.h>
#include <levelforge/mesh/MeshToLevelSet.h>
#include <levelforge/core/MeshValidation.h>
#include <levelforge/core/Progress.h>
#include <levelforge/core/PseudoNormals.h>
#include <levelforge/core/TriangleDistance.h>
#include <levelforge/mesh/TriangleListTree.h>
#include <levelforge/io/VdbIO.h>

#include <openvdb/tools/Morphology.h>
#include <openvdb/tools/SignedFloodFill.h>

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/task_group.h>

#include <algorithm>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif
#include <atomic>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <numeric>
#include <sstream>

namespace levelforge {

namespace adf_internal {

// ------------------------------------------------------------------------------ reconstruction

bool Reconstruction::subdividedIn(const FloatLeaf& leaf, int x0, int y0, int z0, int n)
{
    const auto& m = leaf.getValueMask();
    const uint64_t zb = ((uint64_t(1) << n) - 1) << z0;
    uint64_t pat = 0;
    for (int y = y0; y < y0 + n; ++y) pat |= zb << (8 * y);
    for (int x = x0; x < x0 + n; ++x)
        if (m.template getWord<uint64_t>(openvdb::Index(x)) & pat) return true;
    return false;
}

CellInfo Reconstruction::cellAt(const Coord& c)
{
    const Internal1* n1 = mAcc.template probeConstNode<Internal1>(c);
    if (!n1) return {128, Coord(c.x() & ~127, c.y() & ~127, c.z() & ~127)};
    const FloatLeaf* leaf = mAcc.probeConstLeaf(c);
    if (!leaf) return {8, Coord(c.x() & ~7, c.y() & ~7, c.z() & ~7)};
    return cellInLeaf(*leaf, c);
}

CellInfo cellInLeaf(const FloatLeaf& leaf, const Coord& c)
{
    const int lx = c.x() & 7, ly = c.y() & 7, lz = c.z() & 7;
    if (!Reconstruction::subdividedIn(leaf, lx & ~3, ly & ~3, lz & ~3, 4))
        return {4, Coord(c.x() & ~3, c.y() & ~3, c.z() & ~3)};
    if (!Reconstruction::subdividedIn(leaf, lx & ~1, ly & ~1, lz & ~1, 2))
        return {2, Coord(c.x() & ~1, c.y() & ~1, c.z() & ~1)};
    return {1, c};
}

bool Reconstruction::stored(const Coord& p, float& v)
{
    if (const FloatLeaf* leaf = mAcc.probeConstLeaf(p)) {
        v = leaf->getValue(p);
        return true;
    }
    if (mAcc.template probeConstNode<Internal1>(p)) {
        if ((p.x() & 7) || (p.y() & 7) || (p.z() & 7)) return false;
        v = mAcc.getValue(p);
        return true;
    }
    if (mAcc.template probeConstNode<Internal2>(p)) {
        if ((p.x() & 127) || (p.y() & 127) || (p.z() & 127)) return false;
        v = mAcc.getValue(p);
        return true;
    }
    // No node holds p: the tree was collapsed (e.g. pruned by another tool), and a root tile
    // covers it. A 128-aligned point is then a stored coarse sample (the tile's value), which
    // also ends the recursion of value() -> cellAt() -> value() for such points.
    if (!((p.x() & 127) || (p.y() & 127) || (p.z() & 127))) {
        v = mAcc.getValue(p);
        return true;
    }
    return false;
}

Coord Reconstruction::clampCell(const Coord& p) const
{
    const Coord& lo = mDomain.min();
    const Coord& hi = mDomain.max();
    return Coord(std::max(lo.x(), std::min(p.x(), hi.x() - 1)), std::max(lo.y(), std::min(p.y(), hi.y() - 1)),
                 std::max(lo.z(), std::min(p.z(), hi.z() - 1)));
}

double Reconstruction::value(const Coord& p)
{
    float v;
    if (stored(p, v)) return v;
    const CellInfo X = cellAt(clampCell(p));
    return interp(X, Vec3d(p.x(), p.y(), p.z()), nullptr);
}

double Reconstruction::interp(const CellInfo& X, const Vec3d& q, Vec3d* dvdt)
{
    const int s = X.size;
    double v[8];
    for (int k = 0; k < 8; ++k) {
        const Coord c = X.origin + Coord(((k >> 2) & 1) * s, ((k >> 1) & 1) * s, (k & 1) * s);
        v[k] = value(c);
    }
    return trilinear(v, (q - Vec3d(X.origin.x(), X.origin.y(), X.origin.z())) / double(s), dvdt);
}

double Reconstruction::trilinear(const double* v, const Vec3d& t, Vec3d* dvdt)
{
    const double tx = t[0], ty = t[1], tz = t[2];
    // v index = (x << 2) | (y << 1) | z
    const double c00 = v[0] + (v[4] - v[0]) * tx, c01 = v[1] + (v[5] - v[1]) * tx;
    const double c10 = v[2] + (v[6] - v[2]) * tx, c11 = v[3] + (v[7] - v[3]) * tx;
    const double c0 = c00 + (c10 - c00) * ty, c1 = c01 + (c11 - c01) * ty;
    if (dvdt) {
        const double ax = (v[4] - v[0]) * (1 - ty) * (1 - tz) + (v[6] - v[2]) * ty * (1 - tz) +
                          (v[5] - v[1]) * (1 - ty) * tz + (v[7] - v[3]) * ty * tz;
        const double ay = (c10 - c00) * (1 - tz) + (c11 - c01) * tz;
        const double az = c1 - c0;
        *dvdt = Vec3d(ax, ay, az);
    }
    return c0 + (c1 - c0) * tz;
}

double Reconstruction::distanceIndex(const Vec3d& q, Vec3d* gradIndex, int* levelOut)
{
    const Coord& lo = mDomain.min();
    const Coord& hi = mDomain.max();
    Vec3d qc = q;
    for (int k = 0; k < 3; ++k) qc[k] = std::max(double(lo[k]), std::min(q[k], double(hi[k])));
    const double extra = (q - qc).length();
    const Coord c = clampCell(Coord(int(std::floor(qc[0])), int(std::floor(qc[1])), int(std::floor(qc[2]))));
    const CellInfo X = cellAt(c);
    if (levelOut) *levelOut = levelOfSize(X.size);
    const int s = X.size;
    Vec3d dvdt;
    double d;
    const FloatLeaf* leaf = s == 1 ? mAcc.probeConstLeaf(c) : nullptr;
    if (leaf && (c.x() & 7) < 7 && (c.y() & 7) < 7 && (c.z() & 7) < 7) {
        // fast path: the 8 corners are voxels of the same leaf
        const openvdb::Index o = FloatLeaf::coordToOffset(c);
        const float* buf = leaf->buffer().data();
        const double v[8] = {buf[o], buf[o + 1], buf[o + 8], buf[o + 9], buf[o + 64], buf[o + 65], buf[o + 72], buf[o + 73]};
        d = trilinear(v, qc - Vec3d(c.x(), c.y(), c.z()), &dvdt);
    } else {
        d = interp(X, qc, &dvdt);
    }
    if (gradIndex) *gradIndex = dvdt / double(s);
    return d + extra;
}

int levelOfSize(int size)
{
    switch (size) {
    case 1: return 0;
    case 2: return 1;
    case 4: return 2;
    case 8: return 3;
    case 128: return 4;
    default: return -1;
    }
}

// ------------------------------------------------------------------------------------- layout

namespace {
inline int floorTo(int v, int m) { return v & ~(m - 1); }
inline int ceilTo(int v, int m) { return (v + m - 1) & ~(m - 1); }
inline bool inDomainCell(const CoordBBox& dom, const Coord& c)
{
    for (int k = 0; k < 3; ++k)
        if (c[k] < dom.min()[k] || c[k] >= dom.max()[k]) return false;
    return true;
}
} // namespace

void Layout::finish()
{
    // leaves sorted and merged
    std::vector<size_t> order(leafOrigins.size());
    std::iota(order.begin(), order.end(), size_t(0));
    std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return leafOrigins[a] < leafOrigins[b]; });
    std::vector<Coord> o2;
    std::vector<LeafMask> m2;
    for (size_t i : order) {
        if (!o2.empty() && o2.back() == leafOrigins[i]) {
            m2.back() |= leafMasks[i];
        } else {
            o2.push_back(leafOrigins[i]);
            m2.push_back(leafMasks[i]);
        }
    }
    leafOrigins.swap(o2);
    leafMasks.swap(m2);
    // grading: the 128³ blocks holding leaves and their in-domain 26-neighbours are subdivided,
    // so a leaf never touches a 128³ cell (its constrained corners then come from 8³ cells)
    const Coord lo0 = domain.min(), hi0 = domain.max();
    for (const Coord& o : leafOrigins) {
        const Coord b(floorTo(o.x(), 128), floorTo(o.y(), 128), floorTo(o.z(), 128));
        for (int dx = -1; dx <= 1; ++dx)
            for (int dy = -1; dy <= 1; ++dy)
                for (int dz = -1; dz <= 1; ++dz) {
                    const Coord n = b + Coord(dx * 128, dy * 128, dz * 128);
                    if (n.x() >= lo0.x() && n.y() >= lo0.y() && n.z() >= lo0.z() && n.x() < hi0.x() && n.y() < hi0.y() &&
                        n.z() < hi0.z())
                        subdividedL2.push_back(n);
                }
    }
    std::sort(subdividedL2.begin(), subdividedL2.end());
    subdividedL2.erase(std::unique(subdividedL2.begin(), subdividedL2.end()), subdividedL2.end());
    // every L2 block of the domain plus one layer past the maximum faces (storage of the last
    // corners): subdivided blocks are internal-1 nodes, the others level-2 tiles. A block past
    // the domain is subdivided when an in-domain neighbour is.
    const Coord lo = domain.min(), hi = domain.max();
    auto isSub = [&](const Coord& b) { return std::binary_search(subdividedL2.begin(), subdividedL2.end(), b); };
    std::vector<Coord> extraSub;
    tileL2.clear();
    for (int x = lo.x(); x <= hi.x(); x += 128)
        for (int y = lo.y(); y <= hi.y(); y += 128)
            for (int z = lo.z(); z <= hi.z(); z += 128) {
                const Coord b(x, y, z);
                const bool beyond = x == hi.x() || y == hi.y() || z == hi.z();
                if (!beyond) {
                    if (!isSub(b)) tileL2.push_back(b);
                    continue;
                }
                bool sub = false;
                for (int dx = -1; dx <= 1 && !sub; ++dx)
                    for (int dy = -1; dy <= 1 && !sub; ++dy)
                        for (int dz = -1; dz <= 1 && !sub; ++dz) {
                            const Coord n = b + Coord(dx * 128, dy * 128, dz * 128);
                            if (n.x() < hi.x() && n.y() < hi.y() && n.z() < hi.z() && n.x() >= lo.x() &&
                                n.y() >= lo.y() && n.z() >= lo.z() && isSub(n))
                                sub = true;
                        }
                if (sub) extraSub.push_back(b); else tileL2.push_back(b);
            }
    subdividedL2.insert(subdividedL2.end(), extraSub.begin(), extraSub.end());
    std::sort(subdividedL2.begin(), subdividedL2.end());
    subdividedL2.erase(std::unique(subdividedL2.begin(), subdividedL2.end()), subdividedL2.end());
}

void makeDomain(Layout& layout, const CoordBBox& cellBox, double paddingVoxels)
{
    const int pad = std::max(9, int(std::ceil(paddingVoxels)));
    const Coord lo(floorTo(cellBox.min().x() - pad, 128), floorTo(cellBox.min().y() - pad, 128),
                   floorTo(cellBox.min().z() - pad, 128));
    const Coord hi(ceilTo(cellBox.max().x() + 1 + pad, 128), ceilTo(cellBox.max().y() + 1 + pad, 128),
                   ceilTo(cellBox.max().z() + 1 + pad, 128));
    layout.domain = CoordBBox(lo, hi);
}

FloatTree::Ptr createTree(const Layout& layout, float background)
{
    auto tree = std::make_shared<FloatTree>(background);
    for (const Coord& b : layout.subdividedL2) tree->addTile(1, b, 0.0f, false); // creates the internal-1 node
    for (size_t i = 0; i < layout.leafOrigins.size(); ++i) {
        auto* leaf = new FloatLeaf(layout.leafOrigins[i], 0.0f, false);
        leaf->setValueMask(layout.leafMasks[i]);
        tree->addLeaf(leaf);
    }
    for (const Coord& b : layout.tileL2) tree->addTile(2, b, 0.0f, false);
    return tree;
}

// ----------------------------------------------------------------------------- value pipeline

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

/// Cell sizes inside a leaf from its refined-cell mask (as cellInLeaf, by bit operations):
/// bit q of sub4 / sub2 tells whether 4³ block q / 2³ block q holds an active voxel.
struct LeafCellSizes
{
    uint8_t sub4 = 0;
    uint64_t sub2 = 0;
    LeafCellSizes() = default;
    explicit LeafCellSizes(const LeafMask& m)
    {
        for (int bx = 0; bx < 4; ++bx) {
            const uint64_t w = m.template getWord<uint64_t>(openvdb::Index(2 * bx)) | m.template getWord<uint64_t>(openvdb::Index(2 * bx + 1));
            if (!w) continue;
            for (int by = 0; by < 4; ++by)
                for (int bz = 0; bz < 4; ++bz)
                    if ((w >> (16 * by + 2 * bz)) & 0x303u) {
                        sub2 |= uint64_t(1) << ((bx << 4) | (by << 2) | bz);
                        sub4 |= uint8_t(1u << (((bx >> 1) << 2) | ((by >> 1) << 1) | (bz >> 1)));
                    }
        }
    }
    /// Size of the cell holding local unit cell (x, y, z), x, y, z in [0, 8).
    int size(int x, int y, int z) const
    {
        if (!((sub4 >> (((x >> 2) << 2) | ((y >> 2) << 1) | (z >> 2))) & 1)) return 4;
        if (!((sub2 >> (((x >> 1) << 4) | ((y >> 1) << 2) | (z >> 1))) & 1)) return 2;
        return 1;
    }
    /// Cells of sizes 1, 2 and 4 in the leaf.
    void count(uint64_t& n1, uint64_t& n2, uint64_t& n4) const
    {
        const int s4 = __builtin_popcount(sub4), s2 = __builtin_popcountll(sub2);
        n4 += uint64_t(8 - s4);
        n2 += uint64_t(8 * s4 - s2);
        n1 += uint64_t(8 * s2);
    }
};

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
    const auto t0 = Clock::now();
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
    res.secondsLeaves = secondsSince(t0);

    provider.afterLeaves(tree);

    // ---- tiles: level-1 tiles of the internal-1 nodes and level-2 tiles
    const auto t1 = Clock::now();
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
    res.secondsTiles = secondsSince(t1);

    // ---- hanging points, coarsest cells first (their corners are final by then)
    const auto t2 = Clock::now();
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
    res.secondsHanging = secondsSince(t2);
    return res;
}

// -------------------------------------------------------------------------------- metadata

void stampAdfMetadata(openvdb::FloatGrid& grid, const CoordBBox& domain, const std::array<double, kAdfLevels>& bounds)
{
    grid.setGridClass(openvdb::GRID_UNKNOWN);
    grid.insertMeta(kAdfMetaKey, openvdb::StringMetadata(kAdfVersion));
    grid.insertMeta("levelforge:adf_domain_min", openvdb::Vec3IMetadata(domain.min().asVec3i()));
    grid.insertMeta("levelforge:adf_domain_max", openvdb::Vec3IMetadata(domain.max().asVec3i()));
    grid.insertMeta("levelforge:adf_sampling",
                    openvdb::StringMetadata(
                        "samples at index points (world = index*voxel size); leaf voxels: the lattice values of "
                        "the block, active voxels = subdivided finest cells, nodes of size 2/4 inside a leaf are "
                        "subdivided iff they hold an active voxel; level-1 tile: value at its minimum corner, cell "
                        "8^3; level-2 tile: value at its minimum corner, cell 128^3; corners lying on a larger "
                        "cell's face or edge take that cell's trilinear value; trilinear reconstruction"));
    for (int l = 0; l < kAdfLevels; ++l) {
        char key[64];
        std::snprintf(key, sizeof(key), "levelforge:adf_bound_level%d_voxels", l);
        grid.insertMeta(key, openvdb::DoubleMetadata(bounds[size_t(l)]));
    }
    grid.insertMeta("levelforge:generator", openvdb::StringMetadata(generatorString()));
}

// ------------------------------------------------------------------------- the mesh provider

namespace {

/// Nearest centre of a boundary cell (type-3 estimator, §7.2): a BVH over the list tree's leaves.
class CentreBvh
{
public:
    using ListLeaf = openvdb::UInt32Tree::LeafNodeType;
    explicit CentreBvh(const openvdb::UInt32Tree& tree)
    {
        // primitives: the non-empty 4³ quarters of every leaf (tight boxes prune well)
        for (auto it = tree.cbeginLeaf(); it; ++it) {
            const auto& mask = it->getValueMask();
            for (int q = 0; q < 8; ++q) {
                const int x0 = (q >> 2) * 4, y0 = ((q >> 1) & 1) * 4, z0 = (q & 1) * 4;
                CoordBBox bb;
                for (int x = x0; x < x0 + 4; ++x)
                    for (int y = y0; y < y0 + 4; ++y)
                        for (int z = z0; z < z0 + 4; ++z)
                            if (mask.isOn(openvdb::Index((x << 6) | (y << 3) | z))) bb.expand(it->origin() + Coord(x, y, z));
                if (bb.empty()) continue;
                mLeaves.push_back(&*it);
                mQuarter.push_back(uint8_t(q));
                mBoxes.push_back(bb);
            }
        }
        std::vector<uint32_t> idx(mLeaves.size());
        std::iota(idx.begin(), idx.end(), 0u);
        if (!idx.empty()) build(idx, 0, idx.size());
    }
    bool empty() const { return mLeaves.empty(); }

    /// Squared index-space distance from p to the nearest cell centre; `hint` is a centre
    /// (updated) used as the starting bound.
    double nearest2(const Vec3d& p, Vec3d& hint) const
    {
        double best2 = (p - hint).lengthSqr();
        uint32_t stack[128];
        int sp = 0;
        stack[sp++] = 0;
        while (sp) {
            const Node& n = mNodes[stack[--sp]];
            if (boxDist2(n, p) >= best2) continue;
            if (n.leaf != kNoLeaf) {
                scanLeaf(n.leaf, p, best2, hint);
                continue;
            }
            const double dl = boxDist2(mNodes[n.left], p), dr = boxDist2(mNodes[n.right], p);
            if (dl < dr) { stack[sp++] = n.right; stack[sp++] = n.left; }
            else { stack[sp++] = n.left; stack[sp++] = n.right; }
        }
        return best2;
    }

private:
    static constexpr uint32_t kNoLeaf = 0xffffffffu;
    struct Node { double lo[3], hi[3]; uint32_t left = 0, right = 0, leaf = kNoLeaf; };

    static double boxDist2(const Node& n, const Vec3d& p)
    {
        double d2 = 0;
        for (int k = 0; k < 3; ++k) {
            const double e = p[k] < n.lo[k] ? n.lo[k] - p[k] : (p[k] > n.hi[k] ? p[k] - n.hi[k] : 0.0);
            d2 += e * e;
        }
        return d2;
    }

    uint32_t build(std::vector<uint32_t>& idx, size_t b, size_t e)
    {
        const uint32_t me = uint32_t(mNodes.size());
        mNodes.emplace_back();
        Node n;
        for (int k = 0; k < 3; ++k) { n.lo[k] = 1e300; n.hi[k] = -1e300; }
        for (size_t i = b; i < e; ++i) {
            const CoordBBox& bb = mBoxes[idx[i]];
            for (int k = 0; k < 3; ++k) {
                n.lo[k] = std::min(n.lo[k], bb.min()[k] + 0.5);
                n.hi[k] = std::max(n.hi[k], bb.max()[k] + 0.5);
            }
        }
        if (e - b == 1) {
            n.leaf = idx[b];
        } else {
            int axis = 0;
            for (int k = 1; k < 3; ++k)
                if (n.hi[k] - n.lo[k] > n.hi[axis] - n.lo[axis]) axis = k;
            const size_t mid = (b + e) / 2;
            std::nth_element(idx.begin() + long(b), idx.begin() + long(mid), idx.begin() + long(e), [&](uint32_t a, uint32_t c) {
                const int ka = mBoxes[a].min()[axis], kc = mBoxes[c].min()[axis];
                return ka != kc ? ka < kc : a < c;
            });
            n.left = build(idx, b, mid);
            n.right = build(idx, mid, e);
        }
        mNodes[me] = n;
        return me;
    }

    void scanLeaf(uint32_t li, const Vec3d& p, double& best2, Vec3d& hint) const
    {
        const ListLeaf& leaf = *mLeaves[li];
        const Coord o = leaf.origin();
        const auto& mask = leaf.getValueMask();
        const int q = mQuarter[li], x0 = (q >> 2) * 4, y0 = ((q >> 1) & 1) * 4, z0 = (q & 1) * 4;
        for (int x = x0; x < x0 + 4; ++x) {
            const double dx = o.x() + x + 0.5 - p[0], dx2 = dx * dx;
            if (dx2 >= best2) continue;
            const uint64_t w = mask.template getWord<uint64_t>(openvdb::Index(x));
            if (!w) continue;
            for (int y = y0; y < y0 + 4; ++y) {
                uint32_t zb = uint32_t(w >> (8 * y)) & (0xfu << z0);
                if (!zb) continue;
                const double dy = o.y() + y + 0.5 - p[1], dxy2 = dx2 + dy * dy;
                if (dxy2 >= best2) continue;
                // nearest set z bit to p: scan outward is overkill for 8 bits; check all
                while (zb) {
                    const int z = __builtin_ctz(zb);
                    zb &= zb - 1;
                    const double dz = o.z() + z + 0.5 - p[2];
                    const double d2 = dxy2 + dz * dz;
                    if (d2 < best2) {
                        best2 = d2;
                        hint = Vec3d(o.x() + x + 0.5, o.y() + y + 0.5, o.z() + z + 0.5);
                    }
                }
            }
        }
    }

    std::vector<const ListLeaf*> mLeaves;
    std::vector<uint8_t> mQuarter;
    std::vector<CoordBBox> mBoxes;
    std::vector<Node> mNodes;
};

/// Exact squared distances from the points of the 8-spaced lattice of the domain to the nearest
/// boundary-cell centre: the type-3 rule at the tile corners, for all of them at once. A
/// separable exact Euclidean distance transform (lower envelopes of parabolas, Felzenszwalb &
/// Huttenlocher) over the list tree's cells, evaluated only at the lattice: columns along z,
/// then y, then x. All in doubled integer coordinates (centre c + 1/2 -> 2c + 1, lattice point
/// p -> 2p; D = 4·d²), with exact rational comparisons, so each value equals the minimum the
/// BVH finds (a half-integer sum of squares, exact in double) bit for bit.
class LatticeEdt
{
public:
    static constexpr int kStep = 8;

    /// False (nothing built; use the BVH) for empty trees, huge coordinates or huge lattices.
    bool build(const openvdb::UInt32Tree& tree, const CoordBBox& domain)
    {
        mD.clear();
        mLo = domain.min();
        std::vector<const ListLeaf*> leaves;
        for (auto it = tree.cbeginLeaf(); it; ++it)
            if (!it->isEmpty()) leaves.push_back(&*it);
        if (leaves.empty()) return false;
        std::sort(leaves.begin(), leaves.end(), [](const ListLeaf* a, const ListLeaf* b) { return a->origin() < b->origin(); });
        CoordBBox sb;
        for (const ListLeaf* l : leaves) { sb.expand(l->origin()); sb.expand(l->origin().offsetBy(7)); }
        const int64_t lim = int64_t(1) << 20;
        for (int k = 0; k < 3; ++k) {
            if (std::abs(int64_t(sb.min()[k])) >= lim || std::abs(int64_t(sb.max()[k])) >= lim) return false;
            if (std::abs(int64_t(domain.min()[k])) >= lim || std::abs(int64_t(domain.max()[k])) >= lim) return false;
            if (domain.max()[k] < domain.min()[k]) return false;
            mN[k] = (domain.max()[k] - domain.min()[k]) / kStep + 1;
        }
        const int sx0 = sb.min().x(), nxs = sb.max().x() - sx0 + 1;
        const int nx = mN[0], ny = mN[1], nz = mN[2];
        if (double(nx) * ny * nz > double(1 << 24) || double(nxs) * ny * nz > double(1 << 24)) return false;

        // pass 1 (z) and 2 (y), per site column x: g2[(j*nz + k)*nxs + x - sx0]
        const int64_t kInf = std::numeric_limits<int64_t>::max();
        std::vector<int64_t> g2(size_t(nxs) * ny * nz, kInf);
        std::vector<uint8_t> hasX(size_t(nxs), 0);
        tbb::parallel_for(tbb::blocked_range<int>(0, nxs, 4), [&](const tbb::blocked_range<int>& r) {
            std::vector<int64_t> Y, g1, Z, F, out(static_cast<size_t>(ny));
            Envelope env;
            for (int xi = r.begin(); xi != r.end(); ++xi) {
                const int x = sx0 + xi, ox = x & ~7, lx = x - ox;
                auto lo = std::lower_bound(leaves.begin(), leaves.end(), ox, [](const ListLeaf* l, int v) { return l->origin().x() < v; });
                auto hi = std::lower_bound(lo, leaves.end(), ox + 8, [](const ListLeaf* l, int v) { return l->origin().x() < v; });
                Y.clear();
                g1.clear();
                for (auto g = lo; g != hi;) {
                    auto ge = g;
                    while (ge != hi && (*ge)->origin().y() == (*g)->origin().y()) ++ge;
                    const int oy = (*g)->origin().y();
                    for (int ly = 0; ly < 8; ++ly) {
                        Z.clear();
                        for (auto it = g; it != ge; ++it) {
                            uint32_t bits = uint32_t(((*it)->getValueMask().template getWord<uint64_t>(openvdb::Index(lx)) >> (8 * ly)) & 0xffu);
                            while (bits) {
                                Z.push_back(2 * int64_t((*it)->origin().z() + __builtin_ctz(bits)) + 1);
                                bits &= bits - 1;
                            }
                        }
                        if (Z.empty()) continue;
                        Y.push_back(2 * int64_t(oy + ly) + 1);
                        size_t i = 0;
                        for (int k = 0; k < nz; ++k) {
                            const int64_t t = 2 * (int64_t(mLo.z()) + int64_t(k) * kStep);
                            while (i + 1 < Z.size() && Z[i + 1] <= t) ++i;
                            int64_t best = (t - Z[i]) * (t - Z[i]);
                            if (i + 1 < Z.size()) best = std::min(best, (Z[i + 1] - t) * (Z[i + 1] - t));
                            g1.push_back(best);
                        }
                    }
                    g = ge;
                }
                if (Y.empty()) continue;
                hasX[size_t(xi)] = 1;
                F.resize(Y.size());
                for (int k = 0; k < nz; ++k) {
                    for (size_t i = 0; i < Y.size(); ++i) F[i] = g1[i * size_t(nz) + size_t(k)];
                    env.run(Y.data(), F.data(), int(Y.size()), 2 * int64_t(mLo.y()), 2 * kStep, ny, out.data());
                    for (int j = 0; j < ny; ++j) g2[(size_t(j) * nz + size_t(k)) * nxs + size_t(xi)] = out[size_t(j)];
                }
            }
        });
        // pass 3 (x)
        std::vector<int64_t> X;
        std::vector<int> xs;
        for (int xi = 0; xi < nxs; ++xi)
            if (hasX[size_t(xi)]) { X.push_back(2 * int64_t(sx0 + xi) + 1); xs.push_back(xi); }
        mD.assign(size_t(nx) * ny * nz, 0);
        tbb::parallel_for(tbb::blocked_range<int>(0, ny * nz, 16), [&](const tbb::blocked_range<int>& r) {
            std::vector<int64_t> F(X.size()), out(static_cast<size_t>(nx));
            Envelope env;
            for (int jk = r.begin(); jk != r.end(); ++jk) {
                const int64_t* row = &g2[size_t(jk) * nxs];
                for (size_t i = 0; i < xs.size(); ++i) F[i] = row[size_t(xs[i])];
                env.run(X.data(), F.data(), int(X.size()), 2 * int64_t(mLo.x()), 2 * kStep, nx, out.data());
                for (int i = 0; i < nx; ++i) mD[size_t(i) * ny * nz + size_t(jk)] = out[size_t(i)];
            }
        });
        return true;
    }

    /// Squared index-space distance from lattice point p to the nearest boundary-cell centre.
    bool lookup(const Coord& p, double& d2) const
    {
        if (mD.empty()) return false;
        int idx[3];
        for (int k = 0; k < 3; ++k) {
            const int64_t o = int64_t(p[k]) - mLo[k];
            if (o < 0 || o % kStep || o / kStep >= mN[k]) return false;
            idx[k] = int(o / kStep);
        }
        d2 = double(mD[(size_t(idx[0]) * mN[1] + size_t(idx[1])) * mN[2] + size_t(idx[2])]) * 0.25;
        return true;
    }

private:
    using ListLeaf = openvdb::UInt32Tree::LeafNodeType;

    /// Lower envelope of the parabolas (t - Y[i])² + F[i] (Y strictly increasing), evaluated at
    /// t = t0 + j·dt, j < nq. Breakpoints are the rationals num/den (den > 0), compared exactly.
    struct Envelope
    {
        std::vector<int> v;
        std::vector<int64_t> zn, zd;
        void run(const int64_t* Y, const int64_t* F, int n, int64_t t0, int64_t dt, int nq, int64_t* out)
        {
            v.resize(size_t(n));
            zn.resize(size_t(n) + 1);
            zd.resize(size_t(n) + 1);
            int k = 0;
            v[0] = 0;
            for (int q = 1; q < n; ++q) {
                int64_t sn, sd;
                for (;;) {
                    const int a = v[size_t(k)];
                    sn = (F[q] + Y[q] * Y[q]) - (F[a] + Y[a] * Y[a]);
                    sd = 2 * (Y[q] - Y[a]);
                    // pop while s <= z[k] (z[0] = -inf)
                    if (k > 0 && __int128(sn) * zd[size_t(k)] <= __int128(zn[size_t(k)]) * sd) { --k; continue; }
                    break;
                }
                ++k;
                v[size_t(k)] = q;
                zn[size_t(k)] = sn;
                zd[size_t(k)] = sd;
            }
            int c = 0;
            for (int j = 0; j < nq; ++j) {
                const int64_t t = t0 + int64_t(j) * dt;
                // advance while the next breakpoint z[c+1] < t
                while (c < k && __int128(zn[size_t(c) + 1]) < __int128(t) * zd[size_t(c) + 1]) ++c;
                const int a = v[size_t(c)];
                out[j] = (t - Y[a]) * (t - Y[a]) + F[a];
            }
        }
    };

    Coord mLo{0, 0, 0};
    int mN[3] = {0, 0, 0};
    std::vector<int64_t> mD;
};

/// A gathered triangle: cell-space vertices (double) and its mesh id.
struct PreparedTri { Vec3d a, b, c; uint32_t id; };
/// Its bounding box (the first, exact filter of the nearest search), computed once per gathered
/// triangle and copied into the RefQuads of the cells that list it. In float relative to the
/// leaf centre (w = 0), tested with a kPlaneSlack slack per axis.
struct alignas(16) TriBox { float lo[4], hi[4]; };
/// Lower-bound planes of a gathered triangle, relative to the leaf centre: the unit normal and
/// the three in-plane outward edge normals (n, -n·a; m_k, -m_k·v_k). For a point p,
/// dist² >= plane(p)² + max(0, edge_k(p))², exact in the face and edge regions (all zero, i.e.
/// no bound, for slivers whose normal is not accurate).
/// Stored in float, transposed (x, y, z, w of the plane and the three edge lines) so that one
/// SSE step evaluates all four. `err` bounds the float rounding of the four values for points
/// within 32 cells of the leaf centre: 1e-5 + 2e-7 × the largest |w| (coefficients and the sum
/// round at 6e-8 of their magnitude); the bound is taken as max(0, |plane| - err) and
/// max(0, edge - err).
struct alignas(16) TriPlanes { float x[4], y[4], z[4], w[4]; float err = 0.0f; };
/// Four references of a cell's triangle list with their boxes (as TriBox), transposed so that
/// one SSE step tests four: lanes beyond the list hold an empty box (lo = +1e30, never passes).
struct alignas(16) RefQuad { float lx[4], ly[4], lz[4], hx[4], hy[4], hz[4]; uint32_t t[4]; };
constexpr RefQuad kPadQuad{{1e30f, 1e30f, 1e30f, 1e30f}, {1e30f, 1e30f, 1e30f, 1e30f}, {1e30f, 1e30f, 1e30f, 1e30f},
                           {1e30f, 1e30f, 1e30f, 1e30f}, {1e30f, 1e30f, 1e30f, 1e30f}, {1e30f, 1e30f, 1e30f, 1e30f},
                           {0u, 0u, 0u, 0u}};
/// Float rounding of the query point and of the box subtraction for boxes near the centre.
constexpr double kPlaneSlack = 1e-4; // cells

/// Cells p + o, o in [-R, R-1+extra]³, sorted by their minimum squared distance from p
/// (a lattice point, extra = 0) or from any point of the unit cell [p, p+1) (extra = 1).
struct OffsetTable
{
    std::vector<Coord> off;
    std::vector<int> d2;
    std::vector<double> d2d;    ///< d2 as double
    std::vector<int32_t> delta; ///< linear index offset in the gathered region
    OffsetTable(int R, int extra, int region)
    {
        auto a = [&](int o) { return extra ? (o >= 1 ? o - 1 : (o <= -1 ? -o - 1 : 0)) : (o >= 0 ? o : -o - 1); };
        std::vector<std::pair<int, Coord>> v;
        for (int x = -R; x <= R - 1 + extra; ++x)
            for (int y = -R; y <= R - 1 + extra; ++y)
                for (int z = -R; z <= R - 1 + extra; ++z) v.push_back({a(x) * a(x) + a(y) * a(y) + a(z) * a(z), Coord(x, y, z)});
        std::stable_sort(v.begin(), v.end(), [](const auto& l, const auto& r) { return l.first < r.first; });
        for (auto& e : v) {
            d2.push_back(e.first);
            d2d.push_back(double(e.first));
            off.push_back(e.second);
            delta.push_back((e.second.x() * region + e.second.y()) * region + e.second.z());
        }
    }
};

constexpr int kGather = 4;             // the leaf's region: [o-4, o+12)³
constexpr int kRegion = 8 + 2 * kGather;

/// Per-thread scratch of the mesh provider: the gathered lists of one leaf region.
struct MeshScratch
{
    std::vector<int32_t> cellSlot;       // region cell -> range index or -1
    std::vector<uint32_t> rangeBegin;    // per marked cell: [begin, end) into quads
    std::vector<RefQuad> quads;          // the cells' lists (local triangle ids and boxes), 4 per quad
    std::vector<PreparedTri> tris;
    std::vector<TriBox> boxes;
    std::vector<TriPlanes> planes;       // computed on first use (planeReady)
    std::vector<uint8_t> planeReady;
    std::vector<uint32_t> stamp;
    std::vector<uint32_t> hashKey;       // gather: triangle id + 1 (0 = empty)
    std::vector<uint32_t> hashLocal;     // gather: its local id
    std::vector<std::pair<int, uint32_t>> cells; // gather: (region index, ordinal)
    uint32_t stampValue = 0, lastTri = kNone;
    Vec3d centre{0.0};                   // leaf centre (the planes' origin)
    double margin = 0;                   // rounding margin of the plane bounds (cells)
    Vec3d hint{1e300};
    uint64_t type1 = 0, type2 = 0, type3 = 0, type2Wide = 0;
    double type2MaxBound = 0;
};

struct Nearest { double d2 = std::numeric_limits<double>::infinity(); uint32_t tri = kNone; TriangleClosestPoint cp{}; };

std::atomic<bool> gAvx2LeafPass{true}; // testing hook (setAvx2LeafPassEnabled)

// The leaf pass is compiled twice, for the baseline and for AVX2 (chosen at run time); its
// helpers are inlined into both.
#if defined(__GNUC__) && (defined(__x86_64__) || defined(_M_X64))
#define LF_ADF_AVX2 1
#define LF_HOT inline __attribute__((always_inline))
#else
#define LF_HOT inline
#endif

class MeshProvider : public SampleProvider
{
public:
    MeshProvider(const TriangleMesh& mesh, const std::vector<Vec3d>& cellPts, const TriangleListTree& lists,
                 const PseudoNormals& normals, double h)
        : mMesh(mesh), mPts(cellPts), mLists(lists), mNormals(normals), mH(h), mBvh(lists.tree()),
          mLattice(kGather, 0, kRegion), mReal(kGather, 1, kRegion)
    {
    }

    /// Gathers the lists of the leaf region [o-4, o+12)³ (the cells the mReal table reaches
    /// from the leaf's cells); `latticeOnly` leaves out the last layer, which the mLattice table
    /// never reaches from the leaf's lattice points (their cells end at o+10).
    LF_HOT void gather(const Coord& o, MeshScratch& s, bool latticeOnly) const
    {
        s.cellSlot.assign(size_t(kRegion) * kRegion * kRegion, -1);
        s.rangeBegin.clear();
        s.quads.clear();
        s.tris.clear();
        s.boxes.clear();
        const Coord rmin = o.offsetBy(-kGather), rmax = o.offsetBy(8 + kGather - 1 - (latticeOnly ? 1 : 0));
        s.centre = Vec3d(o.x() + 4.0, o.y() + 4.0, o.z() + 4.0); // origin of the boxes and planes
        size_t entries = 0;
        auto& cells = s.cells; // (region index, ordinal), in the list leaves' voxel order
        cells.clear();
        const auto& tree = mLists.tree();
        for (int lx = rmin.x() & ~7; lx <= rmax.x(); lx += 8)
            for (int ly = rmin.y() & ~7; ly <= rmax.y(); ly += 8)
                for (int lz = rmin.z() & ~7; lz <= rmax.z(); lz += 8) {
                    const auto* leaf = tree.probeConstLeaf(Coord(lx, ly, lz));
                    if (!leaf) continue;
                    // the part of the leaf inside the region, by mask words
                    const int x0 = std::max(rmin.x(), lx) - lx, x1 = std::min(rmax.x(), lx + 7) - lx;
                    const int y0 = std::max(rmin.y(), ly) - ly, y1 = std::min(rmax.y(), ly + 7) - ly;
                    const int z0 = std::max(rmin.z(), lz) - lz, z1 = std::min(rmax.z(), lz + 7) - lz;
                    const uint32_t zmask = (0xffu >> (7 - (z1 - z0))) << z0;
                    const auto& mask = leaf->getValueMask();
                    const uint32_t* vals = leaf->buffer().data();
                    for (int x = x0; x <= x1; ++x) {
                        const uint64_t w = mask.template getWord<uint64_t>(openvdb::Index(x));
                        if (!w) continue;
                        for (int y = y0; y <= y1; ++y) {
                            uint32_t bits = uint32_t(w >> (8 * y)) & zmask;
                            while (bits) {
                                const int z = __builtin_ctz(bits);
                                bits &= bits - 1;
                                const uint32_t ord = vals[(x << 6) | (y << 3) | z];
                                const int idx = ((lx + x - rmin.x()) * kRegion + (ly + y - rmin.y())) * kRegion + (lz + z - rmin.z());
                                cells.push_back({idx, ord});
                                entries += mLists.listSize(ord);
                            }
                        }
                    }
                }
        // open addressing on the triangle id + 1 (0 = empty; the keys alone are probed, so
        // they stay in L1), the local id beside; sized for the entries (every distinct
        // triangle is at least one entry), load factor <= 1/2
        size_t hsize = 64;
        while (hsize < 2 * entries) hsize <<= 1;
        const uint32_t hmask = uint32_t(hsize - 1);
        s.hashKey.assign(hsize, 0u);
        s.hashLocal.resize(hsize);
        uint32_t* hkey = s.hashKey.data();
        uint32_t* hlocal = s.hashLocal.data();
        s.quads.reserve(entries / 2 + cells.size());
        for (const auto& cell : cells) {
            s.cellSlot[size_t(cell.first)] = int32_t(s.rangeBegin.size());
            s.rangeBegin.push_back(uint32_t(s.quads.size()));
            int lane = 4;
            for (const uint32_t* t = mLists.listBegin(cell.second); t != mLists.listEnd(cell.second); ++t) {
                const uint32_t key = *t + 1;
                uint32_t h = (*t * 2654435761u) & hmask;
                while (hkey[h] != 0u && hkey[h] != key) h = (h + 1) & hmask;
                if (hkey[h] == 0u) {
                    hkey[h] = key;
                    hlocal[h] = uint32_t(s.tris.size());
                    const Vec3I& tri = mMesh.triangles[*t];
                    const Vec3d& a = mPts[tri[0]];
                    const Vec3d& b = mPts[tri[1]];
                    const Vec3d& c = mPts[tri[2]];
                    s.tris.push_back({a, b, c, *t});
                    // grown by 2e-7 of its coordinates' magnitude before rounding to float, which
                    // covers that rounding and the subtraction's (6e-8 each); kPlaneSlack covers
                    // the query point's
                    const Vec3d lo = minComponent(minComponent(a, b), c) - s.centre;
                    const Vec3d hi = maxComponent(maxComponent(a, b), c) - s.centre;
                    const double g = 2e-7 * std::max({std::abs(lo[0]), std::abs(lo[1]), std::abs(lo[2]),
                                                      std::abs(hi[0]), std::abs(hi[1]), std::abs(hi[2])});
                    s.boxes.push_back({{float(lo[0] - g), float(lo[1] - g), float(lo[2] - g), 0.0f},
                                       {float(hi[0] + g), float(hi[1] + g), float(hi[2] + g), 0.0f}});
                }
                const uint32_t local = hlocal[h];
                if (lane == 4) {
                    s.quads.push_back(kPadQuad);
                    lane = 0;
                }
                RefQuad& q = s.quads.back();
                const TriBox& bx = s.boxes[local];
                q.lx[lane] = bx.lo[0]; q.ly[lane] = bx.lo[1]; q.lz[lane] = bx.lo[2];
                q.hx[lane] = bx.hi[0]; q.hy[lane] = bx.hi[1]; q.hz[lane] = bx.hi[2];
                q.t[lane] = local;
                ++lane;
            }
        }
        s.rangeBegin.push_back(uint32_t(s.quads.size()));
        s.stamp.assign(s.tris.size(), 0u);
        s.stampValue = 0;
        s.lastTri = kNone;
        s.planes.resize(s.tris.size());
        s.planeReady.assign(s.tris.size(), 0);
        // the plane bounds and the exact distances round at ~1e-16 of the coordinates (and of
        // 1/sin of the smallest angle, >= 1e-3 where the bound is used): a margin of 1e-6 cells
        // per 1000 cells of coordinate magnitude covers both with a wide reserve
        const double mag = std::max(std::abs(s.centre[0]), std::max(std::abs(s.centre[1]), std::abs(s.centre[2]))) + 64.0;
        s.margin = 1e-6 * std::max(1.0, mag / 1000.0);
    }

    /// The lower-bound planes of gathered triangle t (see TriPlanes).
    LF_HOT static void preparePlanes(MeshScratch& s, uint32_t t)
    {
        s.planeReady[t] = 1;
        TriPlanes& P = s.planes[t];
        double f[16] = {};
        auto store = [&]() {
            double wmax = 0.0;
            for (int row = 0; row < 4; ++row) {
                P.x[row] = float(f[4 * row]);
                P.y[row] = float(f[4 * row + 1]);
                P.z[row] = float(f[4 * row + 2]);
                P.w[row] = float(f[4 * row + 3]);
                wmax = std::max(wmax, std::abs(f[4 * row + 3]));
            }
            P.err = float(1e-5 + 2e-7 * wmax);
        };
        store(); // no bound until the planes are known to be accurate
        const PreparedTri& pt = s.tris[t];
        const Vec3d v[3] = {pt.a - s.centre, pt.b - s.centre, pt.c - s.centre};
        const Vec3d e0 = v[1] - v[0], e1 = v[2] - v[0];
        Vec3d n = e0.cross(e1);
        const double nl = n.length(), l0 = e0.length(), l1 = e1.length();
        if (!(nl > 1e-3 * l0 * l1) || !std::isfinite(nl)) return; // sliver (or degenerate): no bound
        n /= nl;
        f[0] = n[0]; f[1] = n[1]; f[2] = n[2]; f[3] = -n.dot(v[0]);
        for (int k = 0; k < 3; ++k) {
            Vec3d m = (v[(k + 1) % 3] - v[k]).cross(n);
            const double ml = m.length();
            if (!(ml > 0.0)) return; // P still all zero: no bound
            m /= ml;
            f[4 + 4 * k] = m[0]; f[5 + 4 * k] = m[1]; f[6 + 4 * k] = m[2]; f[7 + 4 * k] = -m.dot(v[k]);
        }
        store();
    }

    /// (sqrt(d2) + margin)²: a triangle whose plane bound exceeds it cannot come closer than d2.
    LF_HOT static double boundLimit(double d2, double margin)
    {
        if (!(d2 < std::numeric_limits<double>::infinity())) return d2;
        const double d = std::sqrt(d2) + margin;
        return d * d;
    }

    /// Nearest gathered triangle to q (index space); `base` = the lattice point (local to the
    /// region's corner o-4) the offsets are relative to. Exact when the result is <= kGather.
    /// Cells are visited nearest-first, four references at a time (RefQuad); a triangle is
    /// stamped when its box first passes (a box that fails keeps failing: the best only
    /// shrinks); the plane bound only skips triangles that provably (with a rounding margin)
    /// cannot beat the current best, so the result, ties included, is that of the plain search.
    LF_HOT Nearest nearest(const Vec3d& q, const Coord& baseLocal, const OffsetTable& table, MeshScratch& s) const
    {
        Nearest best;
        if (++s.stampValue == 0) { std::fill(s.stamp.begin(), s.stamp.end(), 0u); s.stampValue = 1; }
        if (s.lastTri < s.tris.size()) { // seed: the previous sample's nearest triangle (an upper bound)
            const PreparedTri& pt = s.tris[s.lastTri];
            s.stamp[s.lastTri] = s.stampValue;
            best.cp = closestPointOnTriangle(q, pt.a, pt.b, pt.c);
            best.d2 = best.cp.distanceSqr;
            best.tri = s.lastTri;
        }
        double limit = boundLimit(best.d2, s.margin);
        const Vec3d r = q - s.centre;
        const float rf[3] = {float(r[0]), float(r[1]), float(r[2])};
#if defined(__SSE2__)
        const __m128 rx4 = _mm_set1_ps(rf[0]), ry4 = _mm_set1_ps(rf[1]), rz4 = _mm_set1_ps(rf[2]);
        const __m128 slack4 = _mm_set1_ps(float(kPlaneSlack));
#endif
        const size_t n = table.off.size();
        const double* td2 = table.d2d.data();
        const int32_t* delta = table.delta.data();
        const int32_t* slots = s.cellSlot.data() + ((baseLocal.x() * kRegion + baseLocal.y()) * kRegion + baseLocal.z());
        const uint32_t* rb = s.rangeBegin.data();
        uint32_t* stamp = s.stamp.data();
        const uint32_t sv = s.stampValue;
        const RefQuad* quads = s.quads.data();
        for (size_t k = 0; k < n; ++k) {
            if (td2[k] >= best.d2) break;
            const int32_t slot = slots[delta[k]];
            if (slot < 0) continue;
            for (uint32_t qi = rb[slot], qe = rb[slot + 1]; qi < qe; ++qi) {
                const RefQuad& quad = quads[qi];
                // box lower bounds of the four references in float: per axis max(lo - p, p - hi,
                // 0) less the slack, summed as (x² + z²) + y² (the order of the one-box form)
                unsigned lanes;
#if defined(__SSE2__)
                {
                    const __m128 zero = _mm_setzero_ps();
                    auto axis = [&](const float* lo, const float* hi, __m128 p) {
                        __m128 d = _mm_max_ps(_mm_sub_ps(_mm_load_ps(lo), p), _mm_sub_ps(p, _mm_load_ps(hi)));
                        d = _mm_max_ps(_mm_sub_ps(d, slack4), zero);
                        return _mm_mul_ps(d, d);
                    };
                    const __m128 b = _mm_add_ps(_mm_add_ps(axis(quad.lx, quad.hx, rx4), axis(quad.lz, quad.hz, rz4)),
                                                axis(quad.ly, quad.hy, ry4));
                    // at least as permissive as the one-box test boxD2 (1 - 1e-6) < best
                    const float tf = best.d2 < 1e30 ? float(best.d2 * (1.0 + 2e-6)) : std::numeric_limits<float>::infinity();
                    lanes = unsigned(_mm_movemask_ps(_mm_cmplt_ps(b, _mm_set1_ps(tf))));
                    if (!lanes) continue;
                }
#else
                lanes = 0;
                for (int l = 0; l < 4; ++l) {
                    const float lo[3] = {quad.lx[l], quad.ly[l], quad.lz[l]}, hi[3] = {quad.hx[l], quad.hy[l], quad.hz[l]};
                    float sq[3];
                    for (int a = 0; a < 3; ++a) {
                        const float d = std::max(std::max(lo[a] - rf[a], rf[a] - hi[a]) - float(kPlaneSlack), 0.0f);
                        sq[a] = d * d;
                    }
                    const float b = (sq[0] + sq[2]) + sq[1];
                    if (b < 1e30f && double(b) * (1.0 - 1e-6) < best.d2) lanes |= 1u << l;
                }
#endif
                // the lanes not yet stamped (a cell lists a triangle once, so the four differ;
                // padding lanes never pass the box test)
                lanes &= unsigned(stamp[quad.t[0]] != sv) | unsigned(stamp[quad.t[1]] != sv) << 1 |
                         unsigned(stamp[quad.t[2]] != sv) << 2 | unsigned(stamp[quad.t[3]] != sv) << 3;
                while (lanes) {
                    const int l = __builtin_ctz(lanes);
                    lanes &= lanes - 1;
                    // a triangle whose box cannot beat the best is skipped at every visit (the
                    // best only shrinks), so stamping only the ones that pass is enough; a
                    // triangle evaluated although it cannot beat the best changes nothing
                    const uint32_t t = quad.t[l];
                    stamp[t] = sv;
                    if (limit < std::numeric_limits<double>::infinity()) {
                        if (!s.planeReady[t]) preparePlanes(s, t);
                        const TriPlanes& P = s.planes[t];
                        float v[4];
#if defined(__SSE2__)
                        const __m128 pv = _mm_add_ps(_mm_add_ps(_mm_mul_ps(_mm_load_ps(P.x), rx4), _mm_mul_ps(_mm_load_ps(P.y), ry4)),
                                                     _mm_add_ps(_mm_mul_ps(_mm_load_ps(P.z), rz4), _mm_load_ps(P.w)));
                        _mm_storeu_ps(v, pv);
#else
                        for (int row = 0; row < 4; ++row) v[row] = P.x[row] * rf[0] + P.y[row] * rf[1] + P.z[row] * rf[2] + P.w[row];
#endif
                        const double slack = kPlaneSlack + double(P.err);
                        const double pl = std::max(std::abs(double(v[0])) - slack, 0.0);
                        const double e = std::max(double(std::max(std::max(v[1], v[2]), std::max(v[3], 0.0f))) - slack, 0.0);
                        if (pl * pl + e * e > limit) continue;
                    }
                    const PreparedTri& pt = s.tris[t];
                    const TriangleClosestPoint cp = closestPointOnTriangle(q, pt.a, pt.b, pt.c);
                    if (cp.distanceSqr < best.d2) {
                        best.d2 = cp.distanceSqr;
                        best.tri = t;
                        best.cp = cp;
                        limit = boundLimit(best.d2, s.margin);
                    }
                }
            }
        }
        s.lastTri = best.tri;
        return best;
    }


    /// Signed distance (world) from a nearest-triangle result; pseudonormal sign.
    double signedWorld(const Nearest& nb, const Vec3d& q, const MeshScratch& s) const
    {
        const double d = std::sqrt(nb.d2) * mH;
        return mNormals.isInside(s.tris[nb.tri].id, nb.cp, q) ? -d : d;
    }

    /// Signed distance (world) from the gathered triangles, with its certificate (voxels): exact
    /// when the nearest gathered triangle is within kGather cells (every closer triangle would
    /// be listed in the region). Otherwise the true distance lies in [max(kGather, e - √3/2),
    /// min(d̃, e + √3/2)] with e the distance to the nearest boundary-cell centre (every
    /// surface point lies in a boundary cell, within √3/2 of its centre); the midpoint is
    /// returned. The sign is the pseudonormal's at the nearest gathered point: the segment to it
    /// stays in the (convex) region, so it crosses no triangle first.
    double certified(const Nearest& nb, const Vec3d& q, MeshScratch& s, double& cert) const
    {
        const double dt = std::sqrt(nb.d2);
        const double sgn = mNormals.isInside(s.tris[nb.tri].id, nb.cp, q) ? -1.0 : 1.0;
        if (dt <= double(kGather)) { cert = 0; return sgn * dt * mH; }
        ++s.type2Wide;
        const double e = std::sqrt(mBvh.nearest2(q, s.hint)), r3 = std::sqrt(3.0) / 2;
        const double lo = std::max(double(kGather), e - r3), hi = std::min(dt, e + r3);
        cert = std::max(0.0, 0.5 * (hi - lo));
        return sgn * 0.5 * (lo + hi) * mH;
    }

    /// Type-3 estimator (world, signed by the flood-filled type-1 band at lattice point `signAt`).
    double estimate(const Vec3d& q, const Coord& signAt, Vec3d& hint) const
    {
        const double d = std::sqrt(mBvh.nearest2(q, hint)) * mH;
        return insideAt(signAt) ? -d : d;
    }

    bool insideAt(const Coord& p) const
    {
        auto& acc = mT1Acc.local();
        if (!acc) acc.reset(new openvdb::tree::ValueAccessor<const FloatTree, false>(*mType1));
        return acc->getValue(p) < 0.0f;
    }

    void leafSamples(size_t, FloatLeaf& leaf, const uint8_t* isFree, float* out) override
    {
#if defined(LF_ADF_AVX2)
        if (avx2LeafPassAvailable() && gAvx2LeafPass.load(std::memory_order_relaxed)) return leafSamplesAvx2(leaf, isFree, out);
#endif
        leafSamplesBase(leaf, isFree, out);
    }

    void leafSamplesBase(FloatLeaf& leaf, const uint8_t* isFree, float* out) { leafSamplesImpl(leaf, isFree, out); }
#if defined(LF_ADF_AVX2)
    /// The same code compiled for AVX2 (VEX encoding; FMA is not enabled, so nothing is
    /// contracted and every value is bit-identical to the base build's).
    __attribute__((target("avx2"))) void leafSamplesAvx2(FloatLeaf& leaf, const uint8_t* isFree, float* out)
    {
        leafSamplesImpl(leaf, isFree, out);
    }
#endif

    LF_HOT void leafSamplesImpl(FloatLeaf& leaf, const uint8_t* isFree, float* out)
    {
        MeshScratch& s = mScratch.local();
        const Coord o = leaf.origin();
        gather(o, s, true);
        FloatLeaf* t1 = nullptr;
        for (int off = 0; off < 512; ++off) {
            if (!isFree[off]) continue;
            const int x = off >> 6, y = (off >> 3) & 7, z = off & 7;
            const Coord local(x + kGather, y + kGather, z + kGather);
            bool type1 = false;
            for (int d = 0; d < 8 && !type1; ++d) {
                const Coord c = local - Coord((d >> 2) & 1, (d >> 1) & 1, d & 1);
                type1 = s.cellSlot[size_t((c.x() * kRegion + c.y()) * kRegion + c.z())] >= 0;
            }
            const Vec3d q(o.x() + x, o.y() + y, o.z() + z);
            const Nearest nb = nearest(q, local, mLattice, s);
            if (nb.tri == kNone) {
                // nothing within the region (refinement leaves far from the surface): type-3 rule.
                // The flood-fill tree is not there yet: signs are fixed in afterLeaves().
                out[off] = float(std::sqrt(mBvh.nearest2(q, s.hint)) * mH);
                mDeferredSign.local().push_back(&out[off]);
                ++s.type3;
                continue;
            }
            double cert = 0;
            const double v = certified(nb, q, s, cert);
            out[off] = float(v);
            if (type1) {
                ++s.type1;
                if (!t1) t1 = new FloatLeaf(o, 0.0f, false);
                t1->setValueOn(openvdb::Index(off), float(v));
            } else {
                ++s.type2;
                s.type2MaxBound = std::max(s.type2MaxBound, cert);
            }
        }
        if (t1) mType1Leaves.local().push_back(t1);
    }

    /// The domain whose 8-spaced lattice the tile samples lie on (set before fillValues).
    void setDomain(const CoordBBox& domain)
    {
        if (mEdtBuilt && domain == mEdtDomain) return;
        mEdtDomain = domain;
        mEdtBuilt = false;
    }

    void afterLeaves(FloatTree& adfTree) override
    {
        const auto t0 = Clock::now();
        if (!mEdtBuilt) {
            mEdt.build(mLists.tree(), mEdtDomain);
            mEdtBuilt = true;
        }
        mType1 = std::make_shared<FloatTree>(1e30f);
        std::vector<FloatLeaf*> all;
        for (auto& v : mType1Leaves) all.insert(all.end(), v.begin(), v.end());
        std::sort(all.begin(), all.end(), [](const FloatLeaf* a, const FloatLeaf* b) { return a->origin() < b->origin(); });
        for (FloatLeaf* l : all) mType1->addLeaf(l);
        mType1Leaves.clear();
        openvdb::tools::signedFloodFill(*mType1);
        mT1Acc.clear();
        fixDeferred(adfTree);
        secondsSignFill = secondsSince(t0);
    }

    void fixDeferred(FloatTree& adfTree)
    {
        // map buffer pointers back to coordinates leaf by leaf
        bool any = false;
        for (auto& v : mDeferredSign) any |= !v.empty();
        if (!any) return;
        std::vector<float*> ptrs;
        for (auto& v : mDeferredSign) ptrs.insert(ptrs.end(), v.begin(), v.end());
        std::sort(ptrs.begin(), ptrs.end());
        openvdb::tree::ValueAccessor<const FloatTree, false> acc(*mType1);
        for (auto it = adfTree.beginLeaf(); it; ++it) {
            float* b = it->buffer().data();
            auto lo = std::lower_bound(ptrs.begin(), ptrs.end(), b);
            for (; lo != ptrs.end() && *lo < b + 512; ++lo) {
                const Coord p = it->offsetToGlobalCoord(openvdb::Index(*lo - b));
                if (acc.getValue(p) < 0.0f) **lo = -std::abs(**lo);
            }
        }
        mDeferredSign.clear();
    }

    double tileSample(const Coord& p) override
    {
        MeshScratch& s = mScratch.local();
        ++s.type3;
        double d2;
        if (mEdt.lookup(p, d2)) { // the tile corners: from the lattice transform (same values)
            const double d = std::sqrt(d2) * mH;
            return insideAt(p) ? -d : d;
        }
        return estimate(Vec3d(p.x(), p.y(), p.z()), p, s.hint);
    }

    // --- bounds (Frisken test points) -------------------------------------------------------
    /// Reference value of the sample function at a point of a leaf cell, world, with its own
    /// bound (world).
    double leafReference(const Vec3d& q, const Coord& o, MeshScratch& s, double& fBound) const
    {
        Coord base(int(std::floor(q[0])), int(std::floor(q[1])), int(std::floor(q[2])));
        for (int k = 0; k < 3; ++k) base[k] = std::min(base[k], o[k] + 7);
        const Coord local = base - o + Coord(kGather);
        const Nearest nb = nearest(q, local, mReal, s);
        if (nb.tri == kNone) {
            fBound = std::sqrt(3.0) / 2 * mH;
            return estimate(q, base, s.hint);
        }
        double cert = 0;
        const double v = certified(nb, q, s, cert);
        fBound = cert * mH;
        return v;
    }

    const TriangleMesh& mMesh;
    const std::vector<Vec3d>& mPts;
    const TriangleListTree& mLists;
    const PseudoNormals& mNormals;
    double mH;
    CentreBvh mBvh;
    OffsetTable mLattice, mReal;
    LatticeEdt mEdt;
    CoordBBox mEdtDomain;
    bool mEdtBuilt = false;
    tbb::enumerable_thread_specific<MeshScratch> mScratch;
    tbb::enumerable_thread_specific<std::vector<FloatLeaf*>> mType1Leaves;
    tbb::enumerable_thread_specific<std::vector<float*>> mDeferredSign;
    std::shared_ptr<FloatTree> mType1;
    mutable tbb::enumerable_thread_specific<std::unique_ptr<openvdb::tree::ValueAccessor<const FloatTree, false>>> mT1Acc;
    double secondsSignFill = 0;

    ~MeshProvider() override
    {
        for (auto& v : mType1Leaves)
            for (FloatLeaf* l : v) delete l;
    }
};

/// Frisken's 19 test points of a cell (centre, face centres, edge midpoints) and its 8
/// corners, index space; `isCorner` tells which.
template<typename F>
void forTestPoints(const CellInfo& X, F&& f)
{
    for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b)
            for (int c = 0; c < 3; ++c)
                f(Vec3d(X.origin.x() + 0.5 * a * X.size, X.origin.y() + 0.5 * b * X.size, X.origin.z() + 0.5 * c * X.size),
                  a != 1 && b != 1 && c != 1);
}

/// Bound of |∇rec| in a cell (world units per world unit): each component of the gradient of a
/// trilinear function is bilinear in the other two coordinates, so its extreme values are
/// taken on the 4 cell edges along that axis.
double gradientBound(Reconstruction& rec, const CellInfo& X, double h)
{
    double v[8];
    for (int k = 0; k < 8; ++k)
        v[k] = rec.value(X.origin + Coord(((k >> 2) & 1) * X.size, ((k >> 1) & 1) * X.size, (k & 1) * X.size));
    double g2 = 0;
    for (int axis = 0; axis < 3; ++axis) {
        const int bit = 4 >> axis;
        double m = 0;
        for (int k = 0; k < 8; ++k)
            if (!(k & bit)) m = std::max(m, std::abs(v[k | bit] - v[k]));
        g2 += (m / (X.size * h)) * (m / (X.size * h));
    }
    return std::sqrt(g2);
}

struct BoundAcc
{
    std::array<double, kAdfLevels> dev{{-1, -1, -1, -1, -1}};   // Frisken: test points only
    std::array<double, kAdfLevels> bound{{-1, -1, -1, -1, -1}}; // everywhere in the cell
    std::vector<std::pair<int, Coord>> failing; // (level, cell origin) over tolerance
    void add(int level, double testDev, double cellBound)
    {
        dev[size_t(level)] = std::max(dev[size_t(level)], testDev);
        bound[size_t(level)] = std::max(bound[size_t(level)], cellBound);
    }
};

/// Checks the reconstruction at the test points of every tile cell (levels 3, 4) and, if
/// `leafCells`, of the cells inside leaves (level 0: every unitStride-th finest cell). Returns per-level
/// (deviation + reference bound), in voxels; collects tile cells deviating more than tolWorld.
struct Bounds { std::array<double, kAdfLevels> testPoints, cells; };
Bounds checkBounds(const FloatTree& tree, const Layout& layout, MeshProvider& mp, bool leafCells, int unitStride,
                   double tolWorld, std::vector<std::pair<int, Coord>>* failing)
{
    const CoordBBox dom = layout.domain;
    const double h = mp.mH, e3 = std::sqrt(3.0) / 2 * h;
    tbb::enumerable_thread_specific<BoundAcc> accs;
    // tile cells
    std::vector<CellInfo> tileCells;
    for (const Coord& b : layout.subdividedL2) {
        const Internal1* n1 = tree.root().template probeConstNode<Internal1>(b);
        if (!n1 || !inDomainCell(dom, b)) continue;
        for (openvdb::Index n = 0; n < Internal1::NUM_VALUES; ++n)
            if (!n1->isChildMaskOn(n)) tileCells.push_back({8, n1->offsetToGlobalCoord(n)});
    }
    for (const Coord& b : layout.tileL2)
        if (inDomainCell(dom, b)) tileCells.push_back({128, b});
    tbb::parallel_for(tbb::blocked_range<size_t>(0, tileCells.size(), 64), [&](const tbb::blocked_range<size_t>& r) {
        Reconstruction rec(tree, dom);
        BoundAcc& acc = accs.local();
        MeshScratch& s = mp.mScratch.local();
        for (size_t i = r.begin(); i != r.end(); ++i) {
            const CellInfo X = tileCells[i];
            double worst = 0, worstTest = 0;
            forTestPoints(X, [&](const Vec3d& q, bool corner) {
                const double f = mp.estimate(q, X.origin, s.hint);
                const double dev = std::abs(rec.distanceIndex(q, nullptr, nullptr) - f);
                worst = std::max(worst, dev);
                if (!corner) worstTest = std::max(worstTest, dev);
            });
            const double lip = (1.0 + gradientBound(rec, X, h)) * std::sqrt(3.0) / 4 * X.size * h;
            acc.add(levelOfSize(X.size), worstTest + e3, worst + e3 + lip);
            if (tolWorld > 0 && worstTest > tolWorld) acc.failing.push_back({levelOfSize(X.size), X.origin});
        }
    });
    if (leafCells) {
        const size_t nLeaves = layout.leafOrigins.size();
        tbb::parallel_for(tbb::blocked_range<size_t>(0, nLeaves, 4), [&](const tbb::blocked_range<size_t>& r) {
            Reconstruction rec(tree, dom);
            BoundAcc& acc = accs.local();
            MeshScratch& s = mp.mScratch.local();
            for (size_t i = r.begin(); i != r.end(); ++i) {
                const Coord o = layout.leafOrigins[i];
                mp.gather(o, s, false);
                int unitCounter = 0;
                for (int x = 0; x < 8; ++x)
                    for (int y = 0; y < 8; ++y)
                        for (int z = 0; z < 8; ++z) {
                            const Coord c = o + Coord(x, y, z);
                            const CellInfo X = rec.cellAt(c);
                            if (X.origin != c) continue; // visit each cell once, at its origin
                            if (X.size == 1 && (unitCounter++ % unitStride) != 0) continue;
                            double worst = 0, worstTest = 0;
                            forTestPoints(X, [&](const Vec3d& q, bool corner) {
                                double fb = 0;
                                const double f = mp.leafReference(q, o, s, fb);
                                const double dev = std::abs(rec.distanceIndex(q, nullptr, nullptr) - f) + fb;
                                worst = std::max(worst, dev);
                                if (!corner) worstTest = std::max(worstTest, dev);
                            });
                            const double lip = (1.0 + gradientBound(rec, X, h)) * std::sqrt(3.0) / 4 * X.size * h;
                            acc.add(levelOfSize(X.size), worstTest, worst + lip);
                        }
            }
        });
    }
    Bounds out;
    out.testPoints.fill(-1);
    out.cells.fill(-1);
    for (const BoundAcc& a : accs) {
        for (int l = 0; l < kAdfLevels; ++l) {
            out.testPoints[size_t(l)] = std::max(out.testPoints[size_t(l)], a.dev[size_t(l)]);
            out.cells[size_t(l)] = std::max(out.cells[size_t(l)], a.bound[size_t(l)]);
        }
        if (failing) failing->insert(failing->end(), a.failing.begin(), a.failing.end());
    }
    for (int l = 0; l < kAdfLevels; ++l) {
        if (out.testPoints[size_t(l)] >= 0) out.testPoints[size_t(l)] /= h;
        if (out.cells[size_t(l)] >= 0) out.cells[size_t(l)] /= h;
    }
    if (failing) std::sort(failing->begin(), failing->end());
    return out;
}

} // namespace

} // namespace adf_internal

namespace adf_internal {

bool avx2LeafPassAvailable()
{
#if defined(LF_ADF_AVX2)
    static const bool has = __builtin_cpu_supports("avx2");
    return has;
#else
    return false;
#endif
}

void setAvx2LeafPassEnabled(bool enabled) { gAvx2LeafPass.store(enabled, std::memory_order_relaxed); }

} // namespace adf_internal

// ================================================================================ public API

using namespace adf_internal;

AdaptiveDistanceField::AdaptiveDistanceField(openvdb::FloatGrid::ConstPtr grid)
{
    if (!grid) throw InvalidArgumentError("ADF: null grid");
    if (!isAdaptiveDistanceField(*grid))
        throw InvalidArgumentError("grid '" + grid->getName() + "' is not a levelforge ADF (no \"" + kAdfMetaKey + "\" metadata)");
    const auto lo = grid->getMetadata<openvdb::Vec3IMetadata>("levelforge:adf_domain_min");
    const auto hi = grid->getMetadata<openvdb::Vec3IMetadata>("levelforge:adf_domain_max");
    if (!lo || !hi) throw InvalidArgumentError("ADF grid '" + grid->getName() + "': missing domain metadata");
    mDomain = CoordBBox(Coord(lo->value()), Coord(hi->value()));
    for (int k = 0; k < 3; ++k)
        if (mDomain.min()[k] % 128 || mDomain.max()[k] % 128 || mDomain.max()[k] <= mDomain.min()[k])
            throw InvalidArgumentError("ADF grid '" + grid->getName() + "': domain is not made of whole 128^3 blocks");
    if (!grid->hasUniformVoxels() || !grid->transform().isLinear())
        throw InvalidArgumentError("ADF grid '" + grid->getName() + "': transform must be linear with cubic voxels");
    mH = grid->voxelSize()[0];
    for (int l = 0; l < kAdfLevels; ++l) {
        char key[64];
        std::snprintf(key, sizeof(key), "levelforge:adf_bound_level%d_voxels", l);
        if (const auto m = grid->getMetadata<openvdb::DoubleMetadata>(key)) mBounds[size_t(l)] = m->value();
    }
    mGrid = grid;
}

openvdb::BBoxd AdaptiveDistanceField::worldDomain() const
{
    return openvdb::BBoxd(mGrid->indexToWorld(mDomain.min()), mGrid->indexToWorld(mDomain.max()));
}

namespace {
inline Vec3d toIndex(const openvdb::FloatGrid& g, const Vec3d& w) { return g.worldToIndex(w); }
} // namespace

double AdaptiveDistanceField::distance(const Vec3d& worldPoint) const
{
    Reconstruction rec(mGrid->tree(), mDomain);
    return rec.distanceIndex(toIndex(*mGrid, worldPoint), nullptr, nullptr);
}

Vec3d AdaptiveDistanceField::gradient(const Vec3d& worldPoint) const
{
    Reconstruction rec(mGrid->tree(), mDomain);
    Vec3d g;
    rec.distanceIndex(toIndex(*mGrid, worldPoint), &g, nullptr);
    return g / mH;
}

int AdaptiveDistanceField::level(const Vec3d& worldPoint) const
{
    const Vec3d q = toIndex(*mGrid, worldPoint);
    for (int k = 0; k < 3; ++k)
        if (q[k] < mDomain.min()[k] || q[k] > mDomain.max()[k]) return -1;
    Reconstruction rec(mGrid->tree(), mDomain);
    int l = -1;
    rec.distanceIndex(q, nullptr, &l);
    return l;
}

double AdaptiveDistanceField::latticeValue(const openvdb::Coord& ijk) const
{
    Reconstruction rec(mGrid->tree(), mDomain);
    return rec.value(ijk);
}

bool isAdaptiveDistanceField(const openvdb::GridBase& grid)
{
    return bool(grid.getMetadata<openvdb::StringMetadata>(kAdfMetaKey)) && grid.isType<openvdb::FloatGrid>();
}

namespace {

/// 3 × 10 bits interleaved (x highest).
inline uint32_t mortonCode(uint32_t x, uint32_t y, uint32_t z)
{
    auto spread = [](uint32_t v) {
        v &= 0x3ff;
        v = (v | v << 16) & 0x030000ffu;
        v = (v | v << 8) & 0x0300f00fu;
        v = (v | v << 4) & 0x030c30c3u;
        v = (v | v << 2) & 0x09249249u;
        return v;
    };
    return spread(x) << 2 | spread(y) << 1 | spread(z);
}

/// The indices 0..n-1 ordered by key (stable), by a two-pass 16-bit radix sort.
std::vector<uint32_t> orderByKey(const std::vector<uint32_t>& key)
{
    const size_t n = key.size();
    std::vector<uint32_t> a(n), b(n);
    std::iota(a.begin(), a.end(), 0u);
    for (int shift = 0; shift < 32; shift += 16) {
        std::vector<uint32_t> count(65537, 0u);
        for (uint32_t i : a) ++count[((key[i] >> shift) & 0xffffu) + 1];
        for (size_t d = 1; d < count.size(); ++d) count[d] += count[d - 1];
        for (uint32_t i : a) b[count[(key[i] >> shift) & 0xffffu]++] = i;
        a.swap(b);
    }
    return a;
}

/// The mesh with its vertices and triangles in Morton order of their positions (blocks of 4
/// cells of size `cell`; beyond 1024 blocks per axis the order coarsens), each triangle's vertex
/// order kept: the voxelization and the per-leaf gathers then read nearby memory. Distances do
/// not depend on the order; which of several equally near triangles is reported, and so the
/// certified samples beyond the gather radius, may. `b`: the mesh's bounds (TriangleMesh::bounds).
TriangleMesh spatiallyOrdered(const TriangleMesh& mesh, const BBoxd& b, double cell)
{
    const double inv = 1.0 / (4.0 * cell);
    auto key = [&](const Vec3d& p) {
        uint32_t c[3];
        for (int k = 0; k < 3; ++k) {
            const double v = (p[k] - b.min()[k]) * inv; // unused vertices may lie anywhere, or be NaN
            c[k] = v >= 0.0 ? uint32_t(std::min(v, 1023.0)) : 0u;
        }
        return mortonCode(c[0], c[1], c[2]);
    };
    TriangleMesh out;
    out.source = mesh.source;
    std::vector<uint32_t> vkey(mesh.points.size());
    tbb::parallel_for(tbb::blocked_range<size_t>(0, vkey.size(), 8192), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t i = r.begin(); i != r.end(); ++i) vkey[i] = key(mesh.points[i]);
    });
    const std::vector<uint32_t> vorder = orderByKey(vkey);
    std::vector<uint32_t> newIndex(vorder.size());
    out.points.resize(vorder.size());
    for (size_t i = 0; i < vorder.size(); ++i) {
        newIndex[vorder[i]] = uint32_t(i);
        out.points[i] = mesh.points[vorder[i]];
    }
    std::vector<uint32_t> tkey(mesh.triangles.size());
    tbb::parallel_for(tbb::blocked_range<size_t>(0, tkey.size(), 8192), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t t = r.begin(); t != r.end(); ++t) {
            const Vec3I& tri = mesh.triangles[t];
            tkey[t] = key((mesh.points[tri[0]] + mesh.points[tri[1]] + mesh.points[tri[2]]) / 3.0);
        }
    });
    const std::vector<uint32_t> torder = orderByKey(tkey);
    out.triangles.resize(torder.size());
    for (size_t t = 0; t < torder.size(); ++t) {
        const Vec3I& tri = mesh.triangles[torder[t]];
        out.triangles[t] = Vec3I(newIndex[tri[0]], newIndex[tri[1]], newIndex[tri[2]]);
    }
    return out;
}

} // namespace

AdaptiveDistanceField meshToAdaptiveDistanceField(const TriangleMesh& inputMesh, const AdaptiveDistanceFieldOptions& options,
                                                  AdaptiveDistanceFieldStats* statsOut)
{
    openvdb::initialize();
    AdaptiveDistanceFieldStats stats;
    auto* interrupter = options.interrupter;
    if (!std::isfinite(options.paddingVoxels) || options.paddingVoxels < 0)
        throw InvalidArgumentError("ADF padding must be a finite number of voxels >= 0");
    if (!std::isfinite(options.toleranceVoxels) || options.toleranceVoxels < 0)
        throw InvalidArgumentError("ADF tolerance must be a finite number of voxels >= 0 (0 = no refinement)");
    requireUsableMesh(inputMesh);
    MeshToLevelSetOptions lsOpt;
    lsOpt.voxelSize = options.voxelSize;
    lsOpt.voxelCount = options.voxelCount;
    const double h = resolveVoxelSize(inputMesh, lsOpt);
    stats.voxelSize = h;
    const BBoxd bounds = inputMesh.bounds();
    for (int k = 0; k < 3; ++k) {
        const double lo = bounds.min()[k] / h - 1024, hi = bounds.max()[k] / h + 1024;
        if (!(std::abs(lo) < 1.0e9 && std::abs(hi) < 1.0e9))
            throw ResourceLimitError("voxel size is too small for this mesh: index coordinates would exceed 1e9");
    }
    if (interrupter) interrupter->start("mesh to ADF");
    const TriangleMesh mesh = spatiallyOrdered(inputMesh, bounds, h);

    // ---- voxelization + triangle lists (cell space = index space: cell c = [c, c+1)³)
    const auto t0 = Clock::now();
    std::vector<Vec3d> cellPts(mesh.points.size());
    tbb::parallel_for(tbb::blocked_range<size_t>(0, cellPts.size(), 8192), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t i = r.begin(); i != r.end(); ++i) cellPts[i] = mesh.points[i] / h;
    });
    // the non-degenerate triangles, by PseudoNormals' own test (a zero or non-finite normal
    // length), so that the pseudonormals can be built while the lists are
    std::vector<uint8_t> degenerate(mesh.triangles.size(), 0);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, degenerate.size(), 4096), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t t = r.begin(); t != r.end(); ++t) {
            const Vec3I& tri = mesh.triangles[t];
            const Vec3d& a = mesh.points[tri[0]];
            const Vec3d& b = mesh.points[tri[1]];
            const Vec3d& c = mesh.points[tri[2]];
            const double len = (b - a).cross(c - a).length();
            degenerate[t] = !(len > 0.0) || !std::isfinite(len);
        }
    });
    std::vector<uint32_t> use;
    use.reserve(mesh.triangles.size());
    for (uint32_t t = 0; t < mesh.triangles.size(); ++t)
        if (!degenerate[t]) use.push_back(t);
    if (use.empty()) throw InvalidMeshError((mesh.source.empty() ? std::string("mesh") : mesh.source) + ": every triangle is degenerate");
    stats.triangles = use.size();
    // domain guard before the voxelization (the bounding box decides the domain)
    {
        uint64_t dense = 1;
        for (int k = 0; k < 3; ++k) {
            const double ext = (bounds.max()[k] - bounds.min()[k]) / h + 2.0 * std::max(9.0, options.paddingVoxels) + 256;
            dense = uint64_t(double(dense) * ext);
        }
        if (options.maxVoxels && dense > options.maxVoxels * 2) {
            std::ostringstream os;
            os << "the ADF domain would span about " << dense << " finest voxels, more than the limit of " << options.maxVoxels
               << "; use a larger voxel size";
            throw ResourceLimitError(os.str());
        }
    }
    // pseudonormals (partly serial) concurrently with the voxelization
    std::unique_ptr<PseudoNormals> normalsPtr;
    tbb::task_group normalsTask;
    normalsTask.run([&] { normalsPtr.reset(new PseudoNormals(mesh)); });
    std::unique_ptr<TriangleListTree> listsPtr;
    try {
        listsPtr.reset(new TriangleListTree(TriangleListTree::build(cellPts, mesh.triangles, use, nullptr, interrupter)));
    } catch (...) {
        normalsTask.wait();
        throw;
    }
    normalsTask.wait();
    const PseudoNormals& normals = *normalsPtr;
    const TriangleListTree& lists = *listsPtr;
    for (uint32_t t : use)
        if (normals.isDegenerate(t)) throw Error("ADF: degeneracy test disagrees with the pseudonormals"); // never happens
    stats.boundaryCells = lists.cellCount();
    stats.secondsVoxelize = secondsSince(t0);
    progress_internal::check(interrupter, 20);

    // ---- octree: M' = M dilated by one cell; leaves, internal-1 nodes, tiles
    const auto t1 = Clock::now();
    Layout base;
    {
        openvdb::MaskTree mp(lists.tree(), false, openvdb::TopologyCopy());
        openvdb::tools::dilateActiveValues(mp, 1, openvdb::tools::NN_FACE_EDGE_VERTEX, openvdb::tools::IGNORE_TILES);
        for (auto it = mp.cbeginLeaf(); it; ++it) {
            base.leafOrigins.push_back(it->origin());
            base.leafMasks.push_back(it->getValueMask());
        }
        CoordBBox mbox;
        lists.tree().evalActiveVoxelBoundingBox(mbox);
        makeDomain(base, mbox, options.paddingVoxels);
    }
    const Coord dim = base.domain.dim();
    const double domainVoxels = double(dim.x() - 1) * double(dim.y() - 1) * double(dim.z() - 1);
    if (options.maxVoxels && domainVoxels > double(options.maxVoxels)) {
        std::ostringstream os;
        os << "the ADF domain spans " << uint64_t(domainVoxels) << " finest voxels, more than the limit of " << options.maxVoxels;
        throw ResourceLimitError(os.str());
    }
    stats.domainVoxels = uint64_t(domainVoxels);
    stats.secondsOctree = secondsSince(t1);

    MeshProvider provider(mesh, cellPts, lists, normals, h);
    const float background = float(std::sqrt(3.0) * double(dim.x() + dim.y() + dim.z()) * h);
    std::vector<Coord> forcedLeaves, forcedL2;
    FloatTree::Ptr tree;
    Layout layout;
    PipelineResult pr;
    std::array<double, kAdfLevels> bound{{-1, -1, -1, -1, -1}};
    for (int iteration = 0;; ++iteration) {
        const auto t2 = Clock::now();
        layout = base;
        LeafMask full;
        full.setOn();
        for (const Coord& o : forcedLeaves) { layout.leafOrigins.push_back(o); layout.leafMasks.push_back(full); }
        layout.subdividedL2 = forcedL2;
        layout.finish();
        tree = createTree(layout, background);
        stats.secondsOctree += secondsSince(t2);
        for (auto& s : provider.mScratch) { s.type1 = s.type2 = s.type3 = s.type2Wide = 0; s.type2MaxBound = 0; }
        provider.setDomain(layout.domain);
        pr = fillValues(*tree, layout, provider, interrupter);
        progress_internal::check(interrupter, 80);
        if (options.toleranceVoxels <= 0 || iteration >= 8) break;
        std::vector<std::pair<int, Coord>> failing;
        const auto t3 = Clock::now();
        checkBounds(*tree, layout, provider, false, 1, options.toleranceVoxels * h, &failing);
        stats.secondsBounds += secondsSince(t3);
        if (failing.empty()) break;
        for (const auto& f : failing) {
            if (f.first == 4) forcedL2.push_back(f.second);
            else forcedLeaves.push_back(f.second);
            ++stats.refinedTiles;
        }
    }
    for (const MeshScratch& s : provider.mScratch) {
        stats.type1 += s.type1;
        stats.type2 += s.type2;
        stats.type3 += s.type3;
        stats.type2Wide += s.type2Wide;
        stats.type2MaxBoundVoxels = std::max(stats.type2MaxBoundVoxels, s.type2MaxBound);
    }
    stats.hanging = pr.hanging;
    stats.leaves = layout.leafOrigins.size();
    stats.level1Tiles = pr.level1Tiles;
    stats.level2Tiles = pr.level2Tiles;
    // Table 1 split: the leaf pass computes type-1 and type-2 together; split by count.
    const double leafSec = pr.secondsLeaves;
    const double n12 = double(stats.type1 + stats.type2);
    stats.secondsType1 = n12 > 0 ? leafSec * double(stats.type1) / n12 : 0;
    stats.secondsType2 = leafSec - stats.secondsType1;
    stats.secondsType3 = pr.secondsTiles + provider.secondsSignFill;
    stats.secondsFinish = pr.secondsHanging;

    if (options.computeBounds) {
        const auto t4 = Clock::now();
        const Bounds b = checkBounds(*tree, layout, provider, true, std::max(1, options.boundStride), 0.0, nullptr);
        bound = b.cells;
        stats.levelTestPointVoxels = b.testPoints;
        stats.secondsBounds += secondsSince(t4);
    }
    stats.levelBoundVoxels = bound;
    {
        // cells of sizes 1, 2, 4 inside the leaves, from their masks
        for (const LeafMask& m : layout.leafMasks) LeafCellSizes(m).count(stats.cells[0], stats.cells[1], stats.cells[2]);
        stats.cells[3] = pr.cells[3];
        stats.cells[4] = pr.cells[4];
    }

    auto grid = openvdb::FloatGrid::create(tree);
    grid->setTransform(openvdb::math::Transform::createLinearTransform(h));
    grid->setName(options.gridName);
    stampAdfMetadata(*grid, layout.domain, bound);
    grid->insertMeta("levelforge:source", openvdb::StringMetadata(mesh.source));
    grid->insertMeta("levelforge:method", openvdb::StringMetadata("yin2011-adf"));
    stats.memoryBytes = tree->memUsage();
    if (interrupter) { interrupter->wasInterrupted(100); interrupter->end(); }
    if (statsOut) *statsOut = stats;
    return AdaptiveDistanceField(grid);
}

} // namespace levelforge
