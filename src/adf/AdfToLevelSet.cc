// SPDX-License-Identifier: Apache-2.0
// ADF → narrow-band level set: the reconstruction sampled at the voxel centres of the 8³ blocks
// that may hold the band. See AdaptiveDistanceField.h.
#include "adf/AdfInternal.h"

#include <levelforge/core/Exceptions.h>
#include <levelforge/core/Metadata.h>
#include <levelforge/io/VdbIO.h>

#include <openvdb/tools/SignedFloodFill.h>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <string>
#include <vector>

namespace levelforge {

using namespace adf_internal;

openvdb::FloatGrid::Ptr adaptiveDistanceFieldToLevelSet(const AdaptiveDistanceField& adf, double halfWidthVoxels)
{
    if (!adf.valid()) throw InvalidArgumentError("ADF to level set: empty ADF");
    if (!std::isfinite(halfWidthVoxels) || halfWidthVoxels <= 0)
        throw InvalidArgumentError("ADF to level set: the band half-width must be a positive number of voxels");
    const double h = adf.voxelSize();
    const double band = halfWidthVoxels * h;
    const float bg = float(band);
    const FloatTree& tree = adf.grid()->tree();
    const CoordBBox dom = adf.indexDomain();

    // candidate 8³ blocks: every leaf, and every block of a tile cell whose corner values
    // (trilinear = convex combination) do not all lie beyond the band on the same side
    std::vector<Coord> cand;
    for (auto it = tree.cbeginLeaf(); it; ++it)
        if (inDomainCell(dom, it->origin())) cand.push_back(it->origin());
    {
        Reconstruction rec(tree, dom);
        auto blockMayHold = [&](const Coord& o) {
            double lo = 1e300, hi = -1e300;
            for (int k = 0; k < 8; ++k) {
                const double v = rec.value(o + Coord(((k >> 2) & 1) * 8, ((k >> 1) & 1) * 8, (k & 1) * 8));
                lo = std::min(lo, v);
                hi = std::max(hi, v);
            }
            return !(lo >= band || hi <= -band);
        };
        std::vector<const Internal1*> n1s;
        tree.getNodes(n1s);
        for (const Internal1* n : n1s) {
            if (!inDomainCell(dom, n->origin())) continue;
            for (openvdb::Index i = 0; i < Internal1::NUM_VALUES; ++i) {
                if (n->isChildMaskOn(i)) continue;
                const Coord o = n->offsetToGlobalCoord(i);
                if (blockMayHold(o)) cand.push_back(o);
            }
        }
        std::vector<const Internal2*> n2s;
        tree.getNodes(n2s);
        for (const Internal2* n : n2s) {
            for (openvdb::Index i = 0; i < Internal2::NUM_VALUES; ++i) {
                if (n->isChildMaskOn(i)) continue;
                const Coord o = n->offsetToGlobalCoord(i);
                if (!inDomainCell(dom, o)) continue;
                for (int x = 0; x < 128; x += 8)
                    for (int y = 0; y < 128; y += 8)
                        for (int z = 0; z < 128; z += 8) {
                            const Coord b = o + Coord(x, y, z);
                            if (blockMayHold(b)) cand.push_back(b);
                        }
            }
        }
    }
    std::sort(cand.begin(), cand.end());
    std::vector<std::unique_ptr<FloatLeaf>> out(cand.size());
    tbb::parallel_for(tbb::blocked_range<size_t>(0, cand.size(), 8), [&](const tbb::blocked_range<size_t>& r) {
        Reconstruction rec(tree, dom);
        for (size_t i = r.begin(); i != r.end(); ++i) {
            auto leaf = std::make_unique<FloatLeaf>(cand[i], bg, false);
            bool any = false;
            for (openvdb::Index off = 0; off < FloatLeaf::SIZE; ++off) {
                const Coord p = leaf->offsetToGlobalCoord(off);
                const double d = rec.distanceIndex(Vec3d(p.x(), p.y(), p.z()), nullptr, nullptr);
                if (std::abs(d) < band) {
                    leaf->setValueOn(off, float(d));
                    any = true;
                } else {
                    leaf->setValueOff(off, d < 0 ? -bg : bg);
                }
            }
            if (any) out[i] = std::move(leaf);
        }
    });
    auto lsTree = std::make_shared<FloatTree>(bg);
    for (auto& l : out) {
        if (!l) continue;
        lsTree->addLeaf(l.get()); // owned here until the tree has it
        l.release();
    }
    openvdb::tools::signedFloodFill(*lsTree);
    auto grid = openvdb::FloatGrid::create(lsTree);
    grid->setTransform(adf.grid()->transform().copy());
    grid->setName(adf.grid()->getName() == "adf" ? "surface" : adf.grid()->getName());
    std::string source;
    if (const auto m = adf.grid()->getMetadata<openvdb::StringMetadata>(meta::kSource)) source = m->value();
    stampLevelSetMetadata(*grid, halfWidthVoxels, halfWidthVoxels, source, "yin2011-adf-resampled");
    return grid;
}

} // namespace levelforge
