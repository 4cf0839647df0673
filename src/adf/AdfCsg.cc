// SPDX-License-Identifier: Apache-2.0
// CSG of two ADFs (Yin et al. 2011 Figure 10): the finer cells of the two, op(a, b) sampled at
// the result's lattice points through the value pipeline. See AdaptiveDistanceField.h.
#include "adf/AdfInternal.h"

#include <levelforge/core/CsgOperation.h>
#include <levelforge/core/Exceptions.h>
#include <levelforge/core/Metadata.h>

#include <tbb/enumerable_thread_specific.h>

#include <algorithm>
#include <memory>
#include <string>
#include <utility>

namespace levelforge {

using namespace adf_internal;

namespace {

double applyOp(CsgOperation op, double a, double b)
{
    switch (op) {
    case CsgOperation::Union: return std::min(a, b);
    case CsgOperation::Intersection: return std::max(a, b);
    case CsgOperation::Difference: return std::max(a, -b);
    }
    return a;
}

/// Samples op(a, b) at lattice points, reading both inputs' reconstructions.
class CsgProvider : public SampleProvider
{
public:
    CsgProvider(const AdaptiveDistanceField& a, const AdaptiveDistanceField& b, CsgOperation op) : mA(a), mB(b), mOp(op) {}

    double at(const Coord& p)
    {
        auto& r = mRec.local();
        if (!r.first) {
            r.first.reset(new Reconstruction(mA.grid()->tree(), mA.indexDomain()));
            r.second.reset(new Reconstruction(mB.grid()->tree(), mB.indexDomain()));
        }
        const Vec3d q(p.x(), p.y(), p.z());
        return applyOp(mOp, r.first->distanceIndex(q, nullptr, nullptr), r.second->distanceIndex(q, nullptr, nullptr));
    }
    void leafSamples(size_t, FloatLeaf& leaf, const uint8_t* isFree, float* out) override
    {
        for (int off = 0; off < 512; ++off)
            if (isFree[off]) out[off] = float(at(leaf.offsetToGlobalCoord(openvdb::Index(off))));
    }
    double tileSample(const Coord& p) override { return at(p); }

private:
    const AdaptiveDistanceField& mA;
    const AdaptiveDistanceField& mB;
    CsgOperation mOp;
    tbb::enumerable_thread_specific<std::pair<std::unique_ptr<Reconstruction>, std::unique_ptr<Reconstruction>>> mRec;
};

void addLayoutOf(Layout& layout, const AdaptiveDistanceField& f)
{
    const FloatTree& tree = f.grid()->tree();
    const CoordBBox dom = f.indexDomain();
    for (auto it = tree.cbeginLeaf(); it; ++it) {
        layout.leafOrigins.push_back(it->origin());
        layout.leafMasks.push_back(it->getValueMask());
    }
    std::vector<const Internal1*> nodes;
    tree.getNodes(nodes);
    for (const Internal1* n : nodes)
        if (inDomainCell(dom, n->origin())) layout.subdividedL2.push_back(n->origin());
}

} // namespace

AdaptiveDistanceField csgAdaptiveDistanceFields(const AdaptiveDistanceField& a, const AdaptiveDistanceField& b, CsgOperation op)
{
    if (!a.valid() || !b.valid()) throw InvalidArgumentError("CSG of ADFs: empty ADF");
    if (a.grid()->transform() != b.grid()->transform())
        throw InvalidArgumentError("CSG of ADFs: the two grids have different transforms (voxel sizes " +
                                   std::to_string(a.voxelSize()) + " and " + std::to_string(b.voxelSize()) +
                                   "); convert both with the same voxel size");
    Layout layout;
    CoordBBox dom = a.indexDomain();
    dom.expand(b.indexDomain());
    layout.domain = dom;
    addLayoutOf(layout, a);
    addLayoutOf(layout, b);
    layout.finish();
    const float bg = std::max(a.grid()->background(), b.grid()->background());
    FloatTree::Ptr tree = createTree(layout, bg);
    CsgProvider provider(a, b, op);
    fillValues(*tree, layout, provider, nullptr);
    std::array<double, kAdfLevels> bounds{{-1, -1, -1, -1, -1}};
    double worst = -1;
    for (int l = 0; l < kAdfLevels; ++l) worst = std::max({worst, a.levelBoundVoxels(l), b.levelBoundVoxels(l)});
    for (int l = 0; l < kAdfLevels; ++l) bounds[size_t(l)] = worst;
    auto grid = openvdb::FloatGrid::create(tree);
    grid->setTransform(a.grid()->transform().copy());
    grid->setName(a.grid()->getName());
    stampAdfMetadata(*grid, layout.domain, bounds);
    grid->insertMeta(meta::kMethod, openvdb::StringMetadata(std::string("yin2011-adf-csg-") + csgOperationName(op)));
    return AdaptiveDistanceField(grid);
}

} // namespace levelforge
