// SPDX-License-Identifier: Apache-2.0
// Level set → fog volume (see levelset/SdfToFog.h).
#include <levelforge/levelset/SdfToFog.h>

#include <levelforge/core/Exceptions.h>
#include <levelforge/core/Metadata.h>
#include <levelforge/mesh/MeshToLevelSet.h>

#include <openvdb/tools/Prune.h>
#include <openvdb/tree/LeafManager.h>

#include <tbb/blocked_range.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <sstream>

namespace levelforge {

namespace {

double bandMeta(const openvdb::FloatGrid& g, const char* key)
{
    if (auto m = g.getMetadata<openvdb::FloatMetadata>(key)) return double(m->value());
    if (auto m = g.getMetadata<openvdb::DoubleMetadata>(key)) return m->value();
    return 0.0;
}

} // namespace

double fogInteriorWidth(const openvdb::FloatGrid& sdf, const SdfToFogOptions& options)
{
    double w = options.interiorWidthWorld;
    std::string from = "the interior width option";
    if (w == 0.0) {
        const openvdb::Vec3d vs = sdf.voxelSize();
        const double voxels = bandMeta(sdf, meta::kInteriorBandVoxels);
        if (voxels > 0.0 && std::isfinite(voxels)) {
            if (!(std::abs(vs[0] - vs[1]) <= 1e-9 * vs[0] && std::abs(vs[0] - vs[2]) <= 1e-9 * vs[0]))
                throw InvalidArgumentError("fog: the level set '" + sdf.getName() +
                                           "' has a non-uniform voxel size: give the interior width in world units");
            w = voxels * vs[0];
            from = "the level set's interior band metadata";
        } else {
            w = double(sdf.background());
            from = "the level set's background";
        }
    }
    if (!(std::isfinite(w) && w > 0.0)) {
        std::ostringstream os;
        os << "fog: the interior ramp width must be finite and positive (world units), got " << w << " from "
           << from;
        throw InvalidArgumentError(os.str());
    }
    return w;
}

openvdb::FloatGrid::Ptr sdfToFog(const openvdb::FloatGrid& sdf, const SdfToFogOptions& options)
{
    using TreeT = openvdb::FloatTree;
    using LeafT = TreeT::LeafNodeType;
    const double width = fogInteriorWidth(sdf, options);
    const float scale = float(-1.0 / width); // fog = clamp(φ · (−1/w), 0, 1)
    const float background = sdf.background();
    bool filled = false;
    if (auto m = sdf.getMetadata<openvdb::BoolMetadata>(kFillInteriorMetadata)) filled = m->value();
    const float deep = -std::abs(background); // the value of a filled interior voxel (band values
                                              // below it, with a wider interior band, still ramp)

    auto* interrupter = options.interrupter;
    if (interrupter) interrupter->start("level set to fog");

    // A deep copy of the tree: same topology, then every value rewritten in place.
    auto tree = std::make_shared<TreeT>(sdf.tree());

    std::atomic<bool> stop{false};
    {
        openvdb::tree::LeafManager<TreeT> leaves(*tree);
        leaves.foreach([&](LeafT& leaf, size_t) {
            if (stop.load(std::memory_order_relaxed)) return;
            if (interrupter && interrupter->wasInterrupted()) {
                stop.store(true, std::memory_order_relaxed);
                return;
            }
            for (openvdb::Index i = 0; i < LeafT::SIZE; ++i) {
                const float phi = leaf.getValue(i);
                float fog = 0.0f;
                if (phi < 0.0f) {
                    const bool deepInside = !leaf.isValueOn(i) || (filled && phi == deep);
                    fog = deepInside ? 1.0f : std::clamp(phi * scale, 0.0f, 1.0f);
                }
                if (fog > 0.0f) leaf.setValueOn(i, fog);
                else leaf.setValueOff(i, 0.0f);
            }
        });
    }
    if (stop.load()) {
        if (interrupter) interrupter->end();
        throw InterruptedError("interrupted while converting a level set to fog");
    }

    // Tiles (every level above the leaves): inside → active 1, outside → inactive 0.
    TreeT::ValueAllIter it = tree->beginValueAll();
    it.setMaxDepth(TreeT::ValueAllIter::LEAF_DEPTH - 1); // leaf values: done above
    for (; it; ++it) {
        if (*it < 0.0f) {
            it.setValue(1.0f);
            it.setActiveState(true);
        } else {
            it.setValue(0.0f);
            it.setActiveState(false);
        }
    }
    tree->root().setBackground(0.0f, /*updateChildNodes=*/false);
    openvdb::tools::prune(*tree); // leaves all 0 or all 1 (active) become tiles

    auto fog = openvdb::FloatGrid::create(tree);
    fog->setTransform(sdf.transform().copy());
    fog->setName(options.gridName.empty() ? sdf.getName() : options.gridName);
    fog->setGridClass(openvdb::GRID_FOG_VOLUME);
    if (interrupter) interrupter->end();
    return fog;
}

} // namespace levelforge
