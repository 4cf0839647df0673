// SPDX-License-Identifier: Apache-2.0
// Adaptively sampled distance fields on the VDB tile hierarchy (Yin, Liu, Wu 2011): the public
// class (queries on the reconstruction) and the ADF test. See AdaptiveDistanceField.h for the
// design; the builder is in AdfMeshBuilder.cc, CSG in AdfCsg.cc, the level-set conversion in
// AdfToLevelSet.cc.
#include "adf/AdfInternal.h"

#include <levelforge/core/Exceptions.h>
#include <levelforge/core/Metadata.h>

namespace levelforge {

using namespace adf_internal;

AdaptiveDistanceField::AdaptiveDistanceField(openvdb::FloatGrid::ConstPtr grid)
{
    if (!grid) throw InvalidArgumentError("ADF: null grid");
    if (!isAdaptiveDistanceField(*grid))
        throw InvalidArgumentError("grid '" + grid->getName() + "' is not a levelforge ADF (no \"" + meta::kAdf + "\" metadata)");
    const auto lo = grid->getMetadata<openvdb::Vec3IMetadata>(meta::kAdfDomainMin);
    const auto hi = grid->getMetadata<openvdb::Vec3IMetadata>(meta::kAdfDomainMax);
    if (!lo || !hi) throw InvalidArgumentError("ADF grid '" + grid->getName() + "': missing domain metadata");
    mDomain = CoordBBox(Coord(lo->value()), Coord(hi->value()));
    for (int k = 0; k < 3; ++k)
        if (mDomain.min()[k] % 128 || mDomain.max()[k] % 128 || mDomain.max()[k] <= mDomain.min()[k])
            throw InvalidArgumentError("ADF grid '" + grid->getName() + "': domain is not made of whole 128^3 blocks");
    if (!grid->hasUniformVoxels() || !grid->transform().isLinear())
        throw InvalidArgumentError("ADF grid '" + grid->getName() + "': transform must be linear with cubic voxels");
    mH = grid->voxelSize()[0];
    for (int l = 0; l < kAdfLevels; ++l)
        if (const auto m = grid->getMetadata<openvdb::DoubleMetadata>(boundLevelKey(l))) mBounds[size_t(l)] = m->value();
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
    return bool(grid.getMetadata<openvdb::StringMetadata>(meta::kAdf)) && grid.isType<openvdb::FloatGrid>();
}

} // namespace levelforge
