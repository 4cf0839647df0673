// SPDX-License-Identifier: Apache-2.0
// Microtriangle voxelization must find every cell a triangle overlaps (Chang et al. §3.1).
#include "TestUtil.h"

#include <levelforge/io/MeshIO.h>
#include <levelforge/reference/MeshShapes.h>
#include <levelforge/mesh/MicrotriangleVoxelizer.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <set>
#include <utility>

using namespace levelforge;
using openvdb::math::Coord;

namespace {

/// Independent oracle (it shares no code with the library's separating-axis test): clip the
/// triangle against the box, one axis-aligned plane at a time (Sutherland–Hodgman); the two
/// overlap iff a non-empty polygon remains. The box is cell [x, x+1] x [y, y+1] x [z, z+1] grown
/// by `tolerance` on every side (< 0 shrinks it: cells merely touched on a face, edge or corner
/// then do not count; > 0 also counts cells missed by at most that much). The clipping is done
/// hierarchically (x slab, then y, then z), so only cells whose slabs the triangle reaches are
/// visited; intersection points are put exactly on their plane.
using Polygon = std::vector<Vec3d>;

/// Keeps the part of `in` with sign * (p[axis] - bound) >= 0.
void clipPlane(const Polygon& in, int axis, double bound, double sign, Polygon& out)
{
    out.clear();
    const size_t n = in.size();
    for (size_t i = 0; i < n; ++i) {
        const Vec3d& p = in[i];
        const Vec3d& q = in[(i + 1) % n];
        const double dp = sign * (p[axis] - bound), dq = sign * (q[axis] - bound);
        if (dp >= 0) out.push_back(p);
        if ((dp >= 0) != (dq >= 0)) {
            Vec3d x = p + (q - p) * (dp / (dp - dq));
            x[axis] = bound;
            out.push_back(x);
        }
    }
}

/// The part of `in` inside the slab [lo, hi] along `axis`.
void clipSlab(const Polygon& in, int axis, double lo, double hi, Polygon& tmp, Polygon& out)
{
    clipPlane(in, axis, lo, 1.0, tmp);
    clipPlane(tmp, axis, hi, -1.0, out);
}

std::vector<Coord> bruteForceCells(const Vec3d& a, const Vec3d& b, const Vec3d& c, double tolerance)
{
    std::vector<Coord> out;
    const Polygon tri{a, b, c};
    Polygon px, pxy, pxyz, tmp;
    auto range = [](const Polygon& p, int axis) {
        double lo = p[0][axis], hi = p[0][axis];
        for (const Vec3d& v : p) lo = std::min(lo, v[axis]), hi = std::max(hi, v[axis]);
        return std::make_pair(int(std::floor(lo)) - 1, int(std::floor(hi)) + 1);
    };
    const auto xr = range(tri, 0);
    for (int x = xr.first; x <= xr.second; ++x) {
        clipSlab(tri, 0, x - tolerance, x + 1 + tolerance, tmp, px);
        if (px.empty()) continue;
        const auto yr = range(px, 1);
        for (int y = yr.first; y <= yr.second; ++y) {
            clipSlab(px, 1, y - tolerance, y + 1 + tolerance, tmp, pxy);
            if (pxy.empty()) continue;
            const auto zr = range(pxy, 2);
            for (int z = zr.first; z <= zr.second; ++z) {
                clipSlab(pxy, 2, z - tolerance, z + 1 + tolerance, tmp, pxyz);
                if (!pxyz.empty()) out.emplace_back(x, y, z);
            }
        }
    }
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
        std::vector<Coord> may = bruteForceCells(a, b, c, 1e-6);
        std::sort(may.begin(), may.end());
        for (const Coord& q : cells)
            if (!std::binary_search(may.begin(), may.end(), q)) ++extra;
        total += must.size();
    }
    EXPECT_EQ(missed, 0u) << "cells missed out of " << total << " (" << mesh.source << ", scale " << scale << ")";
    EXPECT_EQ(extra, 0u) << "cells reported that the triangle does not touch (" << mesh.source << ")";
    std::printf("  %s (scale %g): %zu triangles, %llu cells, %llu missed, %llu extra\n", mesh.source.c_str(), scale,
                mesh.triangles.size(), (unsigned long long)total, (unsigned long long)missed, (unsigned long long)extra);
}

} // namespace

TEST(MicrotriangleVoxelizer, ClippingOracleItself)
{
    // the oracle on cases whose answer is known by hand
    using V = std::vector<Coord>;
    EXPECT_EQ(bruteForceCells(Vec3d(0.2, 0.2, 0.2), Vec3d(0.7, 0.3, 0.2), Vec3d(0.3, 0.8, 0.6), -1e-7), V{Coord(0, 0, 0)});
    // a triangle inside the face x = 1 between cells (0,0,0) and (1,0,0): touched only
    const Vec3d a(1, 0.2, 0.2), b(1, 0.8, 0.2), c(1, 0.5, 0.9);
    EXPECT_TRUE(bruteForceCells(a, b, c, -1e-7).empty());
    EXPECT_EQ(bruteForceCells(a, b, c, 1e-6), (V{Coord(0, 0, 0), Coord(1, 0, 0)}));
    // a right triangle in the plane z = 0.5 whose hypotenuse x + y = 2 passes through the corner
    // (1, 1) of cell (1, 1, 0): three cells strictly, the fourth only within the tolerance
    const Vec3d p(0.5, 0.5, 0.5), q(1.5, 0.5, 0.5), r(0.5, 1.5, 0.5);
    EXPECT_EQ(bruteForceCells(p, q, r, -1e-7), (V{Coord(0, 0, 0), Coord(0, 1, 0), Coord(1, 0, 0)}));
    EXPECT_EQ(bruteForceCells(p, q, r, 1e-6), (V{Coord(0, 0, 0), Coord(0, 1, 0), Coord(1, 0, 0), Coord(1, 1, 0)}));
}

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
    checkMesh(makeBox(Vec3d(-1.0), Vec3d(1.0), 3), 9.0, Vec3d(0.0)); // faces on cell faces: nothing strictly required
    checkMesh(makeBox(Vec3d(-1.0), Vec3d(1.0), 3), 9.0, Vec3d(0.31, 0.17, 0.05));
}

TEST(MicrotriangleVoxelizer, RealMeshIfPresent)
{
    LEVELFORGE_SHARED_FILE_OR_SKIP(path, "meshes/watertight/fandisk.obj");
    const TriangleMesh mesh = readMesh(path);
    const BBoxd b = mesh.bounds();
    const double scale = 160.0 / b.extents()[b.maxExtent()];
    checkMesh(mesh, scale, -b.min() * scale);
}

namespace {

/// A unit vector perpendicular to `d`.
Vec3d perpendicular(const Vec3d& d)
{
    const Vec3d t = std::abs(d[0]) < 0.9 ? Vec3d(1, 0, 0) : Vec3d(0, 1, 0);
    Vec3d p = d.cross(t);
    p.normalize();
    return p;
}

Vec3d randomUnit(std::mt19937_64& rng)
{
    std::normal_distribution<double> g(0.0, 1.0);
    Vec3d v(g(rng), g(rng), g(rng));
    v.normalize();
    return v;
}

} // namespace

TEST(MicrotriangleVoxelizer, SliverTriangles)
{
    // Slivers: the third vertex lies next to the middle of the opposite edge (an angle close to
    // 180°), offset by 1e-2 .. 1e-8 of the edge, edges from half a cell to 60 cells, random
    // orientation and position; some with the edge's ends on cell corners.
    std::mt19937_64 rng(2024);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    TriangleMesh m;
    m.source = "<slivers>";
    for (int i = 0; i < 600; ++i) {
        const double len = 0.5 * std::pow(120.0, u(rng));
        const Vec3d dir = randomUnit(rng);
        Vec3d a(u(rng) * 40 - 20, u(rng) * 40 - 20, u(rng) * 40 - 20);
        if (i % 4 == 0) a = Vec3d(std::round(a[0]), std::round(a[1]), std::round(a[2]));
        const Vec3d b = a + dir * len;
        const double offset = len * std::pow(10.0, -2.0 - 6.0 * u(rng));
        const Vec3d c = (a + b) * (0.3 + 0.4 * u(rng)) + perpendicular(dir) * offset; // not exactly the midpoint
        const Vec3d cc = a + (b - a) * (0.3 + 0.4 * u(rng)) + perpendicular(dir) * offset;
        const uint32_t base = uint32_t(m.points.size());
        m.points.push_back(a);
        m.points.push_back(b);
        m.points.push_back(i % 2 ? c * 0.5 + cc * 0.5 : cc);
        m.triangles.emplace_back(base, base + 1, base + 2);
    }
    checkMesh(m, 1.0, Vec3d(0.0));
}

TEST(MicrotriangleVoxelizer, NeedleTriangles)
{
    // Needles: hundreds of cells long, a tenth of a cell wide, along diagonals (the worst case
    // for a triangle's box: it spans hundreds of cells on every axis), both shapes: two long
    // edges and a short one (0.1 cell), and a long base with its apex 0.1 cell off it.
    TriangleMesh m;
    m.source = "<needles>";
    std::mt19937_64 rng(77);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    const Vec3d diagonals[] = {Vec3d(1, 1, 1), Vec3d(1, -1, 1), Vec3d(-1, 1, 1), Vec3d(1, 1, -1), Vec3d(1, 0.9, 1.1)};
    for (int i = 0; i < 20; ++i) {
        Vec3d dir = diagonals[i % 5] + randomUnit(rng) * (i < 5 ? 0.0 : 0.05);
        dir.normalize();
        const double len = 200.0 + 200.0 * u(rng);
        Vec3d a(u(rng) * 10, u(rng) * 10, u(rng) * 10);
        if (i % 3 == 0) a = Vec3d(std::round(a[0]), std::round(a[1]), std::round(a[2]));
        const Vec3d side = perpendicular(dir);
        const uint32_t base = uint32_t(m.points.size());
        m.points.push_back(a);
        if (i % 2 == 0) { // short edge of 0.1 cell at a, two long edges
            m.points.push_back(a + side * 0.1);
            m.points.push_back(a + dir * len);
        } else { // long base, apex 0.1 cell off it
            m.points.push_back(a + dir * len);
            m.points.push_back(a + dir * (len * (0.2 + 0.6 * u(rng))) + side * 0.1);
        }
        m.triangles.emplace_back(base, base + 1, base + 2);
    }
    checkMesh(m, 1.0, Vec3d(0.0));
    checkMesh(m, 1.0, Vec3d(0.5, 0.25, 0.125));
}

TEST(MicrotriangleVoxelizer, VertexFan)
{
    // 600 triangles around one vertex (a fan, as at a pole of a UV sphere): a flat tilted disc and
    // a shallow cone, the hub on a cell corner and at a generic point.
    for (bool cone : {false, true})
        for (const Vec3d& hub : {Vec3d(10.0, -4.0, 7.0), Vec3d(10.37, -4.21, 7.05)}) {
            TriangleMesh m;
            m.source = cone ? "<fan cone>" : "<fan disc>";
            const int n = 600;
            const double radius = 25.0;
            Vec3d axis(0.3, -0.5, 1.0);
            axis.normalize();
            const Vec3d e1 = perpendicular(axis), e2 = axis.cross(e1);
            m.points.push_back(hub);
            for (int i = 0; i < n; ++i) {
                const double t = 2.0 * M_PI * i / n;
                m.points.push_back(hub + (e1 * std::cos(t) + e2 * std::sin(t)) * radius + axis * (cone ? -0.3 * radius : 0.0));
            }
            for (int i = 0; i < n; ++i) m.triangles.emplace_back(0u, uint32_t(1 + i), uint32_t(1 + (i + 1) % n));
            checkMesh(m, 1.0, Vec3d(0.0));
        }
}
