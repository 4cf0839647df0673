// SPDX-License-Identifier: Apache-2.0
// Microtriangle voxelization must find every cell a triangle overlaps (Chang et al. §3.1).
#include "TestUtil.h"

#include <levelforge/io/MeshIO.h>
#include <levelforge/reference/MeshShapes.h>
#include <levelforge/mesh/MicrotriangleVoxelizer.h>

#include <algorithm>
#include <cmath>
#include <set>

using namespace levelforge;
using openvdb::math::Coord;

namespace {

/// Brute force: every cell in the triangle's AABB whose slightly shrunk box the triangle meets
/// (strict SAT with tolerance -1e-7: cells merely touched on a face/edge/corner do not count).
std::vector<Coord> bruteForceCells(const Vec3d& a, const Vec3d& b, const Vec3d& c, double tolerance)
{
    std::vector<Coord> out;
    const Vec3d lo = minComponent(minComponent(a, b), c), hi = maxComponent(maxComponent(a, b), c);
    for (int x = int(std::floor(lo[0])) - 1; x <= int(std::floor(hi[0])) + 1; ++x)
        for (int y = int(std::floor(lo[1])) - 1; y <= int(std::floor(hi[1])) + 1; ++y)
            for (int z = int(std::floor(lo[2])) - 1; z <= int(std::floor(hi[2])) + 1; ++z)
                if (triangleBoxOverlap(Vec3d(x + 0.5, y + 0.5, z + 0.5), Vec3d(0.5), a, b, c, tolerance))
                    out.emplace_back(x, y, z);
    return out;
}

/// Checks voxelization of every triangle of `mesh` scaled by `scale` (cell space) against brute
/// force: no missed cell, and no reported cell farther than 1e-6 cell from the triangle.
void checkMesh(const TriangleMesh& mesh, double scale, const Vec3d& shift, VoxelizerCounters* counters = nullptr)
{
    std::vector<Coord> cells;
    uint64_t missed = 0, extra = 0, total = 0;
    for (size_t t = 0; t < mesh.triangles.size(); ++t) {
        const Vec3I& tri = mesh.triangles[t];
        const Vec3d a = mesh.points[tri[0]] * scale + shift, b = mesh.points[tri[1]] * scale + shift,
                    c = mesh.points[tri[2]] * scale + shift;
        if ((b - a).cross(c - a).lengthSqr() == 0.0) continue;
        cells.clear();
        voxelizeTriangle(a, b, c, cells, counters);
        std::sort(cells.begin(), cells.end());
        ASSERT_TRUE(std::adjacent_find(cells.begin(), cells.end()) == cells.end());
        const std::vector<Coord> must = bruteForceCells(a, b, c, -1e-7);
        for (const Coord& q : must)
            if (!std::binary_search(cells.begin(), cells.end(), q)) ++missed;
        const std::vector<Coord> may = bruteForceCells(a, b, c, 1e-6);
        for (const Coord& q : cells)
            if (!std::binary_search(may.begin(), may.end(), q)) ++extra;
        total += must.size();
    }
    EXPECT_EQ(missed, 0u) << "cells missed out of " << total << " (" << mesh.source << ", scale " << scale << ")";
    EXPECT_EQ(extra, 0u) << "cells reported that the triangle does not touch (" << mesh.source << ")";
}

} // namespace

TEST(MicrotriangleVoxelizer, SingleCellAndCounters)
{
    std::vector<Coord> cells;
    VoxelizerCounters c;
    voxelizeTriangle(Vec3d(0.2, 0.2, 0.2), Vec3d(0.7, 0.3, 0.2), Vec3d(0.3, 0.8, 0.6), cells, &c);
    ASSERT_EQ(cells.size(), 1u);
    EXPECT_EQ(cells[0], Coord(0, 0, 0));
    EXPECT_EQ(c.microtriangles, 1u);
    EXPECT_EQ(c.cases[0], 1u); // I = 3
}

TEST(MicrotriangleVoxelizer, CaseFourCornerCut)
{
    // A triangle slicing the corner region of a 2x2x2 block: its vertices lie in three cells,
    // it must also be found in the cells its interior crosses.
    std::vector<Coord> cells;
    VoxelizerCounters c;
    const Vec3d a(0.05, 1.2, 1.3), b(1.3, 0.05, 1.2), d(1.2, 1.3, 0.05);
    voxelizeTriangle(a, b, d, cells, &c);
    std::sort(cells.begin(), cells.end());
    const auto must = bruteForceCells(a, b, d, -1e-7);
    for (const Coord& q : must) EXPECT_TRUE(std::binary_search(cells.begin(), cells.end(), q)) << q;
    EXPECT_GT(c.cases[3], 0u);
}

TEST(MicrotriangleVoxelizer, RandomTrianglesFindEveryCell)
{
    // Small to large triangles (minification and magnification), random orientation.
    for (double maxEdge : {0.7, 1.5, 4.0, 13.0}) {
        const TriangleMesh soup = makeRandomTriangles(1500, 42 + uint64_t(maxEdge * 10), BBoxd(Vec3d(-20.0), Vec3d(20.0)), maxEdge);
        VoxelizerCounters c;
        checkMesh(soup, 1.0, Vec3d(0.0), &c);
        EXPECT_EQ(c.cases[0] + c.cases[1] + c.cases[2] + c.cases[3], c.microtriangles);
    }
}

TEST(MicrotriangleVoxelizer, AxisAlignedAndGridAlignedTriangles)
{
    // Vertices exactly on cell boundaries and triangles inside cell faces: the hard cases for
    // floor-based classification.
    TriangleMesh m;
    m.source = "<grid-aligned>";
    const Vec3d pts[] = {{0, 0, 0}, {3, 0, 0}, {0, 3, 0}, {0, 0, 3}, {2, 2, 0}, {1, 1, 1}, {2.5, 0.5, 0.5}, {0.5, 2.5, 2}};
    for (const Vec3d& p : pts) m.points.push_back(p);
    m.triangles = {{0, 1, 2}, {0, 1, 3}, {0, 2, 3}, {1, 2, 3}, {0, 4, 5}, {5, 6, 7}, {4, 6, 7}};
    checkMesh(m, 1.0, Vec3d(0.0));
    checkMesh(m, 1.0, Vec3d(0.5));
}

TEST(MicrotriangleVoxelizer, ClosedShapesAtSeveralResolutions)
{
    const TriangleMesh knot = makeTorusKnot(2, 3, 1.0, 0.25, 96, 12);
    for (double scale : {7.3, 20.0, 61.7}) checkMesh(knot, scale, Vec3d(0.37, -0.21, 0.05));
    checkMesh(makeBox(Vec3d(-1.0), Vec3d(1.0), 3), 9.0, Vec3d(0.0));
}

TEST(MicrotriangleVoxelizer, RealMeshIfPresent)
{
    LEVELFORGE_SHARED_FILE_OR_SKIP(path, "meshes/watertight/fandisk.obj");
    const TriangleMesh mesh = readMesh(path);
    const BBoxd b = mesh.bounds();
    const double scale = 160.0 / b.extents()[b.maxExtent()];
    checkMesh(mesh, scale, -b.min() * scale);
}
