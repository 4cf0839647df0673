// SPDX-License-Identifier: Apache-2.0
// Tests for MeshValidation.h: every count on small meshes built by hand, the fatal problems,
// the broken meshes of ../shared/data (skipped when absent), thread-count independence and speed.
#include "TestUtil.h"

#include <levelforge/core/Exceptions.h>
#include <levelforge/io/MeshIO.h>
#include <levelforge/reference/MeshShapes.h>
#include <levelforge/core/MeshValidation.h>

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cstdio>
#include <cmath>
#include <limits>
#include <string>

namespace {

using namespace levelforge;

/// Tetrahedron (0,0,0) (1,0,0) (0,1,0) (0,0,1), outward.
TriangleMesh tetrahedron(const Vec3d& offset = Vec3d(0.0))
{
    TriangleMesh m;
    m.points = {offset + Vec3d(0, 0, 0), offset + Vec3d(1, 0, 0), offset + Vec3d(0, 1, 0),
                offset + Vec3d(0, 0, 1)};
    m.triangles = {Vec3I(0, 2, 1), Vec3I(0, 1, 3), Vec3I(0, 3, 2), Vec3I(1, 2, 3)};
    m.source = "<tetrahedron>";
    return m;
}

/// Appends @a b to @a a (indices shifted).
void append(TriangleMesh& a, const TriangleMesh& b)
{
    const uint32_t base = uint32_t(a.points.size());
    a.points.insert(a.points.end(), b.points.begin(), b.points.end());
    for (const Vec3I& t : b.triangles) a.triangles.emplace_back(t[0] + base, t[1] + base, t[2] + base);
}

template<typename Fn>
std::string invalidMeshMessage(Fn&& fn)
{
    try {
        fn();
    } catch (const InvalidMeshError& e) {
        return e.what();
    }
    return "(no InvalidMeshError)";
}

size_t countLines(const std::string& s) { return size_t(std::count(s.begin(), s.end(), '\n')) + 1; }

} // namespace

TEST(MeshValidation, ClosedTetrahedron)
{
    const MeshReport r = validateMesh(tetrahedron());
    EXPECT_TRUE(r.closed());
    EXPECT_EQ(r.vertices, 4u);
    EXPECT_EQ(r.triangles, 4u);
    EXPECT_EQ(r.edges, 6u);
    EXPECT_EQ(r.components, 1u);
    EXPECT_EQ(r.eulerCharacteristic(), 2);
    EXPECT_EQ(r.boundaryEdges + r.nonManifoldEdges + r.inconsistentlyOrientedEdges, 0u);
    EXPECT_EQ(r.degenerateTriangles + r.unusedVertices + r.nonManifoldVertices, 0u);
    EXPECT_TRUE(r.findings().empty());
    EXPECT_TRUE(r.warnings().empty());
    EXPECT_EQ(countLines(r.summary()), 1u);
    EXPECT_NE(r.summary().find("<tetrahedron>"), std::string::npos);
    EXPECT_NE(r.summary().find("closed"), std::string::npos);
    EXPECT_GT(signedVolume(tetrahedron()), 0.0);
}

TEST(MeshValidation, OpenSurfaceHasBoundaryEdges)
{
    TriangleMesh m = tetrahedron();
    m.triangles.pop_back(); // remove face 1-2-3
    const MeshReport r = validateMesh(m);
    EXPECT_FALSE(r.closed());
    EXPECT_EQ(r.boundaryEdges, 3u);
    ASSERT_EQ(r.boundaryEdgeExamples.size(), 3u);
    EXPECT_EQ(r.boundaryEdgeExamples[0], Vec3I(1, 2, 0));
    EXPECT_EQ(r.boundaryEdgeExamples[1], Vec3I(1, 3, 0));
    EXPECT_EQ(r.boundaryEdgeExamples[2], Vec3I(2, 3, 0));
    EXPECT_EQ(r.inconsistentlyOrientedEdges, 0u);

    TriangleMesh single;
    single.points = {Vec3d(0, 0, 0), Vec3d(1, 0, 0), Vec3d(0, 1, 0)};
    single.triangles = {Vec3I(0, 1, 2)};
    EXPECT_EQ(validateMesh(single).boundaryEdges, 3u);
}

TEST(MeshValidation, FlippedTriangleGivesInconsistentEdges)
{
    TriangleMesh m = tetrahedron();
    std::swap(m.triangles[3][1], m.triangles[3][2]);
    const MeshReport r = validateMesh(m);
    EXPECT_FALSE(r.closed());
    EXPECT_EQ(r.inconsistentlyOrientedEdges, 3u);
    EXPECT_EQ(r.boundaryEdges, 0u);
    EXPECT_EQ(r.nonManifoldEdges, 0u);
    EXPECT_NE(r.summary().find("3 inconsistently oriented edges"), std::string::npos) << r.summary();
}

TEST(MeshValidation, NonManifoldEdgesAndPinchedVertices)
{
    // A fin: three triangles on edge 0-1.
    TriangleMesh fin;
    fin.points = {Vec3d(0, 0, 0), Vec3d(1, 0, 0), Vec3d(0, 1, 0), Vec3d(0, -1, 0), Vec3d(0, 0, 1)};
    fin.triangles = {Vec3I(0, 1, 2), Vec3I(1, 0, 3), Vec3I(0, 1, 4)};
    const MeshReport f = validateMesh(fin);
    EXPECT_EQ(f.nonManifoldEdges, 1u);
    ASSERT_EQ(f.nonManifoldEdgeExamples.size(), 1u);
    EXPECT_EQ(f.nonManifoldEdgeExamples[0], Vec3I(0, 1, 3)); // edge 0-1, 3 triangles
    EXPECT_FALSE(f.closed());

    // Two tetrahedra sharing only vertex 0: closed, but vertex 0 is pinched.
    TriangleMesh pinch = tetrahedron();
    TriangleMesh other = tetrahedron();
    for (Vec3d& p : other.points) p = -p; // point reflection keeps the shared vertex at 0...
    for (Vec3I& t : other.triangles) std::swap(t[1], t[2]); // ...and flips the winding back
    append(pinch, other);
    for (Vec3I& t : pinch.triangles) {
        for (int k = 0; k < 3; ++k) {
            if (t[k] == 4) t[k] = 0; // weld the two apexes
        }
    }
    const MeshReport p = validateMesh(pinch);
    EXPECT_TRUE(p.closed());
    EXPECT_EQ(p.nonManifoldVertices, 1u);
    ASSERT_EQ(p.nonManifoldVertexIds.size(), 1u);
    EXPECT_EQ(p.nonManifoldVertexIds[0], 0u);
    EXPECT_EQ(p.unusedVertices, 1u); // the welded-away copy
    EXPECT_EQ(p.components, 1u);
    EXPECT_EQ(p.eulerCharacteristic(), 3);
    EXPECT_GT(signedVolume(pinch), 0.0);
}

TEST(MeshValidation, DegenerateTrianglesAndUnusedVertices)
{
    // A closed tetrahedron, two unused vertices, and apart from it a collinear (zero-area)
    // triangle and a collapsed one (repeated index).
    TriangleMesh m = tetrahedron();
    m.points.push_back(Vec3d(0.5, 0.5, 0.0)); // 4: unused
    m.points.push_back(Vec3d(7, 7, 7));       // 5: unused
    m.points.push_back(Vec3d(0, 0, 5));       // 6
    m.points.push_back(Vec3d(1, 0, 5));       // 7
    m.points.push_back(Vec3d(2, 0, 5));       // 8
    m.triangles.push_back(Vec3I(6, 7, 8));    // triangle 4: collinear
    m.triangles.push_back(Vec3I(6, 6, 7));    // triangle 5: collapsed
    const MeshReport r = validateMesh(m);
    EXPECT_EQ(r.degenerateTriangles, 2u);
    EXPECT_EQ(r.collapsedTriangles, 1u);
    ASSERT_EQ(r.degenerateTriangleIds.size(), 2u);
    EXPECT_EQ(r.degenerateTriangleIds[0], 4u);
    EXPECT_EQ(r.degenerateTriangleIds[1], 5u);
    EXPECT_EQ(r.unusedVertices, 2u);
    EXPECT_EQ(r.boundaryEdges, 3u); // the collinear triangle's edges; the collapsed one has none
    EXPECT_EQ(r.components, 2u);
    EXPECT_EQ(r.findings().size(), 3u); // boundary, degenerate, unused
    EXPECT_EQ(countLines(r.summary()), 4u);
    for (const std::string& w : r.warnings()) EXPECT_EQ(w.rfind("<tetrahedron>: ", 0), 0u) << w;

    uint64_t removed = 0;
    const TriangleMesh clean = withoutDegenerateTriangles(m, &removed);
    EXPECT_EQ(removed, 2u);
    EXPECT_EQ(clean.triangles.size(), 4u);
    EXPECT_EQ(clean.points.size(), m.points.size());
    EXPECT_TRUE(validateMesh(clean).closed());

    EXPECT_TRUE(isDegenerateTriangle(Vec3d(0, 0, 0), Vec3d(1, 0, 0), Vec3d(3, 0, 0)));
    EXPECT_TRUE(isDegenerateTriangle(Vec3d(1, 2, 3), Vec3d(1, 2, 3), Vec3d(1, 2, 3)));
    EXPECT_FALSE(isDegenerateTriangle(Vec3d(0, 0, 0), Vec3d(1, 0, 0), Vec3d(0.5, 1e-6, 0)));
}

TEST(MeshValidation, ZeroAreaSliverKeepsAClosedMeshClosed)
{
    // Split tetrahedron face (0,2,1) at the midpoint 4 of edge 1-2 without splitting the
    // neighbour (1,2,3): the gap is the zero-area sliver (2,1,4), and the mesh stays closed
    // (like openscad_issue1580-zero-area-triangle.stl).
    TriangleMesh m = tetrahedron();
    m.points.push_back(Vec3d(0.5, 0.5, 0.0)); // 4
    m.triangles = {Vec3I(0, 2, 4), Vec3I(0, 4, 1), Vec3I(0, 1, 3), Vec3I(0, 3, 2), Vec3I(1, 2, 3),
                   Vec3I(2, 1, 4)};
    const MeshReport r = validateMesh(m);
    EXPECT_TRUE(r.closed()) << r.summary();
    EXPECT_EQ(r.degenerateTriangles, 1u);
    EXPECT_EQ(r.degenerateTriangleIds, std::vector<uint32_t>{5u});
    EXPECT_EQ(r.nonManifoldVertices, 0u);
    EXPECT_EQ(r.eulerCharacteristic(), 2);
    EXPECT_NEAR(signedVolume(m), 1.0 / 6.0, 1e-15);
}

TEST(MeshValidation, ComponentsCountSeparateParts)
{
    TriangleMesh m = tetrahedron();
    append(m, tetrahedron(Vec3d(5, 0, 0)));
    append(m, tetrahedron(Vec3d(0, 5, 0)));
    const MeshReport r = validateMesh(m);
    EXPECT_TRUE(r.closed());
    EXPECT_EQ(r.components, 3u);
    EXPECT_EQ(r.eulerCharacteristic(), 6);
}

TEST(MeshValidation, FatalProblemsThrowWithSourceAndElement)
{
    TriangleMesh empty;
    empty.source = "empty.obj";
    std::string msg = invalidMeshMessage([&] { validateMesh(empty); });
    EXPECT_NE(msg.find("empty.obj"), std::string::npos) << msg;
    EXPECT_NE(msg.find("no triangles"), std::string::npos) << msg;

    TriangleMesh nan = tetrahedron();
    nan.source = "nan.obj";
    nan.points[2][1] = std::numeric_limits<double>::quiet_NaN();
    msg = invalidMeshMessage([&] { validateMesh(nan); });
    EXPECT_NE(msg.find("nan.obj"), std::string::npos) << msg;
    EXPECT_NE(msg.find("vertex 2"), std::string::npos) << msg;

    TriangleMesh inf = tetrahedron();
    inf.points[3][0] = -std::numeric_limits<double>::infinity();
    msg = invalidMeshMessage([&] { validateMesh(inf); });
    EXPECT_NE(msg.find("<tetrahedron>"), std::string::npos) << msg;
    EXPECT_NE(msg.find("vertex 3"), std::string::npos) << msg;

    TriangleMesh bad = tetrahedron();
    bad.triangles[1][2] = 17;
    msg = invalidMeshMessage([&] { validateMesh(bad); });
    EXPECT_NE(msg.find("triangle 1"), std::string::npos) << msg;
    EXPECT_NE(msg.find("17"), std::string::npos) << msg;
    EXPECT_NE(msg.find("4 vertices"), std::string::npos) << msg;
}

TEST(MeshValidation, ResultsDoNotDependOnThreadCount)
{
    TriangleMesh m = makeRandomTriangles(20000, 7, BBoxd(Vec3d(0.0), Vec3d(1.0)), 0.05);
    append(m, makeTorus(Vec3d(3.0), 1.0, 0.3, 200, 40));
    m.triangles.push_back(Vec3I(0, 1, 1));
    MeshReport serial;
    {
        tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
        serial = validateMesh(m);
    }
    const MeshReport parallel = validateMesh(m);
    EXPECT_EQ(serial.summary(), parallel.summary());
    EXPECT_EQ(serial.boundaryEdgeExamples, parallel.boundaryEdgeExamples);
    EXPECT_EQ(serial.components, 20001u);
    EXPECT_EQ(serial.boundaryEdges, 60000u);
}

TEST(MeshValidation, FastOnMillionsOfTriangles)
{
    const TriangleMesh torus = makeTorus(Vec3d(0.0), 2.0, 0.5, 1000, 800); // 1.6 M triangles
    ASSERT_EQ(torus.triangles.size(), 1600000u);
    const auto t0 = std::chrono::steady_clock::now();
    const MeshReport r = validateMesh(torus);
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::printf("validateMesh: 1.6 M triangles in %.3f s\n", seconds);
    EXPECT_TRUE(r.closed());
    EXPECT_EQ(r.edges, 2400000u);
    EXPECT_EQ(r.eulerCharacteristic(), 0);
    EXPECT_LT(seconds, 10.0); // ~0.2 s on one core; generous for loaded CI machines
}

// ------------------------------------------------------------------------ real broken meshes

namespace {

struct Expected
{
    const char* file;
    bool closed;
    uint64_t boundary, nonManifold, inconsistent, degenerate, unused, components;
};

// Counts as measured (and, where it says so, as ../shared/data/README.md states).
const Expected kExpected[] = {
    // README: holes in the base (223 boundary edges), 1113 unused vertices.
    {"meshes/open_or_broken/bunny.obj", false, 223, 0, 0, 0, 1113, 1},
    // README: quads, 3 parts, open eyes (42 boundary edges).
    {"meshes/open_or_broken/suzanne.obj", false, 42, 0, 0, 0, 0, 3},
    // README: 4 open parts (1036 boundary edges).
    {"meshes/open_or_broken/teapot.obj", false, 1036, 0, 0, 0, 0, 4},
    // README: large holes (1353 boundary edges).
    {"meshes/open_or_broken/cgal_elephant-with-holes.off", false, 1353, 0, 0, 0, 0, 1},
    // README: 19 parts, open, 10 edges wound the wrong way; also 56 zero-area triangles.
    {"meshes/open_or_broken/assimp_spider.obj", false, 96, 0, 10, 56, 0, 19},
    // README: 100 loose triangles.
    {"meshes/open_or_broken/trimesh_soup.stl", false, 300, 0, 0, 0, 0, 100},
    // README: two tetrahedra sharing a face's edges: the 3 edges of the shared face carry 4
    // triangles each.
    {"meshes/open_or_broken/trimesh_joined_tetrahedra.obj", false, 0, 3, 0, 0, 0, 1},
    // README: closed, with a zero-area triangle.
    {"meshes/open_or_broken/openscad_issue1580-zero-area-triangle.stl", true, 0, 0, 0, 1, 0, 1},
    {"meshes/watertight/spot.obj", true, 0, 0, 0, 0, 0, 1},
    {"meshes/watertight/cow.obj", true, 0, 0, 0, 0, 0, 1},
    {"meshes/watertight/fandisk.obj", true, 0, 0, 0, 0, 0, 1},
    {"meshes/watertight/elephant.off", true, 0, 0, 0, 0, 0, 1},
    {"meshes/watertight/fertility.off", true, 0, 0, 0, 0, 0, 1},
    {"meshes/watertight/3holes_genus3.off", true, 0, 0, 0, 0, 0, 1},
    {"meshes/watertight/chess_pawn.stl", true, 0, 0, 0, 0, 0, 2},
    {"meshes/watertight/chess_knight_decimated.off", true, 0, 0, 0, 0, 0, 1},
    {"meshes/watertight/armadillo_100k.obj", true, 0, 0, 0, 0, 0, 1},
    {"meshes/watertight/dragon_100k.obj", true, 0, 0, 0, 0, 0, 1},
    {"meshes/watertight/lucy_100k.obj", true, 0, 0, 0, 0, 0, 1},
};

class MeshValidationRealMesh : public ::testing::TestWithParam<Expected> {};

} // namespace

TEST_P(MeshValidationRealMesh, CountsAsMeasured)
{
    const Expected& x = GetParam();
    LEVELFORGE_SHARED_FILE_OR_SKIP(path, x.file);
    const MeshReport r = validateMesh(readMesh(path));
    EXPECT_EQ(r.closed(), x.closed) << r.summary();
    EXPECT_EQ(r.boundaryEdges, x.boundary);
    EXPECT_EQ(r.nonManifoldEdges, x.nonManifold);
    EXPECT_EQ(r.inconsistentlyOrientedEdges, x.inconsistent);
    EXPECT_EQ(r.degenerateTriangles, x.degenerate);
    EXPECT_EQ(r.unusedVertices, x.unused);
    EXPECT_EQ(r.components, x.components);
    EXPECT_NE(r.summary().find(path), std::string::npos);
    EXPECT_EQ(r.findings().size() + 1, countLines(r.summary()));
}

INSTANTIATE_TEST_SUITE_P(SharedData, MeshValidationRealMesh, ::testing::ValuesIn(kExpected),
    [](const ::testing::TestParamInfo<Expected>& info) {
        std::string name = std::string(info.param.file);
        name = name.substr(name.rfind('/') + 1);
        name = name.substr(0, name.rfind('.'));
        for (char& c : name) {
            if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
        }
        return name;
    });

TEST(MeshValidation, CowHasOnePinchedVertex)
{
    // cow.obj is watertight, yet its Euler characteristic is odd: two sheets touch at one vertex.
    LEVELFORGE_SHARED_FILE_OR_SKIP(path, "meshes/watertight/cow.obj");
    const MeshReport r = validateMesh(readMesh(path));
    EXPECT_TRUE(r.closed());
    EXPECT_EQ(r.nonManifoldVertices, 1u);
    EXPECT_EQ(r.eulerCharacteristic(), 1);
}

TEST(MeshValidation, SpiderWrongWindingIsReported)
{
    LEVELFORGE_SHARED_FILE_OR_SKIP(path, "meshes/open_or_broken/assimp_spider.obj");
    const MeshReport r = validateMesh(readMesh(path));
    EXPECT_EQ(r.inconsistentlyOrientedEdges, 10u);
    EXPECT_EQ(r.inconsistentEdgeExamples.size(), 10u);
    EXPECT_NE(r.summary().find("10 inconsistently oriented edges"), std::string::npos) << r.summary();
}
