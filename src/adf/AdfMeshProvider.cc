// SPDX-License-Identifier: Apache-2.0
// The mesh provider of the ADF builder (see AdfMeshProvider.h): construction, the type-3 samples
// of the tile corners (Yin et al. 2011 §7.2) and the signs from the flood-filled type-1 band.
#include "adf/AdfMeshProvider.h"

#include "detail/Timer.h"

#include <openvdb/tools/SignedFloodFill.h>

#include <algorithm>
#include <cmath>
#include <memory>

namespace levelforge {
namespace adf_internal {

MeshProvider::MeshProvider(const TriangleMesh& mesh, const std::vector<Vec3d>& cellPts, const TriangleListTree& lists,
                           const PseudoNormals& normals, double h)
    : mMesh(mesh), mPts(cellPts), mLists(lists), mNormals(normals), mH(h), mBvh(lists.tree()),
      mLattice(kGather, 0, kRegion), mReal(kGather, 1, kRegion)
{
}

MeshProvider::~MeshProvider() = default;

void MeshProvider::setDomain(const CoordBBox& domain)
{
    if (mEdtBuilt && domain == mEdtDomain) return;
    mEdtDomain = domain;
    mEdtBuilt = false;
}

void MeshProvider::afterLeaves(FloatTree& adfTree)
{
    const auto t0 = detail::Clock::now();
    if (!mEdtBuilt) {
        mEdt.build(mLists.tree(), mEdtDomain);
        mEdtBuilt = true;
    }
    mType1 = std::make_shared<FloatTree>(1e30f);
    std::vector<std::unique_ptr<FloatLeaf>> all;
    size_t count = 0;
    for (auto& v : mType1Leaves) count += v.size();
    all.reserve(count);
    for (auto& v : mType1Leaves)
        for (auto& l : v) all.push_back(std::move(l));
    mType1Leaves.clear();
    std::sort(all.begin(), all.end(), [](const std::unique_ptr<FloatLeaf>& a, const std::unique_ptr<FloatLeaf>& b) {
        return a->origin() < b->origin();
    });
    // owned here until the tree has it (addLeaf may fail allocating the nodes above it)
    for (auto& l : all) {
        mType1->addLeaf(l.get());
        l.release();
    }
    openvdb::tools::signedFloodFill(*mType1);
    mT1Acc.clear();
    fixDeferred(adfTree);
    secondsSignFill = detail::secondsSince(t0);
}

void MeshProvider::fixDeferred(FloatTree& adfTree)
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

double MeshProvider::tileSample(const Coord& p)
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

} // namespace adf_internal
} // namespace levelforge
