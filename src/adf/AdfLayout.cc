// SPDX-License-Identifier: Apache-2.0
// ADF layout (see AdaptiveDistanceField.h): which 8³ blocks are leaves, which 128³ blocks are
// internal-1 nodes (grading: a leaf never touches a 128³ cell) and which are level-2 tiles; the
// domain rounded out to whole 128³ blocks; the empty tree of a layout.
#include "adf/AdfInternal.h"

#include <algorithm>
#include <cmath>
#include <memory>
#include <numeric>

namespace levelforge {
namespace adf_internal {

namespace {
inline int floorTo(int v, int m) { return v & ~(m - 1); }
inline int ceilTo(int v, int m) { return (v + m - 1) & ~(m - 1); }
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
        auto leaf = std::make_unique<FloatLeaf>(layout.leafOrigins[i], 0.0f, false);
        leaf->setValueMask(layout.leafMasks[i]);
        tree->addLeaf(leaf.get()); // owned here until the tree has it
        leaf.release();
    }
    for (const Coord& b : layout.tileL2) tree->addTile(2, b, 0.0f, false);
    return tree;
}

} // namespace adf_internal
} // namespace levelforge
