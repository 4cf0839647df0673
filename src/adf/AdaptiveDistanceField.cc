// SPDX-License-Identifier: Apache-2.0
// Adaptively sampled distance fields on the VDB tile hierarchy (Yin, Liu, Wu 2011): the public
// class (queries on the reconstruction) and the ADF test. See AdaptiveDistanceField.h for the
// design; the builder is in AdfMeshBuilder.cc, CSG in AdfCsg.cc, the level-set conversion in
// AdfToLevelSet.cc.
#include "adf/AdfInternal.h"

#include <levelforge/core/Exceptions.h>
#include <levelforge/core/Metadata.h>

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <string>
#include <vector>

namespace levelforge {

using namespace adf_internal;

namespace {

/// Index coordinates of an ADF stay within +-2^30 (the builder refuses more), so that a cell's
/// far corner (origin + 128) and the storage layer past the domain never overflow an int.
constexpr int64_t kMaxDomainCoord = int64_t(1) << 30;

std::string coordText(const Coord& c)
{
    return "(" + std::to_string(c.x()) + ", " + std::to_string(c.y()) + ", " + std::to_string(c.z()) + ")";
}

std::string boxText(const CoordBBox& b)
{
    return coordText(b.min()) + " - " + coordText(b.max());
}

/// Whether 128³ block origin b lies in the blocks of the lattice [lo, hi] (the domain's blocks and
/// the storage layer past its maximum faces).
inline bool inLatticeBlocks(const CoordBBox& dom, const Coord& b)
{
    for (int k = 0; k < 3; ++k)
        if (b[k] < dom.min()[k] || b[k] > dom.max()[k]) return false;
    return true;
}

/// The layout rules of AdaptiveDistanceField.h (Layout::finish() builds them), checked once per
/// node: leaves lie in the domain; internal-1 nodes (subdivided 128³ blocks) lie in the domain or
/// the storage layer past its maximum faces; a block holding a leaf has all its 26 neighbours
/// in the lattice subdivided (grading: a leaf never touches a 128³ cell), and a subdivided block
/// of the domain has its neighbours on the storage layer subdivided (the corners of its 8³
/// cells on the maximum faces are stored there). Linear in the number of nodes (a neighbour
/// test is one probe of the tree). Queries terminate on any tree (AdfReconstruction.cc); this
/// refuses trees that are not an ADF layout, whose values would not be the documented
/// reconstruction. Tiles are not checked: a collapsed (pruned) 128³ block without leaves is a
/// level-2 tile of the same value.
void checkLayout(const openvdb::FloatGrid& grid, const CoordBBox& dom)
{
    const FloatTree& tree = grid.tree();
    const std::string name = "ADF grid '" + grid.getName() + "': ";
    const std::string notLayout = " (the tree is not an ADF layout)";
    openvdb::tree::ValueAccessor<const FloatTree, false> acc(tree);
    std::vector<const Internal1*> nodes;
    tree.getNodes(nodes);
    for (const Internal1* n : nodes) {
        const Coord b = n->origin();
        if (!inLatticeBlocks(dom, b))
            throw InvalidArgumentError(name + "subdivided 128^3 block at " + coordText(b) + " lies outside the domain " +
                                       boxText(dom) + " and its storage layer" + notLayout);
        const bool holdsLeaf = !n->getChildMask().isOff();
        const bool inDomain = inDomainCell(dom, b);
        if (!holdsLeaf && !inDomain) continue;
        for (int dx = -1; dx <= 1; ++dx)
            for (int dy = -1; dy <= 1; ++dy)
                for (int dz = -1; dz <= 1; ++dz) {
                    if (!dx && !dy && !dz) continue;
                    const Coord nb = b + Coord(dx * 128, dy * 128, dz * 128);
                    if (!inLatticeBlocks(dom, nb)) continue;
                    // a leaf's neighbours all; a subdivided block's neighbours on the storage layer
                    if (!holdsLeaf && inDomainCell(dom, nb)) continue;
                    if (!acc.template probeConstNode<Internal1>(nb)) {
                        throw InvalidArgumentError(name + "128^3 block at " + coordText(nb) + " is not subdivided, but its " +
                                                   "neighbour at " + coordText(b) + (holdsLeaf ? " holds 8^3 leaves" : " is") +
                                                   notLayout);
                    }
                }
    }
    for (auto it = tree.cbeginLeaf(); it; ++it) {
        const Coord o = it->origin();
        if (!inDomainCell(dom, o))
            throw InvalidArgumentError(name + "leaf at " + coordText(o) + " lies outside the domain " + boxText(dom) + notLayout);
    }
}

} // namespace

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
        if (std::abs(int64_t(mDomain.min()[k])) > kMaxDomainCoord || std::abs(int64_t(mDomain.max()[k])) > kMaxDomainCoord)
            throw InvalidArgumentError("ADF grid '" + grid->getName() + "': domain " + boxText(mDomain) +
                                       " reaches beyond +-2^30 (index space)");
    for (int k = 0; k < 3; ++k)
        if (mDomain.min()[k] % 128 || mDomain.max()[k] % 128 || mDomain.max()[k] <= mDomain.min()[k])
            throw InvalidArgumentError("ADF grid '" + grid->getName() + "': domain is not made of whole 128^3 blocks");
    if (!grid->hasUniformVoxels() || !grid->transform().isLinear())
        throw InvalidArgumentError("ADF grid '" + grid->getName() + "': transform must be linear with cubic voxels");
    mH = grid->voxelSize()[0];
    if (!std::isfinite(mH) || !(mH > 0.0))
        throw InvalidArgumentError("ADF grid '" + grid->getName() + "': voxel size " + std::to_string(mH) +
                                   " is not a positive number");
    checkLayout(*grid, mDomain);
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
