// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Fuzz target adf: an ADF read back from a .vdb file. readGrids() reads the file; every
///        FloatGrid in it is wrapped as an AdaptiveDistanceField (whose constructor validates the
///        meta::kAdf metadata, the domain and the transform) and, when accepted, queried a little:
///        distance, gradient and level at the domain's centre, corners and outside it, lattice
///        values at its corners, the stated bounds.
///
/// Checks: a grid the constructor accepts is one isAdaptiveDistanceField() recognises, and a
/// query point outside the domain has level -1.
#include "FuzzCommon.h"

#include <levelforge/adf/AdaptiveDistanceField.h>
#include <levelforge/io/VdbIO.h>

#include <iterator>

LF_FUZZ_TARGET(adf)
{
    using namespace levelforge;
    fuzz::TempFile file(data, size, ".vdb");
    return fuzz::runGuarded([&] {
        const openvdb::GridPtrVecPtr grids = readGrids(file.path());
        for (const openvdb::GridBase::Ptr& base : *grids) {
            const openvdb::FloatGrid::Ptr grid = openvdb::gridPtrCast<openvdb::FloatGrid>(base);
            if (!grid) continue;
            AdaptiveDistanceField adf;
            try {
                adf = AdaptiveDistanceField(grid);
            } catch (const InvalidArgumentError&) {
                continue; // not an ADF, or its metadata is inconsistent: refused as documented
            }
            if (!isAdaptiveDistanceField(*grid)) fuzz::finding("AdaptiveDistanceField accepted a grid that isAdaptiveDistanceField() refuses");
            const openvdb::CoordBBox& domain = adf.indexDomain();
            const openvdb::Vec3d lo = domain.min().asVec3d(), hi = domain.max().asVec3d();
            const openvdb::Vec3d indexPoints[] = {
                (lo + hi) * 0.5, lo, hi, lo + openvdb::Vec3d(0.25, 0.5, 0.75), hi - openvdb::Vec3d(0.5),
                lo - openvdb::Vec3d(3.0), hi + openvdb::Vec3d(0.5, 2.0, 0.0)};
            constexpr size_t kFirstOutside = 5; // indexPoints[5..] lie outside the domain
            double sum = adf.voxelSize();
            for (size_t i = 0; i < std::size(indexPoints); ++i) {
                const openvdb::Vec3d w = grid->indexToWorld(indexPoints[i]);
                sum += adf.distance(w);
                sum += adf.gradient(w).length();
                const int level = adf.level(w);
                if (level < -1 || level >= kAdfLevels) fuzz::finding("AdaptiveDistanceField::level returned " + std::to_string(level));
                if (i >= kFirstOutside && level != -1) {
                    const openvdb::Vec3d q = grid->worldToIndex(w); // outside after the round trip too?
                    bool outside = false;
                    for (int k = 0; k < 3; ++k) outside |= q[k] < lo[k] || q[k] > hi[k];
                    if (outside) fuzz::finding("AdaptiveDistanceField::level is " + std::to_string(level) + " outside the domain");
                }
            }
            auto middle = [](int a, int b) { return int((int64_t(a) + int64_t(b)) / 2); };
            const openvdb::Coord centre(middle(domain.min().x(), domain.max().x()),
                                        middle(domain.min().y(), domain.max().y()),
                                        middle(domain.min().z(), domain.max().z()));
            const openvdb::Coord corners[] = {domain.min(), domain.max(), centre,
                                              openvdb::Coord(domain.min().x(), domain.max().y(), domain.min().z())};
            for (const openvdb::Coord& c : corners) sum += adf.latticeValue(c);
            for (int l = 0; l < kAdfLevels; ++l) sum += adf.levelBoundVoxels(l);
            const openvdb::BBoxd world = adf.worldDomain();
            sum += world.min()[0];
            // keep the results alive (the values themselves are whatever the file holds)
            volatile double sink = sum;
            (void)sink;
        }
    });
}
