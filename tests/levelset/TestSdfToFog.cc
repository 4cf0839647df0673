// SPDX-License-Identifier: Apache-2.0
// sdfToFog() (issue 16, item 3): the fog volume of a level set against the analytic sphere and
// against openvdb::tools::sdfToFogVolume() as an anchor.
#include <levelforge/core/Exceptions.h>
#include <levelforge/core/Metadata.h>
#include <levelforge/levelset/SdfToFog.h>
#include <levelforge/mesh/MeshToLevelSet.h>

#include <openvdb/openvdb.h>
#include <openvdb/tools/LevelSetSphere.h>
#include <openvdb/tools/LevelSetUtil.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

using namespace levelforge;

namespace {

constexpr double kRadius = 1.0, kVoxel = 0.05, kHalfWidth = 3.0;
const openvdb::Vec3f kCentre(0.1f, -0.2f, 0.3f);

openvdb::FloatGrid::Ptr sphere()
{
    openvdb::initialize();
    return openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(float(kRadius), kCentre, float(kVoxel),
                                                                   float(kHalfWidth));
}

double analyticFog(const openvdb::Vec3d& world, double width)
{
    const double phi = (world - openvdb::Vec3d(kCentre)).length() - kRadius;
    return std::clamp(-phi / width, 0.0, 1.0);
}

} // namespace

TEST(SdfToFog, SphereRampTilesAndOutside)
{
    const auto sdf = sphere();
    const double width = kHalfWidth * kVoxel; // no levelforge metadata: the background
    EXPECT_NEAR(fogInteriorWidth(*sdf), width, 1e-7);
    const auto fog = sdfToFog(*sdf);
    ASSERT_TRUE(fog);
    EXPECT_EQ(fog->getGridClass(), openvdb::GRID_FOG_VOLUME);
    EXPECT_EQ(fog->background(), 0.0f);
    EXPECT_EQ(fog->getName(), sdf->getName());
    EXPECT_EQ(fog->transform(), sdf->transform());

    // Every voxel of the level set's band: the ramp, exact against the analytic sphere.
    uint64_t ramp = 0, outside = 0;
    double maxError = 0.0;
    for (auto it = sdf->tree().cbeginValueOn(); it; ++it) {
        const openvdb::Coord ijk = it.getCoord();
        const float phi = *it;
        const float f = fog->tree().getValue(ijk);
        const bool on = fog->tree().isValueOn(ijk);
        if (phi >= 0.0f) {
            ++outside;
            EXPECT_EQ(f, 0.0f) << ijk;
            EXPECT_FALSE(on) << ijk;
            continue;
        }
        ++ramp;
        EXPECT_TRUE(on) << ijk;
        EXPECT_NEAR(f, std::clamp(-double(phi) / width, 0.0, 1.0), 1e-6) << ijk;
        maxError = std::max(maxError, std::abs(f - analyticFog(sdf->transform().indexToWorld(ijk), width)));
    }
    EXPECT_GT(ramp, 1000u);
    EXPECT_GT(outside, 1000u);
    EXPECT_LE(maxError, 1e-6);

    // Deep inside: 1 and active, in tiles; far outside: 0, inactive.
    const openvdb::Coord centre = sdf->transform().worldToIndexCellCentered(openvdb::Vec3d(kCentre));
    EXPECT_EQ(fog->tree().getValue(centre), 1.0f);
    EXPECT_TRUE(fog->tree().isValueOn(centre));
    EXPECT_GT(fog->tree().activeTileCount(), 0u);
    for (auto it = fog->tree().cbeginValueOn(); it; ++it) {
        ASSERT_GT(*it, 0.0f);
        ASSERT_LE(*it, 1.0f);
    }
    const openvdb::Coord far = sdf->transform().worldToIndexCellCentered(openvdb::Vec3d(kCentre) + openvdb::Vec3d(2.0, 0, 0));
    EXPECT_EQ(fog->tree().getValue(far), 0.0f);
    EXPECT_FALSE(fog->tree().isValueOn(far));
    // Every inside voxel (tiles by volume) is active: the sphere's volume in voxels.
    const double volumeVoxels = 4.0 / 3.0 * M_PI * std::pow(kRadius / kVoxel, 3);
    EXPECT_NEAR(double(fog->activeVoxelCount()), volumeVoxels, 0.02 * volumeVoxels);
    // The level set is untouched.
    EXPECT_EQ(sdf->getGridClass(), openvdb::GRID_LEVEL_SET);
}

TEST(SdfToFog, MatchesOpenVdbSdfToFogVolume)
{
    const auto sdf = sphere();
    const auto ours = sdfToFog(*sdf);
    auto theirs = sdf->deepCopy();
    openvdb::tools::sdfToFogVolume(*theirs);
    uint64_t both = 0, onlyOurs = 0, onlyTheirs = 0;
    double maxDiff = 0.0;
    openvdb::CoordBBox bbox;
    sdf->tree().evalActiveVoxelBoundingBox(bbox);
    bbox.expand(2);
    for (auto ijk = bbox.begin(); ijk; ++ijk) {
        const bool a = ours->tree().isValueOn(*ijk), b = theirs->tree().isValueOn(*ijk);
        if (a && b) {
            ++both;
            maxDiff = std::max(maxDiff, double(std::abs(ours->tree().getValue(*ijk) - theirs->tree().getValue(*ijk))));
        } else if (a) {
            ++onlyOurs;
        } else if (b) {
            ++onlyTheirs;
        }
    }
    EXPECT_GT(both, 30000u); // the sphere's ~33,500 inside voxels
    EXPECT_LE(maxDiff, 1e-6);
    // The same inside: OpenVDB activates the same voxels (tiles by volume), up to the
    // surface voxels where φ rounds to exactly 0.
    EXPECT_LE(onlyOurs + onlyTheirs, both / 1000) << onlyOurs << " only ours, " << onlyTheirs << " only OpenVDB's";
}

TEST(SdfToFog, WidthFromOptionAndMetadata)
{
    const auto sdf = sphere();
    SdfToFogOptions o;
    o.interiorWidthWorld = 0.1;
    o.gridName = "density";
    auto fog = sdfToFog(*sdf, o);
    EXPECT_EQ(fog->getName(), "density");
    for (auto it = sdf->tree().cbeginValueOn(); it; ++it)
        if (*it < 0.0f) ASSERT_NEAR(fog->tree().getValue(it.getCoord()), std::min(1.0, -double(*it) / 0.1), 1e-6);

    // the levelforge band metadata wins over the background
    sdf->insertMeta(meta::kInteriorBandVoxels, openvdb::FloatMetadata(2.0f));
    EXPECT_NEAR(fogInteriorWidth(*sdf), 2.0 * kVoxel, 1e-7);
    fog = sdfToFog(*sdf);
    for (auto it = sdf->tree().cbeginValueOn(); it; ++it)
        if (*it < 0.0f)
            ASSERT_NEAR(fog->tree().getValue(it.getCoord()), std::min(1.0, -double(*it) / (2.0 * kVoxel)), 1e-6);

    o.interiorWidthWorld = -1.0;
    EXPECT_THROW(sdfToFog(*sdf, o), InvalidArgumentError);
    o.interiorWidthWorld = std::nan("");
    EXPECT_THROW(sdfToFog(*sdf, o), InvalidArgumentError);
}

TEST(SdfToFog, FilledInteriorIsOne)
{
    // A filled level set holds −background in its active deep voxels; with a ramp wider than the
    // background those must still read 1.
    const auto sdf = sphere();
    const openvdb::Coord centre = sdf->transform().worldToIndexCellCentered(openvdb::Vec3d(kCentre));
    sdf->tree().setValueOn(centre, -sdf->background());
    SdfToFogOptions o;
    o.interiorWidthWorld = 5.0 * kVoxel;
    EXPECT_NEAR(sdfToFog(*sdf, o)->tree().getValue(centre), 0.6, 1e-6); // not marked filled: the formula
    sdf->insertMeta(kFillInteriorMetadata, openvdb::BoolMetadata(true));
    const auto fog = sdfToFog(*sdf, o);
    EXPECT_EQ(fog->tree().getValue(centre), 1.0f);
    EXPECT_TRUE(fog->tree().isValueOn(centre));
}
