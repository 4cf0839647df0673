// SPDX-License-Identifier: Apache-2.0
// rebuildLevelSet(): a fog volume of a sphere, a level set scaled by 3 and a level set with a
// band of one voxel all become the exact narrow band of the sphere (within the marching
// surface's error), with |∇φ| = 1; another voxel size; OpenVDB's levelSetRebuild as a yardstick.
#include <levelforge/core/Exceptions.h>
#include <levelforge/core/Metadata.h>
#include <levelforge/levelset/RebuildLevelSet.h>
#include <levelforge/levelset/SdfToFog.h>

#include <openvdb/openvdb.h>
#include <openvdb/tools/ChangeBackground.h>
#include <openvdb/tools/LevelSetRebuild.h>
#include <openvdb/tools/LevelSetSphere.h>

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

using namespace levelforge;

namespace {

constexpr float kH = 0.05f;   // voxel size
constexpr float kBand = 3.0f; // half-width, voxels
constexpr double kR = 1.0;    // 20 voxels
const openvdb::Vec3d kC(0.013, -0.021, 0.007); // off the voxel grid

openvdb::FloatGrid::Ptr sphere(float halfWidth = kBand, float h = kH)
{
    openvdb::initialize();
    return openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(float(kR), openvdb::Vec3f(kC), h, halfWidth);
}

/// What a rebuilt sphere looks like against |x − c| − R.
struct Check
{
    double worst = 0.0;        ///< max |φ − exact| over all active voxels, voxels
    double worstGradient = 0.0;///< max ||∇φ| − 1| by central differences where |φ| < 1.5 voxels
                               ///< and the stencil lies in the band
    float lo = 0.0f, hi = 0.0f;///< range of the active values, voxels
};
Check check(const openvdb::FloatGrid& g, double R = kR)
{
    Check c;
    const double h = g.voxelSize()[0];
    const auto acc = g.getConstAccessor();
    for (auto it = g.tree().cbeginValueOn(); it; ++it) {
        const double exact = (g.indexToWorld(it.getCoord()) - kC).length() - R;
        c.worst = std::max(c.worst, std::abs(double(*it) - exact) / h);
        c.lo = std::min(c.lo, float(*it / h));
        c.hi = std::max(c.hi, float(*it / h));
        if (std::abs(*it) < 1.5 * h) {
            const openvdb::Coord ijk = it.getCoord();
            openvdb::Vec3d grad;
            bool inBand = true; // every neighbour holds a distance, not the clamped background
            for (int a = 0; a < 3; ++a) {
                openvdb::Coord p = ijk, m = ijk;
                p[a] += 1;
                m[a] -= 1;
                inBand = inBand && acc.isValueOn(p) && acc.isValueOn(m);
                grad[a] = (acc.getValue(p) - acc.getValue(m)) / (2 * h);
            }
            if (inBand) c.worstGradient = std::max(c.worstGradient, std::abs(grad.length() - 1.0));
        }
    }
    return c;
}

} // namespace

TEST(RebuildLevelSet, AFogVolumeOfASphereBecomesItsExactBand)
{
    const auto s = sphere();
    const auto fog = sdfToFog(*s); // ramp 0 → 1 over the interior band of 3 voxels
    ASSERT_EQ(fog->getGridClass(), openvdb::GRID_FOG_VOLUME);
    RebuildLevelSetOptions o;
    o.isoValue = 0.5; // φ = -1.5 voxels: a sphere of radius R - 1.5 h
    RebuildLevelSetStats st;
    const auto out = rebuildLevelSet(*fog, o, &st);
    EXPECT_EQ(out->getGridClass(), openvdb::GRID_LEVEL_SET);
    EXPECT_EQ(out->transform(), fog->transform());
    EXPECT_EQ(out->getName(), fog->getName());
    EXPECT_FLOAT_EQ(out->background(), kBand * kH);
    const Check c = check(*out, kR - 1.5 * kH);
    std::printf("fog -> sdf: |phi - exact| <= %.4f voxel, ||grad phi| - 1| <= %.3f near the surface; %llu triangles, "
                "sign %s\n",
                c.worst, c.worstGradient, (unsigned long long)st.surfaceTriangles, st.sign.c_str());
    EXPECT_LT(c.worst, 0.05);
    EXPECT_LT(c.worstGradient, 0.05);
    EXPECT_GT(c.hi, kBand - 1.0f);
    EXPECT_LT(c.lo, -(kBand - 1.0f));
    EXPECT_EQ(st.sign, "pseudonormal");
    EXPECT_GT(st.surfaceTriangles, 1000u);
    EXPECT_EQ(st.activeVoxels, out->activeVoxelCount());
    // the inside is inside: the centre is negative, far away positive
    EXPECT_LT(out->tree().getValue(out->transform().worldToIndexCellCentered(kC)), 0.0f);
    EXPECT_GT(out->tree().getValue(openvdb::Coord(100, 0, 0)), 0.0f);
    ASSERT_TRUE(out->getMetadata<openvdb::FloatMetadata>(meta::kIso));
    EXPECT_FLOAT_EQ(out->metaValue<float>(meta::kIso), 0.5f);

    // the same fog with inside = below is the complement: φ flips sign near the surface
    o.inside = RebuildInside::Below;
    const auto flipped = rebuildLevelSet(*fog, o);
    EXPECT_GT(flipped->tree().getValue(flipped->transform().worldToIndexCellCentered(kC)), 0.0f);
    EXPECT_LT(flipped->tree().getValue(openvdb::Coord(100, 0, 0)), 0.0f);
    const Check cf = check(*flipped, kR - 1.5 * kH);
    EXPECT_GT(cf.worst, 2.0); // the exact sphere's signs are reversed ...
    double worstFlipped = 0.0; // ... and −φ is the sphere
    for (auto it = flipped->tree().cbeginValueOn(); it; ++it) {
        const double exact = (flipped->indexToWorld(it.getCoord()) - kC).length() - (kR - 1.5 * kH);
        worstFlipped = std::max(worstFlipped, std::abs(double(-*it) - exact) / kH);
    }
    EXPECT_LT(worstFlipped, 0.05);
}

TEST(RebuildLevelSet, DamagedLevelSetsAreRepaired)
{
    // values scaled by 3 (|∇φ| = 3): same zero set, wrong distances
    auto scaled = sphere();
    for (auto it = scaled->tree().beginValueAll(); it; ++it) it.setValue(*it * 3.0f);
    // a band of one voxel on each side (OpenVDB makes no band under 1.5 voxels: cut one down)
    auto thin = sphere(1.5f);
    for (auto it = thin->tree().beginValueOn(); it; ++it)
        if (std::abs(*it) > kH) it.setValueOff();
    openvdb::tools::changeLevelSetBackground(thin->tree(), kH);
    for (const auto& damaged : {scaled, thin}) {
        RebuildLevelSetOptions o;
        o.exteriorWidth = 3.0;
        o.interiorWidth = 2.0;
        const auto out = rebuildLevelSet(*damaged, o);
        const Check c = check(*out);
        std::printf("%s: |phi - exact| <= %.4f voxel, ||grad phi| - 1| <= %.3f near the surface, band [%.2f, %.2f]\n",
                    damaged == scaled ? "scaled by 3" : "band of 1 voxel", c.worst, c.worstGradient, c.lo, c.hi);
        EXPECT_LT(c.worst, 0.05);
        EXPECT_LT(c.worstGradient, 0.05);
        EXPECT_GT(c.hi, 2.0f);
        EXPECT_LT(c.hi, 3.0f);
        EXPECT_GT(c.lo, -2.0f);
        EXPECT_LT(c.lo, -1.0f);
        EXPECT_FLOAT_EQ(out->metaValue<float>(meta::kInteriorBandVoxels), 2.0f);
    }
}

TEST(RebuildLevelSet, AtAnotherVoxelSizeAndInWorldUnits)
{
    const auto s = sphere();
    RebuildLevelSetOptions o;
    o.voxelSize = 2 * kH;
    o.units = WidthUnits::World;
    o.exteriorWidth = o.interiorWidth = 0.3; // 3 voxels of 0.1
    RebuildLevelSetStats st;
    const auto out = rebuildLevelSet(*s, o, &st);
    EXPECT_DOUBLE_EQ(out->voxelSize()[0], 2 * kH);
    EXPECT_DOUBLE_EQ(st.voxelSize, 2 * kH);
    EXPECT_FLOAT_EQ(out->background(), 0.3f);
    const Check c = check(*out);
    std::printf("h -> 2h: |phi - exact| <= %.4f (new) voxel\n", c.worst);
    EXPECT_LT(c.worst, 0.03); // the surface of the fine grid, measured on the coarse one
    EXPECT_GT(c.hi, 2.0f);
    // voxel (0,0,0) keeps its world position
    EXPECT_EQ(out->indexToWorld(openvdb::Vec3d(0.0)), s->indexToWorld(openvdb::Vec3d(0.0)));
}

TEST(RebuildLevelSet, IsCloserToTheSphereThanOpenVdbsRebuild)
{
    // the same surface extraction; OpenVDB's meshToVolume distances are approximate, ours exact
    auto scaled = sphere();
    for (auto it = scaled->tree().beginValueAll(); it; ++it) it.setValue(*it * 3.0f);
    const auto ours = rebuildLevelSet(*scaled, RebuildLevelSetOptions());
    const auto theirs = openvdb::tools::levelSetRebuild(*scaled, 0.0f, kBand, kBand);
    const Check a = check(*ours), b = check(*theirs);
    std::printf("rebuild of a sphere scaled by 3: levelforge |phi - exact| <= %.4f voxel, OpenVDB levelSetRebuild "
                "<= %.4f voxel\n",
                a.worst, b.worst);
    EXPECT_LT(a.worst, b.worst);
}

TEST(RebuildLevelSet, SimilarityTransforms)
{
    auto t = openvdb::math::Transform::createLinearTransform(0.1);
    EXPECT_TRUE(isSimilarityTransform(*t));
    t->preRotate(0.5, openvdb::math::Y_AXIS);
    t->postTranslate(openvdb::Vec3d(1, 2, 3));
    EXPECT_TRUE(isSimilarityTransform(*t));
    const auto r = transformWithVoxelSize(*t, 0.25);
    EXPECT_TRUE(isSimilarityTransform(*r));
    EXPECT_NEAR(r->voxelSize()[0], 0.25, 1e-12);
    EXPECT_TRUE(r->indexToWorld(openvdb::Vec3d(0.0)).eq(t->indexToWorld(openvdb::Vec3d(0.0)), 1e-12));
    auto sheared = openvdb::math::Transform::createLinearTransform(0.1);
    sheared->preScale(openvdb::Vec3d(1, 2, 1));
    EXPECT_FALSE(isSimilarityTransform(*sheared));
    EXPECT_THROW(transformWithVoxelSize(*t, 0.0), InvalidArgumentError);
    EXPECT_THROW(transformWithVoxelSize(*t, std::nan("")), InvalidArgumentError);
}

TEST(RebuildLevelSet, BadInputIsRefused)
{
    const auto s = sphere();
    RebuildLevelSetOptions o;
    o.isoValue = 10.0; // never crossed
    try {
        rebuildLevelSet(*s, o);
        FAIL() << "no iso-surface accepted";
    } catch (const InvalidArgumentError& e) {
        EXPECT_NE(std::string(e.what()).find("no iso-surface"), std::string::npos) << e.what();
    }
    o.isoValue = std::nan("");
    EXPECT_THROW(rebuildLevelSet(*s, o), InvalidArgumentError);
    o.isoValue = 0.0;
    for (const double bad : {0.0, -1.0, std::nan(""), 1e6}) {
        o.exteriorWidth = bad;
        EXPECT_THROW(rebuildLevelSet(*s, o), InvalidArgumentError) << bad;
    }
    o.exteriorWidth = 3.0;
    o.voxelSize = -1.0;
    EXPECT_THROW(rebuildLevelSet(*s, o), InvalidArgumentError);
    o.voxelSize = 0.0;
    auto sheared = openvdb::math::Transform::createLinearTransform(0.1);
    sheared->preScale(openvdb::Vec3d(1, 2, 1));
    o.transform = sheared;
    EXPECT_THROW(rebuildLevelSet(*s, o), InvalidArgumentError);
    o.transform.reset();
    o.maxVoxels = 1000;
    EXPECT_THROW(rebuildLevelSet(*s, o), ResourceLimitError);
    o.maxVoxels = 0;
    EXPECT_THROW(rebuildInsideFromString("left"), InvalidArgumentError);
    struct Stop : openvdb::util::NullInterrupter
    {
        bool wasInterrupted(int = -1) override { return true; }
    } stop;
    o.interrupter = &stop;
    EXPECT_THROW(rebuildLevelSet(*s, o), InterruptedError);
}
