// SPDX-License-Identifier: Apache-2.0
// levelSetToMesh() (OpenVDB's volumeToMesh, quads split, outward winding) against analytic
// spheres and boxes: vertex distances, closedness, orientation, volume, adaptivity, fog volumes.
#include "TestUtil.h"

#include <levelforge/core/Exceptions.h>
#include <levelforge/levelset/LevelSetToMesh.h>
#include <levelforge/mesh/MeshToLevelSet.h>
#include <levelforge/reference/MeshShapes.h>

#include <openvdb/openvdb.h>
#include <openvdb/tools/LevelSetSphere.h>

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <map>
#include <utility>

using namespace levelforge;

namespace {

constexpr double kH = 0.05;  // voxel size
constexpr double kR = 1.0;   // sphere radius: 20 voxels
const openvdb::Vec3d kC(0.11, -0.07, 0.23); // off the lattice

openvdb::FloatGrid::Ptr exactSphere()
{
    openvdb::initialize();
    // createLevelSetSphere stores the exact distance |x - c| - R at every voxel of the band
    return openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(float(kR), openvdb::Vec3f(kC), float(kH), 3.0f);
}

/// Largest | |p - c| - r | over the vertices, in voxels.
double worstVertexError(const TriangleMesh& mesh, double r, const openvdb::Vec3d& c = kC)
{
    double worst = 0.0;
    for (const Vec3d& p : mesh.points) worst = std::max(worst, std::abs((p - c).length() - r) / kH);
    return worst;
}

/// Every directed edge appears exactly once and its reverse exactly once: closed (every edge in
/// two triangles) and consistently oriented. Returns the number of faulty edges.
size_t badEdges(const TriangleMesh& mesh)
{
    std::map<std::pair<uint32_t, uint32_t>, int> directed;
    for (const Vec3I& t : mesh.triangles)
        for (int k = 0; k < 3; ++k) ++directed[{t[k], t[(k + 1) % 3]}];
    size_t bad = 0;
    for (const auto& [e, n] : directed) {
        const auto rev = directed.find({e.second, e.first});
        if (n != 1 || rev == directed.end() || rev->second != 1) ++bad;
    }
    return bad;
}

struct StopAtOnce : openvdb::util::NullInterrupter
{
    bool wasInterrupted(int = -1) override { return true; }
};

} // namespace

TEST(LevelSetToMesh, SphereVerticesLieOnTheSphereAndTheMeshIsClosedAndOutward)
{
    const auto grid = exactSphere();
    LevelSetToMeshStats stats;
    const TriangleMesh mesh = levelSetToMesh(*grid, LevelSetToMeshOptions(), &stats);
    ASSERT_FALSE(mesh.empty());
    EXPECT_EQ(mesh.triangleCount(), 2 * stats.quads + stats.openvdbTriangles - stats.degenerateDropped);
    // What is measured: the distance of every vertex to the analytic sphere, in voxels.
    const double worst = worstVertexError(mesh, kR);
    std::printf("sphere r = 20 voxels: %zu vertices, %zu triangles, worst vertex %.4f voxel off the sphere\n",
                mesh.vertexCount(), mesh.triangleCount(), worst);
    EXPECT_LT(worst, 0.05);
    EXPECT_EQ(badEdges(mesh), 0u);
    const double volume = signedVolume(mesh), exact = 4.0 / 3.0 * M_PI * kR * kR * kR;
    EXPECT_GT(volume, 0.0);
    EXPECT_NEAR(volume / exact, 1.0, 0.01) << volume << " vs " << exact;
    // every vertex is used
    std::vector<char> used(mesh.vertexCount(), 0);
    for (const Vec3I& t : mesh.triangles)
        for (int k = 0; k < 3; ++k) used[t[k]] = 1;
    for (size_t i = 0; i < used.size(); ++i) ASSERT_TRUE(used[i]) << "vertex " << i;
}

TEST(LevelSetToMesh, MeshOfASphereConvertsBackToANegativeInside)
{
    const auto grid = exactSphere();
    const TriangleMesh mesh = levelSetToMesh(*grid, LevelSetToMeshOptions());
    MeshToLevelSetOptions o;
    o.voxelSize = kH;
    const auto back = meshToLevelSet(mesh, o);
    auto acc = back->getConstAccessor();
    const auto at = [&](const openvdb::Vec3d& p) { return acc.getValue(openvdb::Coord::round(back->worldToIndex(p))); };
    EXPECT_LT(at(kC), 0.0f);                                         // centre, deep inside
    EXPECT_LT(at(kC + openvdb::Vec3d(kR - 2 * kH, 0, 0)), 0.0f);     // in the band, inside
    EXPECT_GT(at(kC + openvdb::Vec3d(0, kR + 2 * kH, 0)), 0.0f);     // in the band, outside
    EXPECT_GT(at(kC + openvdb::Vec3d(0, 0, kR + 10 * kH)), 0.0f);    // far outside
}

TEST(LevelSetToMesh, IsovalueIsAWorldDistanceForALevelSet)
{
    const auto grid = exactSphere();
    LevelSetToMeshOptions o;
    o.isovalue = 1.5 * kH; // 1.5 voxels out, inside the band of 3
    const TriangleMesh mesh = levelSetToMesh(*grid, o);
    EXPECT_LT(worstVertexError(mesh, kR + 1.5 * kH), 0.05);
    EXPECT_EQ(badEdges(mesh), 0u);
    o.isovalue = -1.5 * kH;
    EXPECT_LT(worstVertexError(levelSetToMesh(*grid, o), kR - 1.5 * kH), 0.05);
}

TEST(LevelSetToMesh, AdaptivityGivesFewerTrianglesWithBoundedError)
{
    const auto grid = exactSphere();
    const TriangleMesh uniform = levelSetToMesh(*grid, LevelSetToMeshOptions());
    const double exact = 4.0 / 3.0 * M_PI * kR * kR * kR;
    size_t previous = uniform.triangleCount();
    // measured (r = 20 voxels): triangles, worst vertex distance to the sphere, volume
    for (const double adaptivity : {0.01, 0.05, 0.2}) {
        SCOPED_TRACE(adaptivity);
        LevelSetToMeshOptions o;
        o.adaptivity = adaptivity;
        const TriangleMesh adaptive = levelSetToMesh(*grid, o);
        const double worst = worstVertexError(adaptive, kR);
        const double volume = signedVolume(adaptive) / exact;
        std::printf("adaptivity %.2f: %zu triangles (uniform %zu), worst vertex %.4f voxel off the sphere, volume %.4f "
                    "of the sphere's\n",
                    adaptivity, adaptive.triangleCount(), uniform.triangleCount(), worst, volume);
        EXPECT_LT(adaptive.triangleCount(), previous);
        previous = adaptive.triangleCount();
        EXPECT_LT(worst, 0.5);
        EXPECT_GT(volume, 0.9);
        EXPECT_LT(volume, 1.0 + 1e-3);
    }
}

TEST(LevelSetToMesh, FogVolumeAtIsoOneHalfIsOutwardToo)
{
    openvdb::initialize();
    // A fog sphere: density 1 inside, 0 outside, a linear ramp 0.5 - d / (4h) across the surface,
    // so the 0.5 isosurface is the sphere itself.
    auto fog = openvdb::FloatGrid::create(0.0f);
    fog->setTransform(openvdb::math::Transform::createLinearTransform(kH));
    fog->setGridClass(openvdb::GRID_FOG_VOLUME);
    fog->setName("density");
    auto acc = fog->getAccessor();
    const int n = int(std::ceil((kR + 4 * kH) / kH)) + 4;
    const openvdb::Coord c0 = openvdb::Coord::round(fog->worldToIndex(kC));
    for (int i = -n; i <= n; ++i)
        for (int j = -n; j <= n; ++j)
            for (int k = -n; k <= n; ++k) {
                const openvdb::Coord ijk = c0 + openvdb::Coord(i, j, k);
                const double d = (fog->indexToWorld(ijk) - kC).length() - kR;
                const double rho = std::clamp(0.5 - d / (4 * kH), 0.0, 1.0);
                if (rho > 0.0) acc.setValue(ijk, float(rho));
            }
    LevelSetToMeshOptions o;
    o.isovalue = 0.5;
    const TriangleMesh mesh = levelSetToMesh(*fog, o);
    ASSERT_FALSE(mesh.empty());
    EXPECT_LT(worstVertexError(mesh, kR), 0.05);
    EXPECT_EQ(badEdges(mesh), 0u);
    EXPECT_NEAR(signedVolume(mesh) / (4.0 / 3.0 * M_PI * kR * kR * kR), 1.0, 0.01);
}

TEST(LevelSetToMesh, BoxFacesAreFlatAndOutward)
{
    // levelforge's own exact level set of a box mesh; the mesh of its zero crossing lies on the
    // box's faces (linear interpolation is exact for a plane) away from edges and corners.
    const TriangleMesh box = makeBox(Vec3d(-0.52, -0.31, -0.44), Vec3d(0.47, 0.36, 0.41));
    MeshToLevelSetOptions o;
    o.voxelSize = kH;
    const auto grid = meshToLevelSet(box, o);
    const TriangleMesh mesh = levelSetToMesh(*grid, LevelSetToMeshOptions());
    EXPECT_EQ(badEdges(mesh), 0u);
    size_t checked = 0;
    for (const Vec3d& p : mesh.points) {
        // the distance to the box surface (exact for points near it)
        double inside = 1e9, outside = 0.0;
        for (int a = 0; a < 3; ++a) {
            const double lo = box.bounds().min()[a], hi = box.bounds().max()[a];
            inside = std::min({inside, p[a] - lo, hi - p[a]});
            outside += std::pow(std::max({0.0, lo - p[a], p[a] - hi}), 2);
        }
        const double d = outside > 0.0 ? std::sqrt(outside) : -inside;
        // faces only: at least 2 voxels from every other face plane
        int nearPlanes = 0;
        for (int a = 0; a < 3; ++a) {
            const double lo = box.bounds().min()[a], hi = box.bounds().max()[a];
            nearPlanes += (std::abs(p[a] - lo) < 2 * kH) + (std::abs(p[a] - hi) < 2 * kH);
        }
        if (nearPlanes != 1) continue;
        ++checked;
        EXPECT_LT(std::abs(d) / kH, 1e-3) << p;
    }
    EXPECT_GT(checked, 100u);
    const Vec3d e = box.bounds().extents();
    EXPECT_NEAR(signedVolume(mesh) / (e[0] * e[1] * e[2]), 1.0, 0.02); // edges and corners are cut
}

TEST(LevelSetToMesh, EmptyGridGivesAnEmptyMesh)
{
    openvdb::initialize();
    auto grid = openvdb::FloatGrid::create(3.0f * float(kH));
    grid->setGridClass(openvdb::GRID_LEVEL_SET);
    EXPECT_TRUE(levelSetToMesh(*grid, LevelSetToMeshOptions()).empty());
}

TEST(LevelSetToMesh, BadOptionsAndInterruption)
{
    const auto grid = exactSphere();
    LevelSetToMeshOptions o;
    o.adaptivity = 1.5;
    EXPECT_THROW(levelSetToMesh(*grid, o), InvalidArgumentError);
    o.adaptivity = -0.1;
    EXPECT_THROW(levelSetToMesh(*grid, o), InvalidArgumentError);
    o.adaptivity = 0.0;
    o.isovalue = std::nan("");
    EXPECT_THROW(levelSetToMesh(*grid, o), InvalidArgumentError);
    o.isovalue = 0.0;
    StopAtOnce stop;
    o.interrupter = &stop;
    EXPECT_THROW(levelSetToMesh(*grid, o), InterruptedError);
}
