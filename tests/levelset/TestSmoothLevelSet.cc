// SPDX-License-Identifier: Apache-2.0
// smoothLevelSet() (mean, Gaussian, median, mean-curvature, Laplacian) against analytic shapes:
// a sphere shrinks by each filter's analytic amount, noise on a sphere is removed,
// the corners of a box are rounded while its faces stay put.
#include <levelforge/core/Exceptions.h>
#include <levelforge/levelset/SmoothLevelSet.h>
#include <levelforge/mesh/MeshToLevelSet.h>
#include <levelforge/reference/MeshShapes.h>

#include <openvdb/openvdb.h>
#include <openvdb/tools/LevelSetSphere.h>

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

using namespace levelforge;

namespace {

constexpr float kH = 0.05f;   // voxel size
constexpr float kBand = 3.0f; // half-width, voxels
constexpr double kR = 1.0;    // sphere radius: 20 voxels

const SmoothFilter kAll[] = {SmoothFilter::Mean, SmoothFilter::Gaussian, SmoothFilter::Median,
                             SmoothFilter::MeanCurvature, SmoothFilter::Laplacian};

openvdb::FloatGrid::Ptr sphere(float halfWidth = kBand)
{
    openvdb::initialize();
    return openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(float(kR), openvdb::Vec3f(0.0f), kH, halfWidth);
}

/// Over the active voxels within 1.5 voxels of the surface: the largest and the RMS of
/// |φ − (|x| − R)|, the mean of φ − (|x| − R), and the noise: the standard deviation and the
/// largest deviation of φ − (|x| − R) from that mean (a uniform shrink is not noise); voxels.
struct SphereError
{
    double worst = 0.0, rms = 0.0, mean = 0.0, noiseStd = 0.0, noiseWorst = 0.0;
};
SphereError sphereError(const openvdb::FloatGrid& g, double R = kR)
{
    SphereError e;
    uint64_t n = 0;
    for (auto it = g.tree().cbeginValueOn(); it; ++it) {
        if (std::abs(*it) > 1.5f * kH) continue;
        const double d = (double(*it) - (g.indexToWorld(it.getCoord()).length() - R)) / kH;
        e.worst = std::max(e.worst, std::abs(d));
        e.rms += d * d;
        e.mean += d;
        ++n;
    }
    if (n) { e.rms = std::sqrt(e.rms / double(n)); e.mean /= double(n); }
    e.noiseStd = std::sqrt(std::max(0.0, e.rms * e.rms - e.mean * e.mean));
    for (auto it = g.tree().cbeginValueOn(); it; ++it) {
        if (std::abs(*it) > 1.5f * kH) continue;
        const double d = (double(*it) - (g.indexToWorld(it.getCoord()).length() - R)) / kH;
        e.noiseWorst = std::max(e.noiseWorst, std::abs(d - e.mean));
    }
    return e;
}

/// A deterministic pseudo-random number in [-1, 1] for a voxel.
double noise(const openvdb::Coord& c)
{
    uint32_t x = uint32_t(c.x()) * 73856093u ^ uint32_t(c.y()) * 19349663u ^ uint32_t(c.z()) * 83492791u;
    x ^= x >> 13; x *= 0x5bd1e995u; x ^= x >> 15;
    return double(x & 0xffffu) / 32767.5 - 1.0;
}

} // namespace

/// How far one iteration of @p f moves the surface of a sphere of radius R voxels inward, in
/// voxels (radius 1 for the box filters). Mean: the box average of |x| over (2r+1)³ offsets u is
/// |x| + (|u|² − (u·n)²)/(2|x|) on average = |x| + r(r+1)/(3R); Gaussian: four box passes;
/// mean-curvature flow: dt κ_mean with OpenVDB's dt = h²/3 and κ_mean = 1/R; Laplacian flow:
/// dt Δφ with dt = h²/6 and Δφ = 2/R. Median: no closed form.
double predictedShrink(SmoothFilter f, double R)
{
    switch (f) {
    case SmoothFilter::Mean: return 2.0 / (3.0 * R);
    case SmoothFilter::Gaussian: return 4.0 * 2.0 / (3.0 * R);
    case SmoothFilter::MeanCurvature: return 1.0 / (3.0 * R);
    case SmoothFilter::Laplacian: return 1.0 / (3.0 * R);
    case SmoothFilter::Median: break;
    }
    return 0.0;
}

TEST(SmoothLevelSet, ASphereShrinksByTheFiltersAnalyticAmount)
{
    const auto s = sphere();
    for (const SmoothFilter f : kAll) {
        for (const int iterations : {1, 4}) {
            SCOPED_TRACE(std::string(toString(f)) + " x" + std::to_string(iterations));
            SmoothLevelSetOptions o;
            o.filter = f;
            o.iterations = iterations;
            const auto out = smoothLevelSet(*s, o);
            EXPECT_EQ(out->getGridClass(), openvdb::GRID_LEVEL_SET);
            EXPECT_EQ(out->background(), s->background());
            EXPECT_EQ(out->transform(), s->transform());
            const SphereError e = sphereError(*out);
            const double predicted = iterations * predictedShrink(f, kR / kH);
            std::printf("%-15s x%d: phi - exact: mean %+.4f voxel (predicted %+.4f), worst %.4f, rms %.4f\n", toString(f),
                        iterations, e.mean, predicted, e.worst, e.rms);
            if (f == SmoothFilter::Median) {
                // the median of a smooth field moves it little, and never by more than this
                EXPECT_LT(std::abs(e.mean), 0.03 * iterations);
                EXPECT_LT(e.worst, 0.06 * iterations + 0.05);
            } else {
                // the surface moves inward uniformly by the analytic amount
                EXPECT_NEAR(e.mean, predicted, 0.05 * predicted + 0.003);
                EXPECT_LT(e.worst, 1.1 * predicted + 0.01);
            }
            // the band keeps its width
            float lo = 0.0f, hi = 0.0f;
            for (auto it = out->tree().cbeginValueOn(); it; ++it) { lo = std::min(lo, *it); hi = std::max(hi, *it); }
            EXPECT_GT(hi / kH, kBand - 1.0f);
            EXPECT_LT(lo / kH, -(kBand - 1.0f));
        }
    }
    // the radius widens the box: mean of radius 2 shrinks by r(r+1)/(3R) = 0.1 voxel
    SmoothLevelSetOptions o;
    o.radius = 2;
    EXPECT_NEAR(sphereError(*smoothLevelSet(*s, o)).mean, 6.0 / (3.0 * kR / kH), 0.01);
    // the input is unchanged
    EXPECT_LT(sphereError(*s).worst, 1e-4);
}

TEST(SmoothLevelSet, NoiseOnASphereIsRemoved)
{
    // ±0.3 voxel of noise on every active value of an exact sphere
    auto noisy = sphere();
    for (auto it = noisy->tree().beginValueOn(); it; ++it)
        it.setValue(float(*it + 0.3 * kH * noise(it.getCoord())));
    const SphereError before = sphereError(*noisy);
    ASSERT_GT(before.noiseStd, 0.1);
    for (const SmoothFilter f : kAll) {
        SCOPED_TRACE(toString(f));
        SmoothLevelSetOptions o;
        o.filter = f;
        o.iterations = 2;
        const SphereError after = sphereError(*smoothLevelSet(*noisy, o));
        std::printf("%-15s x2: noise std %.3f -> %.3f voxel, worst %.3f -> %.3f (uniform shrink %+.3f)\n", toString(f),
                    before.noiseStd, after.noiseStd, before.noiseWorst, after.noiseWorst, after.mean);
        EXPECT_LT(after.noiseStd, 0.5 * before.noiseStd);
        // the median keeps the shape of what it cannot remove: its worst voxel improves least
        EXPECT_LT(after.noiseWorst, (f == SmoothFilter::Median ? 1.0 : 0.8) * before.noiseWorst);
    }
}

TEST(SmoothLevelSet, TheCornersOfABoxAreRoundedAndItsFacesStay)
{
    openvdb::initialize();
    MeshToLevelSetOptions mo;
    mo.voxelSize = kH;
    mo.exteriorWidth = mo.interiorWidth = kBand;
    const auto box = meshToLevelSet(makeBox(Vec3d(-0.5), Vec3d(0.5)), mo);
    const openvdb::Coord nearCorner = box->transform().worldToIndexCellCentered(openvdb::Vec3d(0.5 - kH));
    const openvdb::Coord onFace = box->transform().worldToIndexCellCentered(openvdb::Vec3d(0.5 - kH, 0.0, 0.0));
    const float cornerBefore = box->tree().getValue(nearCorner), faceBefore = box->tree().getValue(onFace);
    ASSERT_NEAR(cornerBefore, -kH, 1e-5);
    ASSERT_NEAR(faceBefore, -kH, 1e-5);
    for (const SmoothFilter f : kAll) {
        SCOPED_TRACE(toString(f));
        SmoothLevelSetOptions o;
        o.filter = f;
        o.iterations = 4;
        const auto out = smoothLevelSet(*box, o);
        const float corner = out->tree().getValue(nearCorner), face = out->tree().getValue(onFace);
        std::printf("%-15s x4: voxel 1 inside the corner %+.3f -> %+.3f voxel; on a face %+.3f -> %+.3f\n", toString(f),
                    cornerBefore / kH, corner / kH, faceBefore / kH, face / kH);
        // the corner is cut: the voxel one diagonal step inside it moves towards (or past) the surface
        EXPECT_GT(corner - cornerBefore, 0.25f * kH);
        // the middle of a flat face does not move
        EXPECT_NEAR(face, faceBefore, 0.05f * kH);
    }
}

TEST(SmoothLevelSet, BadInputIsRefused)
{
    const auto s = sphere();
    SmoothLevelSetOptions o;
    for (const int bad : {0, -1, 1001}) {
        o.iterations = bad;
        EXPECT_THROW(smoothLevelSet(*s, o), InvalidArgumentError) << bad;
    }
    o.iterations = 1;
    for (const int bad : {0, 33}) {
        o.radius = bad;
        EXPECT_THROW(smoothLevelSet(*s, o), InvalidArgumentError) << bad;
    }
    o.radius = 1;
    auto fog = s->deepCopy();
    fog->setGridClass(openvdb::GRID_FOG_VOLUME);
    EXPECT_THROW(smoothLevelSet(*fog, o), InvalidArgumentError);
    EXPECT_THROW(smoothLevelSet(*sphere(1.5f), o), InvalidArgumentError); // band under 2 voxels
    EXPECT_THROW(smoothFilterFromString("blur"), InvalidArgumentError);
    for (const SmoothFilter f : kAll) EXPECT_EQ(smoothFilterFromString(toString(f)), f);
    struct Stop : openvdb::util::NullInterrupter
    {
        bool wasInterrupted(int = -1) override { return true; }
    } stop;
    o.interrupter = &stop;
    EXPECT_THROW(smoothLevelSet(*s, o), InterruptedError);
}
