// SPDX-License-Identifier: Apache-2.0
// Resampling onto another transform: exact rebuild of level sets, OpenVDB's resampleToMatch for
// everything else. See levelset/ResampleGrid.h.
#include <levelforge/levelset/ResampleGrid.h>

#include <levelforge/core/Exceptions.h>
#include <levelforge/core/Metadata.h>

#include <openvdb/tools/GridTransformer.h>
#include <openvdb/tools/Interpolation.h>

#include <cmath>

namespace levelforge {

ResampleOrder resampleOrderFromString(const std::string& name)
{
    if (name == "point") return ResampleOrder::Point;
    if (name == "linear") return ResampleOrder::Linear;
    if (name == "quadratic") return ResampleOrder::Quadratic;
    throw InvalidArgumentError("unknown interpolation order '" + name + "' (point, linear, quadratic)");
}

bool isResamplable(const openvdb::GridBase& grid)
{
    return grid.isType<openvdb::FloatGrid>() || grid.isType<openvdb::DoubleGrid>() ||
           grid.isType<openvdb::Vec3SGrid>() || grid.isType<openvdb::Vec3DGrid>();
}

namespace {

/// Remembers whether the caller's interrupter asked to stop.
struct Poller : openvdb::util::NullInterrupter
{
    openvdb::util::NullInterrupter* user = nullptr;
    bool stopped = false;
    bool wasInterrupted(int percent = -1) override
    {
        if (user && !stopped) stopped = user->wasInterrupted(percent);
        return stopped;
    }
};

template<typename GridT>
openvdb::GridBase::Ptr interpolate(const GridT& in, const openvdb::math::Transform& target,
                                   const ResampleGridOptions& options)
{
    // a shallow copy of class GRID_UNKNOWN: resampleToMatch would rebuild a level set itself
    // (copyGrid() shares the tree and copies the metadata: the new Grid object is ours to change)
    typename GridT::Ptr view = std::const_pointer_cast<GridT>(openvdb::gridConstPtrCast<GridT>(in.copyGrid()));
    view->setGridClass(openvdb::GRID_UNKNOWN);
    typename GridT::Ptr out = GridT::create(in.background());
    out->setTransform(target.copy());
    Poller poller;
    poller.user = options.interrupter;
    switch (options.order) {
    case ResampleOrder::Point: openvdb::tools::resampleToMatch<openvdb::tools::PointSampler>(*view, *out, poller); break;
    case ResampleOrder::Linear: openvdb::tools::resampleToMatch<openvdb::tools::BoxSampler>(*view, *out, poller); break;
    case ResampleOrder::Quadratic:
        openvdb::tools::resampleToMatch<openvdb::tools::QuadraticSampler>(*view, *out, poller);
        break;
    }
    if (poller.stopped) throw InterruptedError("resample: interrupted");
    for (auto it = in.beginMeta(); it != in.endMeta(); ++it) {
        if (it->first.rfind("file_", 0) == 0) continue;
        out->insertMeta(it->first, *it->second);
    }
    out->setName(in.getName());
    out->setGridClass(in.getGridClass());
    return out;
}

const char* orderName(ResampleOrder order)
{
    switch (order) {
    case ResampleOrder::Point: return "point";
    case ResampleOrder::Linear: return "linear";
    case ResampleOrder::Quadratic: return "quadratic";
    }
    return "?";
}

} // namespace

openvdb::GridBase::Ptr resampleGrid(const openvdb::GridBase& grid, const openvdb::math::Transform& target,
                                    const ResampleGridOptions& options, std::string* how)
{
    if (!isResamplable(grid)) {
        throw InvalidArgumentError("resample: grid '" + grid.getName() + "' is of type " + grid.valueType() +
                                   "; only float, double, vec3s and vec3d grids can be resampled");
    }
    if (grid.transform() == target) {
        if (how) *how = "copied (same transform)";
        return grid.deepCopyGrid();
    }
    const auto* ls = dynamic_cast<const openvdb::FloatGrid*>(&grid);
    if (ls && ls->getGridClass() == openvdb::GRID_LEVEL_SET && options.levelSets == LevelSetResample::Rebuild) {
        if (!ls->hasUniformVoxels())
            throw InvalidArgumentError("resample: level set '" + ls->getName() + "' has non-uniform voxels");
        const double h = ls->voxelSize()[0];
        RebuildLevelSetOptions ro;
        ro.isoValue = 0.0;
        ro.inside = RebuildInside::Below;
        ro.exteriorWidth = std::abs(double(ls->background())) / h;
        ro.interiorWidth = ro.exteriorWidth;
        if (const auto m = ls->getMetadata<openvdb::FloatMetadata>(meta::kInteriorBandVoxels))
            if (std::isfinite(m->value()) && m->value() > 0.0f) ro.interiorWidth = m->value();
        ro.transform = target.copy();
        ro.maxVoxels = options.maxVoxels;
        ro.interrupter = options.interrupter;
        if (how) *how = "rebuilt";
        return rebuildLevelSet(*ls, ro);
    }
    if (how) *how = std::string("interpolated (") + orderName(options.order) + ")";
    if (const auto* g = dynamic_cast<const openvdb::FloatGrid*>(&grid)) return interpolate(*g, target, options);
    if (const auto* g = dynamic_cast<const openvdb::DoubleGrid*>(&grid)) return interpolate(*g, target, options);
    if (const auto* g = dynamic_cast<const openvdb::Vec3SGrid*>(&grid)) return interpolate(*g, target, options);
    return interpolate(dynamic_cast<const openvdb::Vec3DGrid&>(grid), target, options);
}

} // namespace levelforge
