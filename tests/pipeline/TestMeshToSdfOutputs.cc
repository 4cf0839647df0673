// SPDX-License-Identifier: Apache-2.0
// meshToSdfGrids() outputs of issue 16 items 3-5: the fog volume, reference transforms, the
// primitive index grid (closest input polygon), and the options they refuse.
#include "TestUtil.h"

#include <levelforge/core/Exceptions.h>
#include <levelforge/core/MeshValidation.h>
#include <levelforge/core/Metadata.h>
#include <levelforge/core/TriangleDistance.h>
#include <levelforge/io/MeshIO.h>
#include <levelforge/io/VdbIO.h>
#include <levelforge/levelset/SdfToFog.h>
#include <levelforge/pipeline/MeshToSdf.h>
#include <levelforge/reference/ExactReference.h>
#include <levelforge/reference/MeshShapes.h>

#include <openvdb/openvdb.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <vector>

using namespace levelforge;
namespace fs = std::filesystem;

namespace {

/// A pentagonal prism as an OBJ of 7 polygons: face 0 the bottom pentagon, faces 1-5 the side
/// quads, face 6 the top pentagon (so triangle ids and face ids differ).
std::string writePrismObj(const fs::path& dir)
{
    const std::string path = (dir / "prism.obj").string();
    std::ofstream f(path);
    f.precision(17);
    for (int ring = 0; ring < 2; ++ring)
        for (int k = 0; k < 5; ++k) {
            const double a = M_PI / 2 + 2 * M_PI * k / 5;
            f << "v " << 0.9 * std::cos(a) << " " << 0.9 * std::sin(a) << " " << (ring ? 0.7 : -0.3) << "\n";
        }
    f << "f 5 4 3 2 1\n";
    for (int k = 0; k < 5; ++k) {
        const int b0 = 1 + k, b1 = 1 + (k + 1) % 5;
        f << "f " << b0 << " " << b1 << " " << b1 + 5 << " " << b0 + 5 << "\n";
    }
    f << "f 6 7 8 9 10\n";
    return path;
}

/// Exact distance from @p p to every input face (minimum over its triangles).
std::vector<double> faceDistances(const TriangleMesh& mesh, const Vec3d& p, size_t faces)
{
    std::vector<double> d(faces, std::numeric_limits<double>::infinity());
    for (size_t t = 0; t < mesh.triangles.size(); ++t) {
        const Vec3I& tri = mesh.triangles[t];
        const double dt = std::sqrt(
            closestPointOnTriangle(p, mesh.points[tri[0]], mesh.points[tri[1]], mesh.points[tri[2]]).distanceSqr);
        double& df = d[mesh.sourceFace(t)];
        df = std::min(df, dt);
    }
    return d;
}

std::string writeReference(const fs::path& dir, const openvdb::math::Transform::Ptr& xform, double ext, double in)
{
    openvdb::initialize();
    auto g = openvdb::FloatGrid::create(float(ext * 0.1));
    g->setName("ref_surface");
    g->setTransform(xform);
    stampLevelSetMetadata(*g, ext, in, "test", "test");
    const std::string path = (dir / "reference.vdb").string();
    writeGridsAtomic(path, openvdb::GridPtrVec{g});
    return path;
}

/// Every active voxel: exact distance and sign at its world centre (brute force), in voxels.
void expectExactAgainstBruteForce(const openvdb::FloatGrid& grid, const TriangleMesh& mesh, double h)
{
    const ExactReference ref(mesh);
    double maxError = 0.0;
    uint64_t n = 0, signErrors = 0;
    for (auto it = grid.tree().cbeginValueOn(); it; ++it) {
        const Vec3d world = grid.transform().indexToWorld(it.getCoord());
        const double exact = ref.bruteForce(world).distance;
        maxError = std::max(maxError, std::abs(std::abs(double(*it)) - std::abs(exact)) / h);
        if (std::abs(exact) > 1e-6 * h && (exact < 0) != (*it < 0)) ++signErrors;
        ++n;
    }
    EXPECT_GT(n, 500u);
    EXPECT_LE(maxError, 1e-4);
    EXPECT_EQ(signErrors, 0u);
}

} // namespace

TEST(MeshToSdfOutputs, ReaderKeepsPolygonIndices)
{
    const fs::path dir = levelforge_test::scratchDir("outputs_reader");
    MeshReadInfo info;
    const TriangleMesh mesh = readMesh(writePrismObj(dir), info);
    EXPECT_EQ(info.fileFaces, 7u);
    ASSERT_EQ(mesh.triangles.size(), 3u + 10u + 3u);
    ASSERT_EQ(mesh.faceIndex.size(), mesh.triangles.size());
    std::vector<int> count(7, 0);
    for (uint32_t f : mesh.faceIndex) {
        ASSERT_LT(f, 7u);
        ++count[f];
    }
    EXPECT_EQ(count, (std::vector<int>{3, 2, 2, 2, 2, 2, 3}));
    // a triangle-only file: triangle i is face i, no index stored
    TriangleMesh tris = makeIcosphere(Vec3d(0.0), 1.0, 1);
    writeMesh(tris, (dir / "tris.obj").string());
    EXPECT_TRUE(readMesh((dir / "tris.obj").string()).faceIndex.empty());
    // withoutDegenerateTriangles() keeps the face of every kept triangle
    TriangleMesh withDegenerate = mesh;
    withDegenerate.triangles.insert(withDegenerate.triangles.begin() + 4, Vec3I(0, 0, 1));
    withDegenerate.faceIndex.insert(withDegenerate.faceIndex.begin() + 4, 99u);
    const TriangleMesh cleaned = withoutDegenerateTriangles(withDegenerate);
    EXPECT_EQ(cleaned.faceIndex, mesh.faceIndex);
}

TEST(MeshToSdfOutputs, PrimitiveIndexIsTheClosestPolygon)
{
    const fs::path dir = levelforge_test::scratchDir("outputs_primitive");
    const TriangleMesh mesh = readMesh(writePrismObj(dir));
    MeshToSdfOptions o;
    o.voxelSize = 0.05;
    o.exteriorWidth = 3.0;
    o.interiorWidth = 3.0;
    o.primitiveIndexGridName = "primitive";
    o.fogGridName = "density";
    for (SignMode sign : {SignMode::Pseudonormal, SignMode::Winding, SignMode::Unsigned}) {
        o.sign = sign;
        if (sign == SignMode::Unsigned) o.fogGridName.clear();
        const MeshToSdfGrids g = meshToSdfGrids(mesh, o);
        ASSERT_TRUE(g.sdf && g.primitiveIndex);
        EXPECT_EQ(g.primitiveIndex->getName(), "primitive");
        EXPECT_EQ(g.primitiveIndex->background(), -1);
        EXPECT_EQ(g.primitiveIndex->transform(), g.sdf->transform());
        EXPECT_EQ(g.primitiveIndex->activeVoxelCount(), g.sdf->activeVoxelCount()) << toString(sign);
        EXPECT_EQ(g.all().size(), sign == SignMode::Unsigned ? 2u : 3u);
        const double h = o.voxelSize;
        uint64_t checked = 0, wrong = 0;
        std::vector<int> seen(7, 0);
        for (auto it = g.sdf->tree().cbeginValueOn(); it; ++it) {
            const openvdb::Coord ijk = it.getCoord();
            if ((ijk.x() * 7 + ijk.y() * 3 + ijk.z()) % 3 != 0) continue; // a third of the voxels
            ASSERT_TRUE(g.primitiveIndex->tree().isValueOn(ijk)) << ijk;
            const int32_t face = g.primitiveIndex->tree().getValue(ijk);
            ASSERT_GE(face, 0);
            ASSERT_LT(face, 7);
            ++seen[face];
            const std::vector<double> d = faceDistances(mesh, g.sdf->transform().indexToWorld(ijk), 7);
            const double best = *std::min_element(d.begin(), d.end());
            if (d[size_t(face)] > best + 1e-6 * h) ++wrong;
            EXPECT_NEAR(std::abs(*it), best, 1e-4 * h);
            ++checked;
        }
        EXPECT_GT(checked, 2000u);
        EXPECT_EQ(wrong, 0u) << toString(sign);
        for (int f = 0; f < 7; ++f) EXPECT_GT(seen[f], 0) << "face " << f;
        if (g.fog) {
            const auto expected = sdfToFog(*g.sdf, [] { SdfToFogOptions f; f.interiorWidthWorld = 0.15; return f; }());
            EXPECT_EQ(g.fog->getName(), "density");
            EXPECT_EQ(g.fog->getGridClass(), openvdb::GRID_FOG_VOLUME);
            EXPECT_EQ(g.fog->activeVoxelCount(), expected->activeVoxelCount());
            for (auto it = expected->tree().cbeginValueOn(); it; ++it)
                ASSERT_NEAR(g.fog->tree().getValue(it.getCoord()), *it, 1e-6);
        }
    }
    // meshToSdf() makes only the level set, the same one
    const auto alone = meshToSdf(mesh, o);
    EXPECT_EQ(alone->activeVoxelCount(), meshToSdfGrids(mesh, o).sdf->activeVoxelCount());
}

TEST(MeshToSdfOutputs, RefusedCombinations)
{
    const TriangleMesh mesh = makeIcosphere(Vec3d(0.0), 1.0, 2);
    MeshToSdfOptions o;
    o.voxelSize = 0.1;
    o.primitiveIndexGridName = "primitive";
    {
        MeshToSdfOptions b = o;
        b.expansion = Expansion::Sweep;
        EXPECT_THROW(meshToSdfGrids(mesh, b), InvalidArgumentError);
        b.expansion = Expansion::Vector;
        EXPECT_THROW(meshToSdfGrids(mesh, b), InvalidArgumentError);
    }
    {
        MeshToSdfOptions b = o;
        b.method = BandMethod::Scan;
        EXPECT_THROW(meshToSdfGrids(mesh, b), InvalidArgumentError);
    }
    {
        MeshToSdfOptions b = o;
        b.fillInterior = true;
        EXPECT_THROW(meshToSdfGrids(mesh, b), InvalidArgumentError);
    }
    {
        MeshToSdfOptions b = o;
        b.primitiveIndexGridName = b.gridName;
        EXPECT_THROW(meshToSdfGrids(mesh, b), InvalidArgumentError);
        b.primitiveIndexGridName = "x";
        b.fogGridName = "x";
        EXPECT_THROW(meshToSdfGrids(mesh, b), InvalidArgumentError);
        b.fogGridName = b.gridName;
        EXPECT_THROW(meshToSdfGrids(mesh, b), InvalidArgumentError);
    }
    {
        MeshToSdfOptions b;
        b.voxelSize = 0.1;
        b.fogGridName = "density";
        b.sign = SignMode::Unsigned;
        EXPECT_THROW(meshToSdfGrids(mesh, b), InvalidArgumentError);
    }
    {
        TriangleMesh bad = mesh;
        bad.faceIndex = {0, 1};
        EXPECT_THROW(meshToSdfGrids(bad, o), InvalidMeshError);
    }
    // the extra grids are refused only when asked for: with an expansion, the fog is fine
    MeshToSdfOptions fog;
    fog.voxelSize = 0.1;
    fog.fogGridName = "density";
    fog.expansion = Expansion::Sweep;
    fog.exteriorWidth = fog.interiorWidth = 6.0;
    const MeshToSdfGrids g = meshToSdfGrids(mesh, fog);
    ASSERT_TRUE(g.fog);
    EXPECT_NEAR(fogInteriorWidth(*g.sdf), 0.6, 1e-6);
}

TEST(MeshToSdfOutputs, ReferenceTransformIsExact)
{
    const fs::path dir = levelforge_test::scratchDir("outputs_reference");
    auto xform = openvdb::math::Transform::createLinearTransform(0.1);
    xform->postTranslate(openvdb::Vec3d(0.03, -0.02, 0.05));
    const std::string refPath = writeReference(dir, xform, 2.5, 1.5);
    const ReferenceGrid ref = readReferenceGrid(refPath);
    EXPECT_EQ(ref.path, refPath);
    EXPECT_EQ(ref.name, "ref_surface");
    EXPECT_NEAR(ref.voxelSize, 0.1, 1e-12);
    EXPECT_NEAR(ref.exteriorBandVoxels, 2.5, 1e-6);
    EXPECT_NEAR(ref.interiorBandVoxels, 1.5, 1e-6);
    ASSERT_TRUE(ref.transform);
    EXPECT_EQ(*ref.transform, *xform);

    const TriangleMesh mesh = makeIcosphere(Vec3d(0.2, 0.1, -0.1), 0.8, 3);
    MeshToSdfOptions o;
    o.voxelSize = 0.37; // ignored: the transform wins
    o.transform = ref.transform;
    o.exteriorWidth = ref.exteriorBandVoxels;
    o.interiorWidth = ref.interiorBandVoxels;
    o.fogGridName = "density";
    o.primitiveIndexGridName = "primitive";
    MeshToSdfStats stats;
    const MeshToSdfGrids g = meshToSdfGrids(mesh, o, &stats);
    EXPECT_NEAR(stats.voxelSize, 0.1, 1e-12);
    EXPECT_EQ(g.sdf->transform(), *xform);
    EXPECT_EQ(g.fog->transform(), *xform);
    EXPECT_EQ(g.primitiveIndex->transform(), *xform);
    // voxel centres coincide with the reference's
    for (const openvdb::Coord& ijk : {openvdb::Coord(0, 0, 0), openvdb::Coord(7, -3, 2), openvdb::Coord(-8, 5, -1)})
        EXPECT_EQ(g.sdf->transform().indexToWorld(ijk), xform->indexToWorld(ijk));
    EXPECT_NEAR(g.sdf->metaValue<float>(meta::kExteriorBandVoxels), 2.5f, 1e-6);
    EXPECT_NEAR(g.sdf->metaValue<float>(meta::kInteriorBandVoxels), 1.5f, 1e-6);
    expectExactAgainstBruteForce(*g.sdf, mesh, 0.1);
    // the band is the requested one around the translated centres
    const ExactReference exact(mesh);
    const BandErrorReport r = compareToReference(*g.sdf, exact, 2.5, 1.5);
    EXPECT_EQ(r.missingVoxels, 0u);
    EXPECT_EQ(r.extraVoxels, 0u);
    EXPECT_EQ(r.signErrors, 0u);

    // without the translation the values differ (the offset is 0.3-0.5 voxel): the test has teeth
    MeshToSdfOptions plain = o;
    plain.transform.reset();
    plain.voxelSize = 0.1;
    const auto p = meshToSdf(mesh, plain);
    double maxDiff = 0.0;
    for (auto it = p->tree().cbeginValueOn(); it; ++it)
        if (g.sdf->tree().isValueOn(it.getCoord()))
            maxDiff = std::max(maxDiff, double(std::abs(*it - g.sdf->tree().getValue(it.getCoord()))));
    EXPECT_GT(maxDiff, 0.02);
}

TEST(MeshToSdfOutputs, RotatedAndReflectedTransforms)
{
    const TriangleMesh mesh = makeIcosphere(Vec3d(0.2, 0.1, -0.1), 0.8, 3);
    for (bool reflect : {false, true}) {
        auto xform = openvdb::math::Transform::createLinearTransform(0.1);
        xform->postRotate(0.5, openvdb::math::Z_AXIS);
        xform->postRotate(0.3, openvdb::math::X_AXIS);
        if (reflect) xform->postScale(openvdb::Vec3d(-1.0, 1.0, 1.0));
        xform->postTranslate(openvdb::Vec3d(0.03, -0.02, 0.05));
        EXPECT_NEAR(checkUniformLinearTransform(*xform, "test"), 0.1, 1e-12);
        MeshToSdfOptions o;
        o.transform = xform;
        o.sign = SignMode::Pseudonormal;
        const auto grid = meshToSdf(mesh, o);
        EXPECT_EQ(grid->transform(), *xform);
        expectExactAgainstBruteForce(*grid, mesh, 0.1);
        // inside is negative
        EXPECT_LT(grid->tree().getValue(grid->transform().worldToIndexCellCentered(Vec3d(0.2, 0.1, -0.1))), 0.0f);
    }
}

TEST(MeshToSdfOutputs, BadTransformsAndReferences)
{
    openvdb::initialize();
    const TriangleMesh mesh = makeIcosphere(Vec3d(0.0), 1.0, 1);
    openvdb::math::Mat4d scale = openvdb::math::Mat4d::identity();
    scale.setToScale(openvdb::Vec3d(0.1, 0.1, 0.2));
    MeshToSdfOptions o;
    o.transform = openvdb::math::Transform::createLinearTransform(scale);
    EXPECT_THROW(meshToSdf(mesh, o), InvalidArgumentError);
    openvdb::math::Mat4d shear = openvdb::math::Mat4d::identity();
    shear.setToShear(openvdb::math::X_AXIS, openvdb::math::Y_AXIS, 0.3);
    o.transform = openvdb::math::Transform::createLinearTransform(shear);
    EXPECT_THROW(meshToSdf(mesh, o), InvalidArgumentError);
    o.transform = openvdb::math::Transform::createFrustumTransform(
        openvdb::BBoxd(openvdb::Vec3d(0.0), openvdb::Vec3d(10.0)), 0.5, 1.0, 0.1);
    EXPECT_THROW(meshToSdf(mesh, o), InvalidArgumentError);

    const fs::path dir = levelforge_test::scratchDir("outputs_bad_reference");
    EXPECT_THROW(readReferenceGrid((dir / "missing.vdb").string()), IoError);
    const std::string noFloat = (dir / "nofloat.vdb").string();
    auto v = openvdb::Vec3SGrid::create();
    v->setName("velocity");
    writeGridsAtomic(noFloat, openvdb::GridPtrVec{v});
    try {
        readReferenceGrid(noFloat);
        ADD_FAILURE() << "no throw";
    } catch (const InvalidArgumentError& e) {
        EXPECT_NE(std::string(e.what()).find(noFloat), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find("velocity"), std::string::npos) << e.what();
    }
    // a level set without metadata: the bands from its background
    auto ls = openvdb::FloatGrid::create(0.4f);
    ls->setTransform(openvdb::math::Transform::createLinearTransform(0.1));
    ls->setGridClass(openvdb::GRID_LEVEL_SET);
    const std::string plain = (dir / "plain.vdb").string();
    writeGridsAtomic(plain, openvdb::GridPtrVec{v, ls});
    const ReferenceGrid r = readReferenceGrid(plain);
    EXPECT_NEAR(r.exteriorBandVoxels, 4.0, 1e-5);
    EXPECT_NEAR(r.interiorBandVoxels, 4.0, 1e-5);
}

TEST(MeshToSdfOutputs, FogOfFilledAndAsymmetricBands)
{
    // Interior band wider than the exterior (background): the deep interior (inactive, or active
    // −background when filled) must read 1, the band the exact ramp over the interior width.
    const TriangleMesh mesh = makeIcosphere(Vec3d(0.0), 1.0, 3);
    MeshToSdfOptions o;
    o.voxelSize = 0.05;
    o.exteriorWidth = 2.0;
    o.interiorWidth = 6.0;
    o.fogGridName = "density";
    const MeshToSdfGrids band = meshToSdfGrids(mesh, o);
    o.fillInterior = true;
    const MeshToSdfGrids filled = meshToSdfGrids(mesh, o);
    const double w = 6.0 * 0.05;
    for (const MeshToSdfGrids* g : {&band, &filled}) {
        EXPECT_EQ(g->fog->tree().getValue(openvdb::Coord(0, 0, 0)), 1.0f);
        EXPECT_TRUE(g->fog->tree().isValueOn(openvdb::Coord(0, 0, 0)));
        for (auto it = g->sdf->tree().cbeginValueOn(); it; ++it) {
            if (*it >= 0.0f) {
                ASSERT_FALSE(g->fog->tree().isValueOn(it.getCoord()));
            } else if (g == &filled && *it == -g->sdf->background()) { // a filled voxel
                ASSERT_EQ(g->fog->tree().getValue(it.getCoord()), 1.0f) << it.getCoord();
            } else { // a band value, also below −background (the interior band is the wider)
                ASSERT_NEAR(g->fog->tree().getValue(it.getCoord()), std::min(1.0, -double(*it) / w), 1e-6);
            }
        }
    }
    // filled or not, the same fog
    EXPECT_EQ(band.fog->activeVoxelCount(), filled.fog->activeVoxelCount());
    for (auto it = band.fog->tree().cbeginValueOn(); it; ++it)
        ASSERT_EQ(filled.fog->tree().getValue(it.getCoord()), *it) << it.getCoord();
}
