// SPDX-License-Identifier: Apache-2.0
// The library pipeline meshToSdf(): exact band (Chang or T4 scan) → expansion → metadata,
// checked against the exact reference and against its stages called one by one.
#include "TestUtil.h"

#include <levelforge/core/Exceptions.h>
#include <levelforge/core/Metadata.h>
#include <levelforge/pipeline/MeshToSdf.h>
#include <levelforge/reference/ExactReference.h>
#include <levelforge/reference/MeshShapes.h>

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>

using namespace levelforge;

namespace {

/// Same active voxels, same value bits.
void expectSameGrid(const openvdb::FloatGrid& a, const openvdb::FloatGrid& b, const std::string& what)
{
    ASSERT_EQ(a.activeVoxelCount(), b.activeVoxelCount()) << what;
    EXPECT_EQ(a.voxelSize(), b.voxelSize()) << what;
    EXPECT_EQ(a.background(), b.background()) << what;
    auto acc = b.getConstAccessor();
    uint64_t differ = 0;
    for (auto it = a.cbeginValueOn(); it; ++it) {
        float v = 0.0f;
        if (!acc.probeValue(it.getCoord(), v)) {
            ++differ;
            continue;
        }
        const float u = *it;
        if (std::memcmp(&u, &v, sizeof(float)) != 0) ++differ;
    }
    EXPECT_EQ(differ, 0u) << what;
}

std::string stringMeta(const openvdb::GridBase& g, const char* key)
{
    const auto m = g.getMetadata<openvdb::StringMetadata>(key);
    return m ? m->value() : std::string("<none>");
}

float floatMeta(const openvdb::GridBase& g, const char* key)
{
    const auto m = g.getMetadata<openvdb::FloatMetadata>(key);
    return m ? m->value() : -1.0f;
}

} // namespace

TEST(MeshToSdf, NoExpansionIsTheExactBandWithMetadata)
{
    const TriangleMesh mesh = makeTorusKnot();
    MeshToSdfOptions opt;
    opt.voxelCount = 64;
    opt.exteriorWidth = 3.0;
    opt.interiorWidth = 2.0;
    MeshToSdfStats stats;
    const auto grid = meshToSdf(mesh, opt, &stats);

    // Against the exact brute-force reference: every active voxel exact, none missing or extra.
    ExactReference ref(mesh);
    const BandErrorReport r = compareToReference(*grid, ref, 3.0, 2.0);
    EXPECT_GT(r.checkedVoxels, 1000u);
    EXPECT_LE(r.maxError, 1e-4);
    EXPECT_EQ(r.signErrors, 0u);
    EXPECT_EQ(r.missingVoxels, 0u);
    EXPECT_EQ(r.extraVoxels, 0u);

    // The same grid as the exact-band stage alone.
    MeshToLevelSetOptions mo;
    mo.voxelCount = 64;
    mo.exteriorWidth = 3.0;
    mo.interiorWidth = 2.0;
    expectSameGrid(*grid, *meshToLevelSet(mesh, mo), "pipeline vs meshToLevelSet");

    EXPECT_EQ(grid->getName(), "surface");
    EXPECT_EQ(stringMeta(*grid, meta::kMethod), "chang2008-exact-band");
    EXPECT_EQ(stringMeta(*grid, meta::kSource), mesh.source);
    EXPECT_EQ(floatMeta(*grid, meta::kExteriorBandVoxels), 3.0f);
    EXPECT_EQ(floatMeta(*grid, meta::kInteriorBandVoxels), 2.0f);
    EXPECT_EQ(stats.method, "chang2008-exact-band");
    EXPECT_EQ(stats.band.activeVoxels, grid->activeVoxelCount());
    EXPECT_DOUBLE_EQ(stats.voxelSize, grid->voxelSize()[0]);
}

TEST(MeshToSdf, WorldUnitWidthsEqualVoxelWidths)
{
    const TriangleMesh mesh = makeIcosphere(Vec3d(0.1, -0.2, 0.3), 1.0, 3);
    for (Expansion e : {Expansion::None, Expansion::Sweep}) {
        MeshToSdfOptions voxels;
        voxels.voxelSize = 0.05;
        voxels.exteriorWidth = 4.0;
        voxels.interiorWidth = 2.0;
        voxels.expansion = e;
        MeshToSdfOptions world = voxels;
        world.units = WidthUnits::World;
        world.exteriorWidth = 4.0 * 0.05;
        world.interiorWidth = 2.0 * 0.05;
        MeshToSdfStats sv, sw;
        const auto a = meshToSdf(mesh, voxels, &sv);
        const auto b = meshToSdf(mesh, world, &sw);
        EXPECT_FLOAT_EQ(float(sw.exteriorBandVoxels), 4.0f);
        EXPECT_FLOAT_EQ(float(sw.interiorBandVoxels), 2.0f);
        if (float(sw.exteriorBandVoxels) == 4.0f && float(sw.interiorBandVoxels) == 2.0f)
            expectSameGrid(*a, *b, e == Expansion::None ? "none" : "sweep");
    }
}

TEST(MeshToSdf, EveryExpansionKeepsTheExactBandAndReachesTheWidth)
{
    const TriangleMesh mesh = makeIcosphere(Vec3d(0.0), 1.0, 4);
    ExactReference ref(mesh);
    const double h = 0.04, width = 10.0, exact = 3.0;
    for (BandMethod method : {BandMethod::Chang, BandMethod::Scan}) {
        for (Expansion e : {Expansion::None, Expansion::Sweep, Expansion::Vector}) {
            const std::string what = std::string(method == BandMethod::Chang ? "chang" : "scan") + "/" +
                                     (e == Expansion::None ? "none" : e == Expansion::Sweep ? "sweep" : "vector");
            MeshToSdfOptions opt;
            opt.method = method;
            opt.expansion = e;
            opt.voxelSize = h;
            opt.exteriorWidth = opt.interiorWidth = width;
            opt.exactBandVoxels = exact;
            MeshToSdfStats stats;
            const auto grid = meshToSdf(mesh, opt, &stats);
            // Inside the exact band every value is exact; beyond it, expansion values are upper
            // bounds of the distance to within first-order error; every voxel with exact
            // |d| < width - 2 is active.
            uint64_t exactChecked = 0, missing = 0, signErrors = 0;
            double maxExactErr = 0.0, maxFarErr = 0.0;
            auto acc = grid->getConstAccessor();
            const int r = int(std::ceil((1.0 + width * h) / h)) + 1;
            for (int i = -r; i <= r; i += 1)
                for (int j = -r; j <= r; j += 3)
                    for (int k = -r; k <= r; k += 2) {
                        const openvdb::Coord c(i, j, k);
                        const double d = ref.signedDistance(Vec3d(i * h, j * h, k * h)) / h;
                        float v = 0.0f;
                        const bool on = acc.probeValue(c, v);
                        if (std::abs(d) < width - 2.0 && !on) ++missing;
                        if (!on) continue;
                        if (std::abs(d) > 0.5 && (v < 0) != (d < 0)) ++signErrors;
                        const double err = std::abs(double(v) / h - d);
                        if (std::abs(d) < exact - 1e-3) {
                            ++exactChecked;
                            maxExactErr = std::max(maxExactErr, err);
                        } else {
                            maxFarErr = std::max(maxFarErr, err);
                        }
                    }
            EXPECT_GT(exactChecked, 100u) << what;
            EXPECT_LE(maxExactErr, 1e-4) << what;
            EXPECT_EQ(signErrors, 0u) << what;
            EXPECT_EQ(missing, 0u) << what;
            EXPECT_LE(maxFarErr, e == Expansion::None ? 1e-4 : 1.5) << what;
            const std::string m = stringMeta(*grid, meta::kMethod);
            EXPECT_EQ(m, stats.method) << what;
            EXPECT_EQ(m.find(method == BandMethod::Chang ? "chang2008" : "erleben-dohlmann"), 0u) << what;
            EXPECT_EQ(m.find('+') != std::string::npos, e != Expansion::None) << what;
            EXPECT_EQ(floatMeta(*grid, meta::kExteriorBandVoxels), float(width)) << what;
        }
    }
}

TEST(MeshToSdf, BadOptionsAndNames)
{
    const TriangleMesh mesh = makeIcosphere(Vec3d(0.0), 1.0, 2);
    MeshToSdfOptions opt;
    opt.voxelCount = 32;
    opt.expansion = Expansion::Sweep;
    opt.exactBandVoxels = 0.5;
    EXPECT_THROW(meshToSdf(mesh, opt), InvalidArgumentError);
    opt.exactBandVoxels = std::nan("");
    EXPECT_THROW(meshToSdf(mesh, opt), InvalidArgumentError);
    MeshToSdfOptions none;
    EXPECT_THROW(meshToSdf(mesh, none), InvalidArgumentError); // neither voxel size nor count
    EXPECT_THROW(meshToSdf(TriangleMesh{}, opt), Error);
    EXPECT_EQ(bandMethodFromString("scan"), BandMethod::Scan);
    EXPECT_EQ(expansionFromString("exact"), Expansion::None);
    EXPECT_EQ(expansionFromString("vector"), Expansion::Vector);
    EXPECT_THROW(bandMethodFromString("marching"), InvalidArgumentError);
    EXPECT_THROW(expansionFromString("wide"), InvalidArgumentError);
}
