// SPDX-License-Identifier: Apache-2.0
// Tests for ExactDistanceTransform.h: the linear-time EDT against brute force (isotropic and
// anisotropic), analytic values, the comparison columns, the report, bad inputs, interruption.
#include <levelforge/volume/ExactDistanceTransform.h>

#include <levelforge/core/Exceptions.h>

#include "TestUtil.h"

#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <limits>
#include <random>

using namespace levelforge;

namespace {

using levelforge_test::randomMask;

void expectNear(const ScalarVolume& a, const ScalarVolume& b, double relTol)
{
    ASSERT_EQ(a.dims, b.dims);
    for (size_t i = 0; i < a.data.size(); ++i) {
        if (std::isinf(b.data[i])) {
            ASSERT_TRUE(std::isinf(a.data[i])) << "voxel " << i;
            continue;
        }
        ASSERT_NEAR(a.data[i], b.data[i], relTol * std::max(1.0f, b.data[i])) << "voxel " << i;
    }
}

class CountingInterrupter : public openvdb::util::NullInterrupter
{
public:
    explicit CountingInterrupter(int stopAfter) : mStopAfter(stopAfter) {}
    bool wasInterrupted(int) override { return ++mCalls > mStopAfter; }
    std::atomic<int> mCalls{0}; // polled from TBB workers too
    int mStopAfter;
};

} // namespace

TEST(ExactDistanceTransform, MatchesBruteForceIsotropic)
{
    for (double density : {0.002, 0.02, 0.2}) {
        for (unsigned seed : {1u, 2u}) {
            const MaskVolume m = randomMask(openvdb::Coord(23, 17, 13), density, seed, openvdb::Vec3d(1.0));
            expectNear(exactDistanceTransform(m), bruteForceDistanceTransform(m), 2e-6);
        }
    }
}

TEST(ExactDistanceTransform, MatchesBruteForceAnisotropic)
{
    for (const openvdb::Vec3d& s : {openvdb::Vec3d(1.0, 1.0, 2.5), openvdb::Vec3d(0.3, 1.7, 0.9)}) {
        const MaskVolume m = randomMask(openvdb::Coord(19, 14, 16), 0.01, 7, s);
        const ScalarVolume e = exactDistanceTransform(m);
        expectNear(e, bruteForceDistanceTransform(m), 2e-6);
        EXPECT_EQ(e.spacing, s);
    }
}

TEST(ExactDistanceTransform, SingleFeatureIsAnalytic)
{
    MaskVolume m(openvdb::Coord(9, 8, 7), 0, openvdb::Vec3d(0.5, 2.0, 1.5), openvdb::Vec3d(3, 4, 5));
    m(2, 5, 3) = 1;
    const ScalarVolume e = exactDistanceTransform(m);
    EXPECT_EQ(e.origin, m.origin);
    for (int k = 0; k < 7; ++k)
        for (int j = 0; j < 8; ++j)
            for (int i = 0; i < 9; ++i) {
                const double d = std::sqrt(std::pow(0.5 * (i - 2), 2) + std::pow(2.0 * (j - 5), 2) + std::pow(1.5 * (k - 3), 2));
                EXPECT_NEAR(e(i, j, k), d, 1e-5 * std::max(1.0, d));
            }
}

TEST(ExactDistanceTransform, NoFeaturesIsInfinite)
{
    const MaskVolume m(openvdb::Coord(5, 4, 3), 0);
    for (float v : exactDistanceTransform(m).data) EXPECT_TRUE(std::isinf(v) && v > 0);
    for (float v : bruteForceDistanceTransform(m).data) EXPECT_TRUE(std::isinf(v) && v > 0);
}

TEST(ExactDistanceTransform, CompareColumns)
{
    ScalarVolume exact(openvdb::Coord(2, 2, 1), 0.0f), computed(openvdb::Coord(2, 2, 1), 0.0f);
    exact.data = {0.0f, -1.0f, 2.0f, std::numeric_limits<float>::infinity()};
    computed.data = {0.0f, -1.5f, 2.25f, std::numeric_limits<float>::infinity()};
    const DistanceTransformComparison c = compareDistanceFields(computed, exact);
    EXPECT_FLOAT_EQ(c.minDistance, -1.5f);
    EXPECT_TRUE(std::isinf(c.maxDistance));
    EXPECT_FLOAT_EQ(c.minError, -0.5f);
    EXPECT_FLOAT_EQ(c.maxError, 0.25f);
    EXPECT_DOUBLE_EQ(c.averageErrorPerVoxel, 0.75 / 4.0);
    EXPECT_EQ(c.voxelsWithError, 2u);
    ScalarVolume other(openvdb::Coord(2, 2, 2), 0.0f);
    EXPECT_THROW(compareDistanceFields(other, exact), InvalidArgumentError);
}

TEST(ExactDistanceTransform, ReportOnSmallSphere)
{
    const int n = 24;
    MaskVolume inside(openvdb::Coord(n), 0);
    for (int k = 0; k < n; ++k)
        for (int j = 0; j < n; ++j)
            for (int i = 0; i < n; ++i)
                inside(i, j, k) = (i - 11.5) * (i - 11.5) + (j - 11.5) * (j - 11.5) + (k - 11.5) * (k - 11.5) <= 64.0;
    const auto rows = distanceTransformReport(inside);
    ASSERT_EQ(rows.size(), 10u);
    EXPECT_EQ(rows[0].method, "Euclidean (exact EDT)");
    EXPECT_EQ(rows[0].averageErrorPerVoxel, 0.0);
    EXPECT_EQ(rows[0].voxelsWithError, 0u);
    EXPECT_LT(rows[0].minDistance, -4.0f); // signed: the interior is negative
    EXPECT_EQ(rows[1].method, "City-block");
    EXPECT_EQ(rows[9].method, "VCVDT8");
    // Table 1's ordering of the chamfer family holds: QE5 < complete < QE3 < city-block.
    EXPECT_LT(rows[5].averageErrorPerVoxel, rows[4].averageErrorPerVoxel);
    EXPECT_LT(rows[4].averageErrorPerVoxel, rows[3].averageErrorPerVoxel);
    EXPECT_LT(rows[3].averageErrorPerVoxel, rows[1].averageErrorPerVoxel);
    // Every vector method beats the best chamfer transform by far.
    for (int r = 6; r < 10; ++r) EXPECT_LT(rows[size_t(r)].averageErrorPerVoxel, 0.1 * rows[5].averageErrorPerVoxel) << rows[size_t(r)].method;
    // City-block never underestimates outside, so its largest error is positive.
    EXPECT_GT(rows[1].maxError, 1.0f);
}

TEST(ExactDistanceTransform, BadInputs)
{
    EXPECT_THROW(exactDistanceTransform(MaskVolume()), InvalidArgumentError);
    MaskVolume m(openvdb::Coord(4), 1);
    m.spacing = openvdb::Vec3d(1, 0, 1);
    EXPECT_THROW(exactDistanceTransform(m), InvalidArgumentError);
    m.spacing = openvdb::Vec3d(1, std::nan(""), 1);
    EXPECT_THROW(exactDistanceTransform(m), InvalidArgumentError);
    m.spacing = openvdb::Vec3d(-1, 1, 1);
    EXPECT_THROW(bruteForceDistanceTransform(m), InvalidArgumentError);
    m.spacing = openvdb::Vec3d(1);
    m.data.pop_back();
    EXPECT_THROW(exactDistanceTransform(m), InvalidArgumentError);
    EXPECT_THROW(distanceTransformReport(MaskVolume()), InvalidArgumentError);
}

TEST(ExactDistanceTransform, Interrupt)
{
    MaskVolume m(openvdb::Coord(16), 0);
    m(3, 4, 5) = 1;
    CountingInterrupter stop(0);
    ExactTransformOptions o;
    o.interrupter = &stop;
    EXPECT_THROW(exactDistanceTransform(m, o), InterruptedError);
    CountingInterrupter never(1 << 30);
    o.interrupter = &never;
    EXPECT_NO_THROW(exactDistanceTransform(m, o));
    EXPECT_GT(never.mCalls, 0);
}
