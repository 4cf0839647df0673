// ADF → level set, and CSG of ADFs (Yin et al. Figure 10, Frisken & Perry) and of level sets.
// See AdaptiveDistanceField.h.
#include "adf/AdfInternal.h"

#include <levelforge/core/Exceptions.h>
#include <levelforge/io/VdbIO.h>

#include <openvdb/tools/Composite.h>
#include <openvdb/tools/SignedFloodFill.h>

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <memory>

namespace levelforge {

using namespace adf_internal;

namespace {

inline bool inDomainBlock(const CoordBBox& dom, const Coord& o)
{
    for (int k = 0; k < 3; ++k)
        if (o[k] < dom.min()[k] || o[k] >= dom.max()[k]) return false;
    return true;
}

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
        if (inDomainBlock(dom, n->origin())) layout.subdividedL2.push_back(n->origin());
}

} // namespace

CsgOperation csgOperationFromString(const std::string& name)
{
    if (name == "union") return CsgOperation::Union;
    if (name == "intersection") return CsgOperation::Intersection;
    if (name == "difference") return CsgOperation::Difference;
    throw InvalidArgumentError("unknown CSG operation '" + name + "' (expected union, intersection or difference)");
}

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
    static const char* names[] = {"union", "intersection", "difference"};
    grid->insertMeta("levelforge:method", openvdb::StringMetadata(std::string("yin2011-adf-csg-") + names[int(op)]));
    return AdaptiveDistanceField(grid);
}

openvdb::FloatGrid::Ptr csgLevelSets(const openvdb::FloatGrid& a, const openvdb::FloatGrid& b, CsgOperation op)
{
    if (a.transform() != b.transform())
        throw InvalidArgumentError("CSG of level sets '" + a.getName() + "' and '" + b.getName() +
                                   "': the grids have different transforms; resample one onto the other first");
    for (const openvdb::FloatGrid* g : {&a, &b})
        if (g->getGridClass() != openvdb::GRID_LEVEL_SET)
            throw InvalidArgumentError("CSG: grid '" + g->getName() + "' is not a level set (class " +
                                       openvdb::GridBase::gridClassToString(g->getGridClass()) + ")");
    openvdb::FloatGrid::Ptr out;
    switch (op) {
    case CsgOperation::Union: out = openvdb::tools::csgUnionCopy(a, b); break;
    case CsgOperation::Intersection: out = openvdb::tools::csgIntersectionCopy(a, b); break;
    case CsgOperation::Difference: out = openvdb::tools::csgDifferenceCopy(a, b); break;
    }
    out->setGridClass(openvdb::GRID_LEVEL_SET);
    out->setName(a.getName());
    return out;
}

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
        if (inDomainBlock(dom, it->origin())) cand.push_back(it->origin());
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
            if (!inDomainBlock(dom, n->origin())) continue;
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
                if (!inDomainBlock(dom, o)) continue;
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
    std::vector<FloatLeaf*> out(cand.size(), nullptr);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, cand.size(), 8), [&](const tbb::blocked_range<size_t>& r) {
        Reconstruction rec(tree, dom);
        for (size_t i = r.begin(); i != r.end(); ++i) {
            auto* leaf = new FloatLeaf(cand[i], bg, false);
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
            if (any) out[i] = leaf; else delete leaf;
        }
    });
    auto lsTree = std::make_shared<FloatTree>(bg);
    for (FloatLeaf* l : out)
        if (l) lsTree->addLeaf(l);
    openvdb::tools::signedFloodFill(*lsTree);
    auto grid = openvdb::FloatGrid::create(lsTree);
    grid->setTransform(adf.grid()->transform().copy());
    grid->setName(adf.grid()->getName() == "adf" ? "surface" : adf.grid()->getName());
    std::string source;
    if (const auto m = adf.grid()->getMetadata<openvdb::StringMetadata>("levelforge:source")) source = m->value();
    stampLevelSetMetadata(*grid, halfWidthVoxels, halfWidthVoxels, source, "yin2011-adf-resampled");
    return grid;
}

} // namespace levelforge
