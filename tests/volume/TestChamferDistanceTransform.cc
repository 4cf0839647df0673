// SPDX-License-Identifier: Apache-2.0
// Tests for ChamferDistanceTransform.h and VolumeFeatures.h: feature voxels (Eq. 2, 3, 5, 6) on
// hand-checked cases, every chamfer metric against Dijkstra on its own weighted neighbourhood
// graph (isotropic and anisotropic), city-block against the analytic L1 metric, determinism, bad
// inputs.
#include <levelforge/volume/ChamferDistanceTransform.h>

#include <levelforge/core/Exceptions.h>
#include <levelforge/volume/VolumeFeatures.h>

#include "TestUtil.h"
#include "volume/ChamferDistanceTransformInternal.h" // neighbourhood(), stepWeight()

#include <gtest/gtest.h>

#include <tbb/global_control.h>
#include <tbb/task_arena.h>

#include <cmath>
#include <limits>
#include <queue>
#include <cstring>
#include <random>

using namespace levelforge;

namespace {

constexpr ChamferMetric kMetrics[] = {ChamferMetric::CityBlock, ChamferMetric::Chessboard,
                                      ChamferMetric::QuasiEuclidean3, ChamferMetric::Complete3,
                                      ChamferMetric::QuasiEuclidean5};

using levelforge_test::randomMask;

/// Multi-source Dijkstra on the metric's neighbourhood graph (double precision).
std::vector<double> dijkstra(const MaskVolume& f, ChamferMetric metric)
{
    const auto steps = chamfer_internal::neighbourhood(metric);
    std::vector<double> w;
    for (const auto& s : steps) w.push_back(chamfer_internal::stepWeight(metric, s, f.spacing));
    std::vector<double> d(f.data.size(), std::numeric_limits<double>::infinity());
    using Item = std::pair<double, size_t>;
    std::priority_queue<Item, std::vector<Item>, std::greater<Item>> q;
    for (size_t i = 0; i < f.data.size(); ++i)
        if (f.data[i]) {
            d[i] = 0;
            q.push({0.0, i});
        }
    const int nx = f.dims.x(), ny = f.dims.y();
    while (!q.empty()) {
        const auto [dist, idx] = q.top();
        q.pop();
        if (dist > d[idx]) continue;
        const int i = int(idx % nx), j = int((idx / nx) % ny), k = int(idx / (size_t(nx) * ny));
        for (size_t s = 0; s < steps.size(); ++s) {
            const int a = i + steps[s].x, b = j + steps[s].y, c = k + steps[s].z;
            if (!f.inside(a, b, c)) continue;
            const size_t n = f.index(a, b, c);
            if (dist + w[s] < d[n]) {
                d[n] = dist + w[s];
                q.push({d[n], n});
            }
        }
    }
    return d;
}

} // namespace

TEST(ChamferDistanceTransform, InsideMaskAndTransverseFeatures)
{
    ScalarVolume f(openvdb::Coord(7), 0.0f);
    for (int k = 2; k <= 4; ++k)
        for (int j = 2; j <= 4; ++j)
            for (int i = 2; i <= 4; ++i) f(i, j, k) = 1.0f;
    f(0, 0, 0) = 0.5f; // exactly at the threshold: inside (Eq. 2 is f >= iso)
    const MaskVolume inside = insideMask(f, 0.5f);
    EXPECT_EQ(inside(0, 0, 0), 1);
    EXPECT_EQ(inside(3, 3, 3), 1);
    EXPECT_EQ(inside(1, 3, 3), 0);
    const MaskVolume feat = transverseFeatures(inside);
    // The 3^3 block: its 26 outer voxels are transverse, the centre has all 26 neighbours
    // inside. The lone voxel at the corner has no inside neighbour: not transverse.
    int count = 0;
    for (auto v : feat.data) count += v;
    EXPECT_EQ(count, 26);
    EXPECT_EQ(feat(3, 3, 3), 0);
    EXPECT_EQ(feat(2, 2, 2), 1);
    EXPECT_EQ(feat(0, 0, 0), 0);
    const DenseVolume<int8_t> c = classification(inside, feat);
    EXPECT_EQ(c(3, 3, 3), -1);
    EXPECT_EQ(c(2, 3, 4), 0);
    EXPECT_EQ(c(5, 5, 5), 1);
    EXPECT_EQ(c(0, 0, 0), 1); // inside but neither transverse nor interior (Eq. 5: otherwise)
}

TEST(ChamferDistanceTransform, VolumeBorderCountsAsOutside)
{
    const MaskVolume inside(openvdb::Coord(4, 5, 6), 1);
    const MaskVolume feat = transverseFeatures(inside);
    const DenseVolume<int8_t> c = classification(inside, feat);
    for (int k = 0; k < 6; ++k)
        for (int j = 0; j < 5; ++j)
            for (int i = 0; i < 4; ++i) {
                const bool border = i == 0 || j == 0 || k == 0 || i == 3 || j == 4 || k == 5;
                EXPECT_EQ(feat(i, j, k), border ? 1 : 0);
                EXPECT_EQ(c(i, j, k), border ? 0 : -1);
            }
}

TEST(ChamferDistanceTransform, ApplySign)
{
    ScalarVolume d(openvdb::Coord(3, 1, 1), 2.0f);
    DenseVolume<int8_t> s(openvdb::Coord(3, 1, 1), 1);
    s.data = {-1, 0, 1};
    d.data[1] = std::numeric_limits<float>::infinity(); // a 0 class is 0 whatever the distance
    const ScalarVolume r = applySign(d, s);
    EXPECT_EQ(r.data[0], -2.0f);
    EXPECT_EQ(r.data[1], 0.0f);
    EXPECT_EQ(r.data[2], 2.0f);
    DenseVolume<int8_t> wrong(openvdb::Coord(2, 1, 1), 1);
    EXPECT_THROW(applySign(d, wrong), InvalidArgumentError);
}

TEST(ChamferDistanceTransform, NeighbourhoodSizes)
{
    EXPECT_EQ(chamfer_internal::neighbourhood(ChamferMetric::CityBlock).size(), 6u);
    EXPECT_EQ(chamfer_internal::neighbourhood(ChamferMetric::Chessboard).size(), 18u);
    EXPECT_EQ(chamfer_internal::neighbourhood(ChamferMetric::QuasiEuclidean3).size(), 18u);
    EXPECT_EQ(chamfer_internal::neighbourhood(ChamferMetric::Complete3).size(), 26u);
    EXPECT_EQ(chamfer_internal::neighbourhood(ChamferMetric::QuasiEuclidean5).size(), 98u);
    const openvdb::Vec3d s(1.0, 2.0, 3.0);
    EXPECT_DOUBLE_EQ(chamfer_internal::stepWeight(ChamferMetric::Chessboard, {1, 1, 0}, s), 2.0);
    EXPECT_DOUBLE_EQ(chamfer_internal::stepWeight(ChamferMetric::QuasiEuclidean3, {1, 1, 0}, s), std::sqrt(5.0));
    EXPECT_DOUBLE_EQ(chamfer_internal::stepWeight(ChamferMetric::QuasiEuclidean5, {2, -1, 1}, s),
                     std::sqrt(4.0 + 4.0 + 9.0));
}

TEST(ChamferDistanceTransform, EqualsDijkstraOnMaskGraph)
{
    for (const openvdb::Vec3d& spacing : {openvdb::Vec3d(1.0), openvdb::Vec3d(1.0, 1.0, 2.5), openvdb::Vec3d(0.7, 1.3, 1.0)}) {
        for (double density : {0.003, 0.05}) {
            const MaskVolume m = randomMask(openvdb::Coord(15, 13, 11), density, 11, spacing);
            for (ChamferMetric metric : kMetrics) {
                const ScalarVolume c = chamferDistanceTransform(m, metric);
                const std::vector<double> ref = dijkstra(m, metric);
                for (size_t i = 0; i < ref.size(); ++i) {
                    if (std::isinf(ref[i])) {
                        ASSERT_TRUE(std::isinf(c.data[i]));
                        continue;
                    }
                    ASSERT_NEAR(c.data[i], ref[i], 1e-5 * std::max(1.0, ref[i]))
                        << chamferMetricName(metric) << " voxel " << i << " spacing " << spacing;
                }
            }
        }
    }
}

TEST(ChamferDistanceTransform, CityBlockIsAnalyticL1)
{
    const openvdb::Vec3d s(0.5, 1.0, 2.5);
    const MaskVolume m = randomMask(openvdb::Coord(20, 12, 9), 0.004, 3, s);
    const ScalarVolume c = chamferDistanceTransform(m, ChamferMetric::CityBlock);
    std::vector<openvdb::Coord> feats;
    for (int k = 0; k < 9; ++k)
        for (int j = 0; j < 12; ++j)
            for (int i = 0; i < 20; ++i)
                if (m(i, j, k)) feats.emplace_back(i, j, k);
    ASSERT_FALSE(feats.empty());
    for (int k = 0; k < 9; ++k)
        for (int j = 0; j < 12; ++j)
            for (int i = 0; i < 20; ++i) {
                double best = 1e30;
                for (const auto& f : feats)
                    best = std::min(best, s[0] * std::abs(i - f.x()) + s[1] * std::abs(j - f.y()) + s[2] * std::abs(k - f.z()));
                ASSERT_NEAR(c(i, j, k), best, 1e-5 * std::max(1.0, best));
            }
}

TEST(ChamferDistanceTransform, BitIdenticalForAnyThreadCount)
{
    const MaskVolume m = randomMask(openvdb::Coord(70, 40, 12), 0.001, 5, openvdb::Vec3d(1.0, 1.2, 2.0));
    for (ChamferMetric metric : {ChamferMetric::Complete3, ChamferMetric::QuasiEuclidean5}) {
        ScalarVolume ref;
        {
            tbb::global_control serial(tbb::global_control::max_allowed_parallelism, 1);
            ChamferOptions automatic;
            automatic.threads = 0;
            ref = chamferDistanceTransform(m, metric, automatic);
        }
        for (int lanes : {2, 3, 5}) {
            tbb::global_control allow(tbb::global_control::max_allowed_parallelism, size_t(lanes));
            tbb::task_arena arena(lanes);
            ScalarVolume r;
            arena.execute([&] {
                ChamferOptions o;
                o.threads = lanes;
                r = chamferDistanceTransform(m, metric, o);
            });
            ASSERT_EQ(0, std::memcmp(r.data.data(), ref.data.data(), ref.data.size() * sizeof(float)))
                << chamferMetricName(metric) << " lanes " << lanes;
        }
    }
}

TEST(ChamferDistanceTransform, BadInputs)
{
    EXPECT_THROW(chamferDistanceTransform(MaskVolume(), ChamferMetric::CityBlock), InvalidArgumentError);
    MaskVolume m(openvdb::Coord(3), 1);
    m.spacing = openvdb::Vec3d(1, 1, 0);
    EXPECT_THROW(chamferDistanceTransform(m, ChamferMetric::Complete3), InvalidArgumentError);
    EXPECT_THROW(transverseFeatures(m), InvalidArgumentError);
    m.spacing = openvdb::Vec3d(1);
    m.data.resize(5);
    EXPECT_THROW(transverseFeatures(m), InvalidArgumentError);
    EXPECT_THROW(insideMask(ScalarVolume(openvdb::Coord(2), 0.0f), std::nanf("")), InvalidArgumentError);
    EXPECT_THROW(classification(MaskVolume(openvdb::Coord(2), 0), MaskVolume(openvdb::Coord(3), 0)),
                 InvalidArgumentError);
}

TEST(ChamferDistanceTransform, Interrupt)
{
    struct Stop : openvdb::util::NullInterrupter
    {
        bool wasInterrupted(int) override { return true; }
    } stop;
    ChamferOptions o;
    o.interrupter = &stop;
    EXPECT_THROW(chamferDistanceTransform(MaskVolume(openvdb::Coord(8), 1), ChamferMetric::CityBlock, o),
                 InterruptedError);
}
