// SPDX-License-Identifier: Apache-2.0
// Expansion completeness against the exact reference: docs/cli.md ("activates every voxel whose
// distance is within the new widths (Euclidean-complete)") and src/expand say that after an
// expansion (--expansion sweep / vector, meshToSdf with Expansion::Sweep / Expansion::Vector)
// every voxel with |d| < w is active. Checked here voxel by voxel, with the exact signed distance
// of ExactReference (not the expansion's own values): every voxel with |d| < w - 0.5 must be
// active and carry the right sign.
#include "TestUtil.h"

#include <levelforge/pipeline/MeshToSdf.h>
#include <levelforge/reference/ExactReference.h>
#include <levelforge/reference/MeshShapes.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

using namespace levelforge;

namespace {

/// Tolerance of the completeness claim, voxels: a voxel must be active when |d| < w - kMargin.
/// Half a voxel, so that a voxel whose centre lies just inside the width on a voxel-quantised
/// band edge is not demanded; the claim itself ("every voxel with d < w") is stronger.
constexpr double kMargin = 0.5;
/// Below this |d| (voxels) the sign is not checked (the surface passes through the centre).
constexpr double kSignTolerance = 1e-6;

struct Counts
{
    uint64_t required = 0;  ///< voxels with |d| < w - kMargin
    uint64_t missing = 0;   ///< ... that are inactive
    uint64_t wrongSign = 0; ///< ... active (or not) whose value has the wrong sign
    double worstMissing = -1; ///< the smallest |d| (voxels) of a missing voxel (-1: none)
};

} // namespace

TEST(ExpansionCompleteness, EveryVoxelWithinTheWidthIsActiveWithTheRightSign)
{
    const auto start = std::chrono::steady_clock::now();
    struct Shape
    {
        const char* name;
        TriangleMesh mesh;
    };
    const Shape shapes[] = {{"torus knot", makeTorusKnot(2, 3, 1.0, 0.25, 128, 16)},
                            {"icosphere", makeIcosphere(Vec3d(0.05, -0.1, 0.02), 1.0, 3)},
                            {"box", makeBox(Vec3d(-0.9, -0.5, -0.7), Vec3d(0.8, 0.6, 0.55))}};
    const double widths[] = {6.0, 12.0};
    const int kVoxelCount = 40; // voxels along the longest side of the mesh box
    uint64_t totalRequired = 0, totalMissing = 0, totalWrongSign = 0;
    for (const Shape& shape : shapes) {
        const ExactReference ref(shape.mesh);
        const BBoxd box = shape.mesh.bounds();
        const double h = box.extents()[box.maxExtent()] / kVoxelCount;
        // exact distances (voxels) of every voxel of the mesh box grown by the largest width + 2
        const int pad = int(std::ceil(widths[1])) + 2;
        const openvdb::Coord lo(int(std::floor(box.min()[0] / h)) - pad, int(std::floor(box.min()[1] / h)) - pad,
                                int(std::floor(box.min()[2] / h)) - pad);
        const openvdb::Coord hi(int(std::ceil(box.max()[0] / h)) + pad, int(std::ceil(box.max()[1] / h)) + pad,
                                int(std::ceil(box.max()[2] / h)) + pad);
        const openvdb::CoordBBox region(lo, hi);
        std::vector<openvdb::Coord> coords;
        std::vector<double> exact;
        for (auto it = region.begin(); it; ++it) {
            const openvdb::Coord ijk = *it;
            const double d = ref.signedDistance(Vec3d(ijk.x(), ijk.y(), ijk.z()) * h) / h;
            if (std::abs(d) < widths[1]) {
                coords.push_back(ijk);
                exact.push_back(d);
            }
        }
        for (Expansion method : {Expansion::Sweep, Expansion::Vector}) {
            for (double w : widths) {
                MeshToSdfOptions opt;
                opt.voxelSize = h;
                opt.exteriorWidth = w;
                opt.interiorWidth = w;
                opt.expansion = method;
                const openvdb::FloatGrid::Ptr grid = meshToSdf(shape.mesh, opt);
                ASSERT_NEAR(grid->voxelSize()[0], h, 1e-12 * h);
                const auto acc = grid->getConstAccessor();
                Counts c;
                for (size_t i = 0; i < coords.size(); ++i) {
                    const double d = exact[i];
                    if (std::abs(d) >= w - kMargin) continue;
                    ++c.required;
                    const bool on = acc.isValueOn(coords[i]);
                    const float v = acc.getValue(coords[i]);
                    if (!on) {
                        ++c.missing;
                        if (c.worstMissing < 0 || std::abs(d) < c.worstMissing) c.worstMissing = std::abs(d);
                    }
                    if (std::abs(d) > kSignTolerance && (v < 0) != (d < 0)) ++c.wrongSign;
                }
                const std::string what = std::string(shape.name) + (method == Expansion::Sweep ? " sweep" : " vector") +
                                         " w=" + std::to_string(int(w));
                std::printf("  %-24s %8llu voxels with |d| < %.1f: %llu inactive (nearest at |d| = %.3f voxels), %llu wrong "
                            "sign; %llu active\n",
                            what.c_str(), (unsigned long long)c.required, w - kMargin, (unsigned long long)c.missing,
                            c.worstMissing, (unsigned long long)c.wrongSign, (unsigned long long)grid->activeVoxelCount());
                EXPECT_GT(c.required, 1000u) << what;
                EXPECT_EQ(c.missing, 0u) << what << ": voxels with |d| < w - " << kMargin << " left inactive (nearest at |d| = "
                                         << c.worstMissing << " voxels)";
                EXPECT_EQ(c.wrongSign, 0u) << what;
                totalRequired += c.required;
                totalMissing += c.missing;
                totalWrongSign += c.wrongSign;
            }
        }
    }
    RecordProperty("required_voxels", std::to_string(totalRequired));
    RecordProperty("missing_voxels", std::to_string(totalMissing));
    RecordProperty("wrong_sign_voxels", std::to_string(totalWrongSign));
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    std::printf("  total: %llu required voxels, %llu inactive, %llu wrong sign (%.2f s)\n", (unsigned long long)totalRequired,
                (unsigned long long)totalMissing, (unsigned long long)totalWrongSign, seconds);
}
