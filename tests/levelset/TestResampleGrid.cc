// SPDX-License-Identifier: Apache-2.0
// resampleGrid(): a sphere level set onto voxel size 2h and onto a rotated, offset reference
// transform lines up with the analytic sphere; interpolated grids reproduce linear fields and
// approximate the sphere to the sampler's order; bad input is refused.
#include <levelforge/core/Exceptions.h>
#include <levelforge/levelset/ResampleGrid.h>

#include <openvdb/openvdb.h>
#include <openvdb/tools/Interpolation.h>
#include <openvdb/tools/LevelSetSphere.h>

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

using namespace levelforge;

namespace {

constexpr float kH = 0.05f;   // voxel size
constexpr float kBand = 3.0f; // half-width, voxels
constexpr double kR = 1.0;    // 20 voxels

openvdb::FloatGrid::Ptr sphere()
{
    openvdb::initialize();
    auto s = openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(float(kR), openvdb::Vec3f(0.0f), kH, kBand);
    s->setName("surface");
    return s;
}

/// Max |φ − (|x| − R)| over the active voxels with |φ| < maxAbs (world), in units of @p unit.
double worstError(const openvdb::FloatGrid& g, double unit, double maxAbs = 1e30)
{
    double worst = 0.0;
    for (auto it = g.tree().cbeginValueOn(); it; ++it) {
        if (std::abs(*it) >= maxAbs) continue;
        const double exact = g.indexToWorld(it.getCoord()).length() - kR;
        worst = std::max(worst, std::abs(double(*it) - exact) / unit);
    }
    return worst;
}

/// A rotated (30° about (1,1,0)), offset transform of voxel size 0.04.
openvdb::math::Transform::Ptr referenceTransform()
{
    auto t = openvdb::math::Transform::createLinearTransform(0.04);
    t->postRotate(0.5235987755982988, openvdb::math::Z_AXIS);
    t->postRotate(0.3, openvdb::math::X_AXIS);
    t->postTranslate(openvdb::Vec3d(0.013, -0.021, 0.007));
    return t;
}

} // namespace

TEST(ResampleGrid, ASphereLevelSetAtTwiceTheVoxelSizeIsRebuiltExactly)
{
    const auto s = sphere();
    const auto target = transformWithVoxelSize(s->transform(), 2 * kH);
    std::string how;
    const auto g = openvdb::gridPtrCast<openvdb::FloatGrid>(resampleGrid(*s, *target, ResampleGridOptions(), &how));
    ASSERT_TRUE(g);
    EXPECT_EQ(how, "rebuilt");
    EXPECT_EQ(g->transform(), *target);
    EXPECT_EQ(g->getName(), "surface");
    EXPECT_EQ(g->getGridClass(), openvdb::GRID_LEVEL_SET);
    EXPECT_FLOAT_EQ(g->background(), kBand * 2 * kH); // the band keeps 3 voxels
    const double worst = worstError(*g, 2 * kH);
    std::printf("sphere h -> 2h, rebuilt: |phi - exact| <= %.4f new voxel over the whole band\n", worst);
    EXPECT_LT(worst, 0.03);
}

TEST(ResampleGrid, ASphereLevelSetOnARotatedOffsetReferenceLinesUp)
{
    const auto s = sphere();
    const auto target = referenceTransform();
    ASSERT_TRUE(isSimilarityTransform(*target));
    const auto g = openvdb::gridPtrCast<openvdb::FloatGrid>(resampleGrid(*s, *target, ResampleGridOptions()));
    ASSERT_TRUE(g);
    EXPECT_EQ(g->transform(), *target);
    const double worst = worstError(*g, 0.04);
    std::printf("sphere onto a rotated, offset transform of voxel 0.04: |phi - exact| <= %.4f voxel\n", worst);
    EXPECT_LT(worst, 0.06);
    // φ at world points (between voxels too) matches the analytic sphere
    const auto acc = g->getConstAccessor();
    for (const openvdb::Vec3d p : {openvdb::Vec3d(1.0, 0.0, 0.0), openvdb::Vec3d(0.0, -0.98, 0.03),
                                   openvdb::Vec3d(0.5, 0.5, 0.71), openvdb::Vec3d(-0.6, 0.0, -0.83)}) {
        const double v = openvdb::tools::BoxSampler::sample(acc, g->worldToIndex(p));
        EXPECT_NEAR(v, p.length() - kR, 0.01) << p;
    }
    EXPECT_GT(g->activeVoxelCount(), 0u);
}

TEST(ResampleGrid, InterpolationReproducesLinearFieldsAndApproximatesTheSphere)
{
    // a level set interpolated (not rebuilt) at each order: errors by order
    // (a target offset from the input's voxel centres: at 2h with the same origin every
    // target voxel centre would be an input voxel centre, and every order would be exact)
    const auto s = sphere();
    const auto target = transformWithVoxelSize(s->transform(), 2 * kH);
    target->postTranslate(openvdb::Vec3d(0.37, 0.21, 0.13) * kH);
    double worst[3];
    int k = 0;
    for (const ResampleOrder order : {ResampleOrder::Point, ResampleOrder::Linear, ResampleOrder::Quadratic}) {
        ResampleGridOptions o;
        o.order = order;
        o.levelSets = LevelSetResample::Interpolate;
        std::string how;
        const auto g = openvdb::gridPtrCast<openvdb::FloatGrid>(resampleGrid(*s, *target, o, &how));
        ASSERT_TRUE(g);
        EXPECT_EQ(how.rfind("interpolated", 0), 0u) << how;
        EXPECT_EQ(g->getGridClass(), openvdb::GRID_LEVEL_SET);
        EXPECT_EQ(g->background(), s->background());
        worst[k] = worstError(*g, 2 * kH, 1.0 * kH); // near the surface, away from the band's edge
        std::printf("sphere h -> 2h, %s: |phi - exact| <= %.4f new voxel within 1 old voxel of the surface\n", how.c_str(),
                    worst[k]);
        ++k;
    }
    EXPECT_LT(worst[1], 0.05);
    EXPECT_LT(worst[2], 0.05);
    EXPECT_LT(worst[1], worst[0]);

    // a linear vector field v(x) = A x + b on a dense block, onto a rotated transform of the same
    // voxel size: linear and quadratic interpolation reproduce it exactly (to float rounding)
    auto field = openvdb::Vec3SGrid::create(openvdb::Vec3s(0.0f));
    field->setTransform(openvdb::math::Transform::createLinearTransform(0.04));
    field->setName("v");
    const auto value = [](const openvdb::Vec3d& x) {
        return openvdb::Vec3d(1.0 + 2.0 * x[0] - x[1], 0.5 * x[2] - 3.0 * x[0], x[0] + x[1] + x[2]);
    };
    auto acc = field->getAccessor();
    for (int i = -16; i < 16; ++i)
        for (int j = -16; j < 16; ++j)
            for (int kk = -16; kk < 16; ++kk) {
                const openvdb::Coord c(i, j, kk);
                acc.setValue(c, openvdb::Vec3s(value(field->indexToWorld(c))));
            }
    auto rotated = openvdb::math::Transform::createLinearTransform(0.04);
    rotated->postRotate(0.4, openvdb::math::Z_AXIS);
    rotated->postTranslate(openvdb::Vec3d(0.011, 0.0, -0.017));
    for (const ResampleOrder order : {ResampleOrder::Linear, ResampleOrder::Quadratic}) {
        ResampleGridOptions o;
        o.order = order;
        const auto g = openvdb::gridPtrCast<openvdb::Vec3SGrid>(resampleGrid(*field, *rotated, o));
        ASSERT_TRUE(g);
        EXPECT_EQ(g->getName(), "v");
        double err = 0.0;
        uint64_t n = 0;
        for (auto it = g->cbeginValueOn(); it; ++it) {
            const openvdb::Vec3d x = g->indexToWorld(it.getCoord());
            const openvdb::Vec3d xi = field->worldToIndex(x);
            if (std::abs(xi[0]) > 13 || std::abs(xi[1]) > 13 || std::abs(xi[2]) > 13) continue; // inside the block
            err = std::max(err, (openvdb::Vec3d(*it) - value(x)).length());
            ++n;
        }
        EXPECT_GT(n, 10000u);
        EXPECT_LT(err, 1e-5) << int(order);
    }
}

TEST(ResampleGrid, TheSameTransformCopies)
{
    const auto s = sphere();
    std::string how;
    const auto g = openvdb::gridPtrCast<openvdb::FloatGrid>(resampleGrid(*s, s->transform(), ResampleGridOptions(), &how));
    ASSERT_TRUE(g);
    EXPECT_EQ(how, "copied (same transform)");
    EXPECT_EQ(g->activeVoxelCount(), s->activeVoxelCount());
    EXPECT_NE(&g->tree(), &s->tree());
}

TEST(ResampleGrid, BadInputIsRefused)
{
    const auto s = sphere();
    auto sheared = openvdb::math::Transform::createLinearTransform(0.05);
    sheared->preScale(openvdb::Vec3d(1, 2, 1));
    EXPECT_THROW(resampleGrid(*s, *sheared, ResampleGridOptions()), InvalidArgumentError); // rebuild needs a similarity
    ResampleGridOptions interp;
    interp.levelSets = LevelSetResample::Interpolate;
    EXPECT_NO_THROW(resampleGrid(*s, *sheared, interp)); // interpolation takes any affine map
    const auto ints = openvdb::Int32Grid::create(0);
    EXPECT_FALSE(isResamplable(*ints));
    EXPECT_THROW(resampleGrid(*ints, *sheared, interp), InvalidArgumentError);
    EXPECT_THROW(resampleOrderFromString("cubic"), InvalidArgumentError);
    EXPECT_EQ(resampleOrderFromString("quadratic"), ResampleOrder::Quadratic);
    struct Stop : openvdb::util::NullInterrupter
    {
        bool wasInterrupted(int = -1) override { return true; }
    } stop;
    ResampleGridOptions o;
    o.interrupter = &stop;
    EXPECT_THROW(resampleGrid(*s, *referenceTransform(), o), InterruptedError);
}
