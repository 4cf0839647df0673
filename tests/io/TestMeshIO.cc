// SPDX-License-Identifier: Apache-2.0
// Tests for MeshIO.h: round trips of every written format, the real meshes of ../shared/data
// (skipped when absent), polygon triangulation, and every documented failure with its message.
#include "TestUtil.h"

#include <levelforge/core/Exceptions.h>
#include <levelforge/io/MeshIO.h>
#include <levelforge/reference/MeshShapes.h>
#include <levelforge/core/MeshValidation.h>

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <limits>
#include <random>
#include <string>
#include <thread>
#include <vector>

namespace {

namespace fs = std::filesystem;
using namespace levelforge;
using levelforge_test::scratchDir;

std::string writeFile(const fs::path& dir, const std::string& name, const std::string& content)
{
    const fs::path p = dir / name;
    std::ofstream out(p, std::ios::binary);
    out << content;
    out.close();
    return p.string();
}

void appendBytes(std::string& s, const void* data, size_t n)
{
    s.append(static_cast<const char*>(data), n);
}

/// A binary STL (little-endian host assumed, as on every platform we build for).
std::string binaryStl(const std::vector<std::array<float, 9>>& facets)
{
    std::string s(80, ' ');
    const uint32_t n = uint32_t(facets.size());
    appendBytes(s, &n, 4);
    for (const auto& f : facets) {
        const float normal[3] = {0, 0, 0};
        appendBytes(s, normal, 12);
        appendBytes(s, f.data(), 36);
        const uint16_t attr = 0;
        appendBytes(s, &attr, 2);
    }
    return s;
}

/// Binary little-endian PLY with double coordinates.
std::string binaryPly(const std::vector<Vec3d>& pts, const std::vector<std::vector<int32_t>>& faces)
{
    std::string s = "ply\nformat binary_little_endian 1.0\nelement vertex " + std::to_string(pts.size()) +
                    "\nproperty double x\nproperty double y\nproperty double z\nelement face " +
                    std::to_string(faces.size()) + "\nproperty list uchar int vertex_indices\nend_header\n";
    for (const Vec3d& p : pts) appendBytes(s, p.asPointer(), 24);
    for (const auto& f : faces) {
        const uint8_t n = uint8_t(f.size());
        appendBytes(s, &n, 1);
        appendBytes(s, f.data(), 4 * f.size());
    }
    return s;
}

/// Expects @a fn to throw E whose message contains every one of @a parts.
template<typename E>
void expectThrowWith(const std::function<void()>& fn, const std::vector<std::string>& parts)
{
    try {
        fn();
        ADD_FAILURE() << "no exception; expected one mentioning '" << parts.front() << "'";
    } catch (const E& e) {
        const std::string msg = e.what();
        for (const std::string& p : parts) {
            EXPECT_NE(msg.find(p), std::string::npos) << "message '" << msg << "' lacks '" << p << "'";
        }
    } catch (const std::exception& e) {
        ADD_FAILURE() << "wrong exception type: " << e.what();
    }
}

double triangleArea(const TriangleMesh& m, const Vec3I& t)
{
    return 0.5 * (m.points[t[1]] - m.points[t[0]]).cross(m.points[t[2]] - m.points[t[0]]).length();
}

Vec3d triangleNormal(const TriangleMesh& m, const Vec3I& t)
{
    Vec3d n = (m.points[t[1]] - m.points[t[0]]).cross(m.points[t[2]] - m.points[t[0]]);
    n.normalize();
    return n;
}

} // namespace

// ------------------------------------------------------------------------------ round trips

TEST(MeshIO, RoundTripExactFormats)
{
    const fs::path dir = scratchDir("meshio_roundtrip");
    const TriangleMesh knot = makeTorusKnot(2, 3, 1.0, 0.25, 64, 12);
    for (const std::string ext : {".obj", ".off", ".ply"}) {
        SCOPED_TRACE(ext);
        const std::string path = (dir / ("knot" + ext)).string();
        writeMesh(knot, path);
        MeshReadInfo info;
        const TriangleMesh back = readMesh(path, info);
        EXPECT_EQ(back.source, path);
        EXPECT_EQ(info.format, ext.substr(1));
        EXPECT_EQ(info.binary, ext == ".ply");
        EXPECT_TRUE(info.doublePrecision);
        ASSERT_EQ(back.points.size(), knot.points.size());
        ASSERT_EQ(back.triangles.size(), knot.triangles.size());
        for (size_t i = 0; i < knot.points.size(); ++i) {
            ASSERT_EQ(back.points[i], knot.points[i]) << "vertex " << i; // bit-exact doubles
        }
        for (size_t i = 0; i < knot.triangles.size(); ++i) {
            ASSERT_EQ(back.triangles[i], knot.triangles[i]) << "triangle " << i;
        }
        EXPECT_TRUE(validateMesh(back).closed());
    }
}

TEST(MeshIO, RoundTripStlMergesCornersBackIntoSharedVertices)
{
    const fs::path dir = scratchDir("meshio_roundtrip_stl");
    const TriangleMesh sphere = makeIcosphere(Vec3d(1.0, 2.0, 3.0), 2.0, 2);
    const std::string path = (dir / "sphere.stl").string();
    writeMesh(sphere, path);
    EXPECT_EQ(fs::file_size(path), 84u + 50u * sphere.triangles.size());
    MeshReadInfo info;
    const TriangleMesh back = readMesh(path, info);
    EXPECT_EQ(info.format, "stl");
    EXPECT_TRUE(info.binary);
    EXPECT_FALSE(info.doublePrecision);
    // STL stores corners per facet; OpenMesh merges identical corners, so the sphere is
    // watertight again with the same number of vertices (in first-use order).
    EXPECT_EQ(back.points.size(), sphere.points.size());
    ASSERT_EQ(back.triangles.size(), sphere.triangles.size());
    for (size_t t = 0; t < sphere.triangles.size(); ++t) {
        for (int k = 0; k < 3; ++k) {
            const Vec3d a = sphere.points[sphere.triangles[t][k]];
            const Vec3d b = back.points[back.triangles[t][k]];
            ASSERT_NEAR((a - b).length(), 0.0, 1e-6) << "triangle " << t;
        }
    }
    EXPECT_TRUE(validateMesh(back).closed());
    EXPECT_NEAR(signedVolume(back), signedVolume(sphere), 1e-5);
}

TEST(MeshIO, WriteIsAtomicAndReportsErrors)
{
    const fs::path dir = scratchDir("meshio_atomic");
    const TriangleMesh box = makeBox(Vec3d(0.0), Vec3d(1.0));
    const std::string path = (dir / "box.obj").string();
    writeFile(dir, "box.obj", "old content");
    writeMesh(box, path); // replaces the old file
    EXPECT_EQ(readMesh(path).triangles.size(), 12u);
    size_t files = 0;
    for (const auto& entry : fs::directory_iterator(dir)) {
        ++files;
        EXPECT_EQ(entry.path().filename(), "box.obj") << "left-over temporary file";
    }
    EXPECT_EQ(files, 1u);

    expectThrowWith<IoError>([&] { writeMesh(box, (dir / "box.xyz").string()); }, {"box.xyz", "unsupported"});
    const std::string missingDir = (dir / "no" / "such" / "dir" / "box.obj").string();
    expectThrowWith<IoError>([&] { writeMesh(box, missingDir); }, {missingDir});
    EXPECT_FALSE(fs::exists(dir / "no"));

    TriangleMesh bad = box;
    bad.triangles[3][1] = 99;
    expectThrowWith<InvalidMeshError>([&] { writeMesh(bad, (dir / "bad.stl").string()); },
                                      {"bad.stl", "triangle 3"});
    EXPECT_FALSE(fs::exists(dir / "bad.stl"));
}

TEST(MeshIO, ExtensionsAreCaseInsensitive)
{
    EXPECT_TRUE(isReadableMeshFile("a/b/c.OBJ"));
    EXPECT_TRUE(isReadableMeshFile("x.Stl"));
    EXPECT_TRUE(isReadableMeshFile("x.stlb"));
    EXPECT_FALSE(isReadableMeshFile("x.vdb"));
    EXPECT_FALSE(isReadableMeshFile("noextension"));
    const std::vector<std::string> exts = readableMeshExtensions();
    for (const char* e : {".obj", ".off", ".ply", ".stl"}) {
        EXPECT_NE(std::find(exts.begin(), exts.end(), e), exts.end()) << e;
    }
    const fs::path dir = scratchDir("meshio_case");
    writeMesh(makeBox(Vec3d(0.0), Vec3d(1.0)), (dir / "box.obj").string());
    fs::rename(dir / "box.obj", dir / "BOX.OBJ");
    EXPECT_EQ(readMesh((dir / "BOX.OBJ").string()).triangles.size(), 12u);
}

// -------------------------------------------------------------------------- format details

TEST(MeshIO, ObjSyntaxVariants)
{
    const fs::path dir = scratchDir("meshio_obj_syntax");
    // v/vt/vn corners, negative (relative) indices, comments, CRLF line ends, a face that refers
    // to vertices defined after it, 'o'/'g'/'usemtl' statements.
    const std::string path = writeFile(dir, "variants.obj",
        "# comment\r\n"
        "o thing\r\n"
        "v 0 0 0\r\n"
        "v 1 0 0\r\n"
        "v 0 1 0\r\n"
        "vt 0 0\r\nvt 1 0\r\nvt 0 1\r\n"
        "vn 0 0 1\r\n"
        "g group\r\n"
        "f 1/1/1 2/2/1 3/3/1\r\n"
        "f -3//1 -2//1 -1//1 # trailing comment\r\n"
        "f 4 5 6\r\n"
        "v 0 0 1\r\nv 1 0 1\r\nv 0 1 1\r\n");
    MeshReadInfo info;
    const TriangleMesh m = readMesh(path, info);
    ASSERT_EQ(m.points.size(), 6u);
    ASSERT_EQ(m.triangles.size(), 3u);
    EXPECT_EQ(m.triangles[0], Vec3I(0, 1, 2));
    EXPECT_EQ(m.triangles[1], Vec3I(0, 1, 2));
    EXPECT_EQ(m.triangles[2], Vec3I(3, 4, 5));
    EXPECT_EQ(m.points[5], Vec3d(0, 1, 1));
    EXPECT_EQ(info.fileFaces, 3u);
    EXPECT_EQ(info.droppedFaces, 0u);
}

TEST(MeshIO, PositionsKeepDoublePrecision)
{
    const fs::path dir = scratchDir("meshio_precision");
    const Vec3d exact(0.1, 0.2, 0.30000000000000004);
    const std::string obj = writeFile(dir, "p.obj",
        "v 0.1 0.2 0.30000000000000004\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    const std::string off = writeFile(dir, "p.off",
        "OFF\n3 1 0\n0.1 0.2 0.30000000000000004\n1 0 0\n0 1 0\n3 0 1 2\n");
    const std::string ply = writeFile(dir, "p.ply",
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty double x\nproperty double y\n"
        "property double z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
        "0.1 0.2 0.30000000000000004\n1 0 0\n0 1 0\n3 0 1 2\n");
    const std::string plyb = writeFile(dir, "pb.ply",
        binaryPly({exact, Vec3d(1, 0, 0), Vec3d(0, 1, 0)}, {{0, 1, 2}}));
    for (const std::string& path : {obj, off, ply, plyb}) {
        SCOPED_TRACE(path);
        MeshReadInfo info;
        const TriangleMesh m = readMesh(path, info);
        EXPECT_TRUE(info.doublePrecision);
        ASSERT_EQ(m.points.size(), 3u);
        EXPECT_EQ(m.points[0], exact); // not the float 0.100000001490116...
    }
}

TEST(MeshIO, ConcavePolygonsAreEarClippedInTheirPlane)
{
    const fs::path dir = scratchDir("meshio_polygons");
    // A dart A(0,0) B(2,1) C(4,0) D(2,3), counter-clockwise, reflex at B: a fan from A would
    // put a flipped triangle outside the polygon. Area 4. Then a concave hexagon (an "L",
    // area 3) in a tilted plane, to exercise the best-fit plane.
    const Vec3d ex(1, 0, 0), ey(0, std::cos(0.7), std::sin(0.7)); // tilted basis
    const Vec3d origin(5, -2, 1);
    auto P = [&](double x, double y) { return origin + ex * x + ey * y; };
    const std::vector<Vec3d> L = {P(0, 0), P(2, 0), P(2, 1), P(1, 1), P(1, 2), P(0, 2)};
    std::string obj = "v 0 0 0\nv 2 1 0\nv 4 0 0\nv 2 3 0\n";
    std::string off = "OFF\n10 2 0\n0 0 0\n2 1 0\n4 0 0\n2 3 0\n";
    for (const Vec3d& p : L) {
        char line[200];
        std::snprintf(line, sizeof(line), "%.17g %.17g %.17g\n", p[0], p[1], p[2]);
        obj += std::string("v ") + line;
        off += line;
    }
    obj += "f 1 2 3 4\nf 5 6 7 8 9 10\n";
    off += "4 0 1 2 3\n6 4 5 6 7 8 9\n";
    const std::string ply = writeFile(dir, "poly.ply",
        binaryPly({Vec3d(0, 0, 0), Vec3d(2, 1, 0), Vec3d(4, 0, 0), Vec3d(2, 3, 0), L[0], L[1], L[2],
                   L[3], L[4], L[5]},
                  {{0, 1, 2, 3}, {4, 5, 6, 7, 8, 9}}));
    const Vec3d tiltedNormal = ex.cross(ey);
    for (const std::string& path : {writeFile(dir, "poly.obj", obj), writeFile(dir, "poly.off", off), ply}) {
        SCOPED_TRACE(path);
        MeshReadInfo info;
        const TriangleMesh m = readMesh(path, info);
        EXPECT_EQ(info.polygons, 2u);
        EXPECT_EQ(info.fanFallbacks, 0u);
        ASSERT_EQ(m.triangles.size(), 2u + 4u);
        double dartArea = 0, lArea = 0;
        for (size_t t = 0; t < 2; ++t) {
            dartArea += triangleArea(m, m.triangles[t]);
            EXPECT_NEAR(triangleNormal(m, m.triangles[t]).dot(Vec3d(0, 0, 1)), 1.0, 1e-12) << t;
        }
        for (size_t t = 2; t < 6; ++t) {
            lArea += triangleArea(m, m.triangles[t]);
            EXPECT_NEAR(triangleNormal(m, m.triangles[t]).dot(tiltedNormal), 1.0, 1e-9) << t;
        }
        EXPECT_NEAR(dartArea, 4.0, 1e-12);
        EXPECT_NEAR(lArea, 3.0, 1e-9);
    }
}

TEST(MeshIO, QuadsAreSplitAlongTheirFirstDiagonalUnlessItLeavesThem)
{
    // a non-planar (saddle) quad: both diagonals are inside its projection, and the split along
    // 0-2 is OpenVDB's (0-1-2, 0-2-3); the other one would be a different surface (its centre
    // 0.5 higher or lower). A convex planar quad in every rotation of its corners keeps 0-2.
    // (The non-convex dart, which must be split along 1-3, is in ConcavePolygonsAreEarClipped.)
    const fs::path dir = scratchDir("meshio_quads");
    const std::string obj = writeFile(dir, "quads.obj",
        "v 0 0 0\nv 1 0 1\nv 1 1 0\nv 0 1 1\n"   // saddle
        "v 3 0 0\nv 5 0 0\nv 5.5 1 0\nv 3 2 0\n" // convex, planar
        "f 1 2 3 4\nf 5 6 7 8\nf 6 7 8 5\n");
    const TriangleMesh m = readMesh(obj);
    ASSERT_EQ(m.triangles.size(), 6u);
    EXPECT_EQ(m.triangles[0], Vec3I(0, 1, 2));
    EXPECT_EQ(m.triangles[1], Vec3I(0, 2, 3));
    EXPECT_EQ(m.triangles[2], Vec3I(4, 5, 6));
    EXPECT_EQ(m.triangles[3], Vec3I(4, 6, 7));
    EXPECT_EQ(m.triangles[4], Vec3I(5, 6, 7));
    EXPECT_EQ(m.triangles[5], Vec3I(5, 7, 4));

    // two quads sharing corners 0 and 2 (a pentagon in between): the second must not split
    // along 0-2 too (four triangles on one edge); it takes 1-3 (here 4-5)
    const std::string two = writeFile(dir, "two.obj",
        "v 0 0 0\nv 1 0 0.2\nv 1 1 0\nv 0 1 0.2\nv 1 0 -0.3\nv 0 1 -0.3\n"
        "f 1 2 3 4\nf 1 4 3 6 5\nf 1 4 3 5\n");
    const TriangleMesh t = readMesh(two);
    ASSERT_GE(t.triangles.size(), 4u);
    EXPECT_EQ(t.triangles[0], Vec3I(0, 1, 2));
    EXPECT_EQ(t.triangles[1], Vec3I(0, 2, 3));
    const size_t n = t.triangles.size();
    EXPECT_EQ(t.triangles[n - 2], Vec3I(3, 2, 4)); // 1-3 of (0, 3, 2, 4): corners 3 and 0 -> 3-2-4, 3-4-0
    EXPECT_EQ(t.triangles[n - 1], Vec3I(3, 4, 0));
}

TEST(MeshIO, RandomStarPolygonsTriangulateExactly)
{
    // Star-shaped (generally concave) polygons with 5..34 corners in random tilted planes: ear
    // clipping must give k-2 triangles that cover exactly the polygon's area, all wound like it.
    const fs::path dir = scratchDir("meshio_stars");
    std::mt19937_64 rng(12345);
    auto uniform = [&](double a, double b) {
        return a + (b - a) * double(rng() >> 11) * (1.0 / 9007199254740992.0);
    };
    struct Star { size_t corners; double area; Vec3d normal; };
    std::vector<Star> stars;
    std::string obj;
    size_t vertexBase = 1;
    for (int i = 0; i < 60; ++i) {
        const size_t k = 5 + size_t(i % 30);
        Vec3d n(uniform(-1, 1), uniform(-1, 1), uniform(-1, 1));
        n.normalize();
        Vec3d e1 = std::abs(n[0]) < 0.9 ? Vec3d(1, 0, 0).cross(n) : Vec3d(0, 1, 0).cross(n);
        e1.normalize();
        const Vec3d e2 = n.cross(e1);
        const Vec3d origin(uniform(-10, 10), uniform(-10, 10), uniform(-10, 10));
        std::vector<double> theta(k), radius(k);
        for (size_t j = 0; j < k; ++j) {
            theta[j] = 2.0 * 3.14159265358979323846 * (double(j) + uniform(0.0, 0.8)) / double(k);
            radius[j] = uniform(0.2, 1.0);
        }
        double area = 0;
        for (size_t j = 0; j < k; ++j) {
            const size_t jn = (j + 1) % k;
            double dt = theta[jn] - theta[j];
            if (jn == 0) dt += 2.0 * 3.14159265358979323846;
            area += 0.5 * radius[j] * radius[jn] * std::sin(dt);
            const Vec3d p = origin + e1 * (radius[j] * std::cos(theta[j])) + e2 * (radius[j] * std::sin(theta[j]));
            char line[200];
            std::snprintf(line, sizeof(line), "v %.17g %.17g %.17g\n", p[0], p[1], p[2]);
            obj += line;
        }
        obj += "f";
        for (size_t j = 0; j < k; ++j) obj += " " + std::to_string(vertexBase + j);
        obj += "\n";
        vertexBase += k;
        stars.push_back({k, area, n});
    }
    MeshReadInfo info;
    const TriangleMesh m = readMesh(writeFile(dir, "stars.obj", obj), info);
    EXPECT_EQ(info.polygons, stars.size());
    EXPECT_EQ(info.fanFallbacks, 0u);
    size_t t = 0;
    for (size_t i = 0; i < stars.size(); ++i) {
        SCOPED_TRACE(i);
        double area = 0;
        for (size_t j = 0; j + 2 < stars[i].corners; ++j, ++t) {
            ASSERT_LT(t, m.triangles.size());
            const Vec3I& tri = m.triangles[t];
            const Vec3d cr = (m.points[tri[1]] - m.points[tri[0]]).cross(m.points[tri[2]] - m.points[tri[0]]);
            EXPECT_GE(cr.dot(stars[i].normal), -1e-12) << "triangle " << t << " is flipped";
            area += 0.5 * cr.length();
        }
        EXPECT_NEAR(area, stars[i].area, 1e-9 * stars[i].corners);
    }
    EXPECT_EQ(t, m.triangles.size());
}

TEST(MeshIO, NonManifoldFacesAreAllKept)
{
    // Three triangles on edge 1-2 plus one wound the other way: OpenMesh's TriMesh would drop
    // the "complex edge" faces, our importer keeps every one.
    const fs::path dir = scratchDir("meshio_nonmanifold");
    const std::string path = writeFile(dir, "fin.obj",
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nv 0 0 -1\n"
        "f 1 2 3\nf 2 1 4\nf 1 2 5\nf 1 2 6\nf 2 1 3\n");
    const TriangleMesh m = readMesh(path);
    EXPECT_EQ(m.triangles.size(), 5u);
    const MeshReport r = validateMesh(m);
    EXPECT_EQ(r.nonManifoldEdges, 1u);
}

TEST(MeshIO, StlMergesCornersAndDropsCollapsedFacets)
{
    const fs::path dir = scratchDir("meshio_stl");
    const std::vector<std::array<float, 9>> facets = {
        {0, 0, 0, 1, 0, 0, 0, 1, 0},  // regular
        {1, 0, 0, 1, 1, 0, 0, 1, 0},  // shares an edge with the first
        {0, 0, 0, 1, 0, 0, 2, 0, 0},  // collinear: zero area, kept (validation reports it)
        {0, 0, 0, 0, 0, 0, 0, 1, 0},  // two identical corners: OpenMesh drops it
        {-0.f, 0, 0, 1, 0, 0, 0, 0, 1}, // -0 merges with 0
    };
    std::string ascii = "solid t\n";
    for (const auto& f : facets) {
        ascii += " facet normal 0 0 0\n  outer loop\n";
        for (int c = 0; c < 3; ++c) {
            char line[160];
            std::snprintf(line, sizeof(line), "   vertex %.9g %.9g %.9g\n", f[3 * c], f[3 * c + 1], f[3 * c + 2]);
            ascii += line;
        }
        ascii += "  endloop\n endfacet\n";
    }
    ascii += "endsolid t\n";
    for (const std::string& path : {writeFile(dir, "a.stl", ascii), writeFile(dir, "b.stl", binaryStl(facets))}) {
        SCOPED_TRACE(path);
        MeshReadInfo info;
        const TriangleMesh m = readMesh(path, info);
        EXPECT_EQ(info.binary, path.find("b.stl") != std::string::npos);
        EXPECT_EQ(info.fileFaces, 5u);
        EXPECT_EQ(info.droppedFaces, 1u);
        EXPECT_EQ(m.triangles.size(), 4u);
        EXPECT_EQ(m.points.size(), 6u); // (0,0,0) (1,0,0) (0,1,0) (1,1,0) (2,0,0) (0,0,1)
        const MeshReport r = validateMesh(m);
        EXPECT_EQ(r.degenerateTriangles, 1u);
    }
}

TEST(MeshIO, ConcurrentReadsAgree)
{
    const fs::path dir = scratchDir("meshio_threads");
    const std::string obj = (dir / "s.obj").string(), off = (dir / "s.off").string();
    const TriangleMesh s = makeIcosphere(Vec3d(0.0), 1.0, 3);
    writeMesh(s, obj);
    writeMesh(s, off);
    std::vector<TriangleMesh> results(8);
    std::vector<std::thread> threads;
    for (size_t i = 0; i < results.size(); ++i) {
        threads.emplace_back([&, i] { results[i] = readMesh(i % 2 ? obj : off); });
    }
    for (std::thread& t : threads) t.join();
    for (const TriangleMesh& m : results) {
        EXPECT_EQ(m.points, s.points);
        EXPECT_EQ(m.triangles, s.triangles);
    }
}

// ----------------------------------------------------------------------------- real meshes

namespace {

struct RealMesh
{
    const char* file;
    uint64_t vertices;
    uint64_t faces;
    uint64_t triangles;
};

// Counts from ../shared/data/README.md; triangles after triangulation (suzanne has quads).
const RealMesh kRealMeshes[] = {
    {"meshes/watertight/spot.obj", 2930, 5856, 5856},
    {"meshes/watertight/cow.obj", 2903, 5804, 5804},
    {"meshes/watertight/fandisk.obj", 6475, 12946, 12946},
    {"meshes/watertight/elephant.off", 2775, 5558, 5558},
    {"meshes/watertight/fertility.off", 4494, 9000, 9000},
    {"meshes/watertight/3holes_genus3.off", 3596, 7200, 7200},
    {"meshes/watertight/chess_pawn.stl", 8621, 17238, 17238},
    {"meshes/watertight/chess_knight_decimated.off", 502, 1000, 1000},
    {"meshes/watertight/armadillo_100k.obj", 49990, 99976, 99976},
    {"meshes/watertight/dragon_100k.obj", 50000, 100000, 100000},
    {"meshes/watertight/lucy_100k.obj", 49987, 99970, 99970},
    {"meshes/open_or_broken/bunny.obj", 35947, 69451, 69451},
    {"meshes/open_or_broken/suzanne.obj", 507, 500, 968},
    {"meshes/open_or_broken/teapot.obj", 3644, 6320, 6320},
    {"meshes/open_or_broken/cgal_elephant-with-holes.off", 2798, 4463, 4463},
    {"meshes/open_or_broken/assimp_spider.obj", 762, 1368, 1368},
    {"meshes/open_or_broken/trimesh_soup.stl", 300, 100, 100},
    {"meshes/open_or_broken/trimesh_joined_tetrahedra.obj", 5, 8, 8},
    {"meshes/open_or_broken/openscad_issue1580-zero-area-triangle.stl", 9, 14, 14},
};

class MeshIORealMesh : public ::testing::TestWithParam<RealMesh> {};

} // namespace

TEST_P(MeshIORealMesh, CountsMatchTheDataReadme)
{
    const RealMesh& rm = GetParam();
    LEVELFORGE_SHARED_FILE_OR_SKIP(path, rm.file);
    MeshReadInfo info;
    const TriangleMesh m = readMesh(path, info);
    EXPECT_EQ(m.source, path);
    EXPECT_EQ(m.points.size(), rm.vertices);
    EXPECT_EQ(info.fileFaces, rm.faces);
    EXPECT_EQ(info.droppedFaces, 0u);
    EXPECT_EQ(info.fanFallbacks, 0u);
    EXPECT_EQ(m.triangles.size(), rm.triangles);
    EXPECT_GE(m.triangles.size(), info.fileFaces);
    const std::string ext = fs::path(path).extension().string();
    EXPECT_EQ(info.doublePrecision, ext != ".stl");
    EXPECT_NO_THROW(validateMesh(m));
}

INSTANTIATE_TEST_SUITE_P(SharedData, MeshIORealMesh, ::testing::ValuesIn(kRealMeshes),
    [](const ::testing::TestParamInfo<RealMesh>& info) {
        std::string name = fs::path(info.param.file).stem().string();
        for (char& c : name) {
            if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
        }
        return name;
    });

TEST(MeshIO, SuzanneQuadsBecomeTwoTrianglesEach)
{
    LEVELFORGE_SHARED_FILE_OR_SKIP(path, "meshes/open_or_broken/suzanne.obj");
    MeshReadInfo info;
    const TriangleMesh m = readMesh(path, info);
    EXPECT_EQ(info.polygons, 468u);
    EXPECT_EQ(m.triangles.size(), 32u + 2u * 468u);
}

// ---------------------------------------------------------------------------- bad inputs

TEST(MeshIO, MissingUnreadableOrUnsupportedFilesThrowIoError)
{
    const fs::path dir = scratchDir("meshio_missing");
    const std::string missing = (dir / "nothing.obj").string();
    expectThrowWith<IoError>([&] { readMesh(missing); }, {missing, "does not exist"});
    const std::string unsupported = writeFile(dir, "points.xyz", "0 0 0\n");
    expectThrowWith<IoError>([&] { readMesh(unsupported); }, {unsupported, "unsupported", ".xyz"});
    const std::string noExt = writeFile(dir, "mesh", "v 0 0 0\n");
    expectThrowWith<IoError>([&] { readMesh(noExt); }, {noExt, "no file extension"});
    fs::create_directories(dir / "folder.obj");
    const std::string folder = (dir / "folder.obj").string();
    expectThrowWith<IoError>([&] { readMesh(folder); }, {folder, "not a regular file"});
}

TEST(MeshIO, EmptyAndGarbageFilesThrowInvalidMesh)
{
    const fs::path dir = scratchDir("meshio_garbage");
    for (const char* name : {"empty.obj", "empty.off", "empty.ply", "empty.stl"}) {
        const std::string p = writeFile(dir, name, "");
        expectThrowWith<InvalidMeshError>([&] { readMesh(p); }, {p, "empty"});
    }
    const std::string garbage = "this is not a mesh\n\x01\x02\x03 at all\n";
    const std::string obj = writeFile(dir, "garbage.obj", garbage);
    expectThrowWith<InvalidMeshError>([&] { readMesh(obj); }, {obj, "no triangles"});
    const std::string off = writeFile(dir, "garbage.off", garbage);
    expectThrowWith<InvalidMeshError>([&] { readMesh(off); }, {off, "not an OFF file"});
    const std::string ply = writeFile(dir, "garbage.ply", garbage);
    expectThrowWith<InvalidMeshError>([&] { readMesh(ply); }, {ply, "not a PLY file"});
    const std::string stl = writeFile(dir, "garbage.stl", garbage);
    expectThrowWith<InvalidMeshError>([&] { readMesh(stl); }, {stl, "no triangles"});
    // Vertices but no faces, and only faces without area.
    const std::string cloud = writeFile(dir, "cloud.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\n");
    expectThrowWith<InvalidMeshError>([&] { readMesh(cloud); }, {cloud, "no triangles", "3 vertices"});
    const std::string flat = writeFile(dir, "flat.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 1 2\nf 2 3 3\n");
    expectThrowWith<InvalidMeshError>([&] { readMesh(flat); }, {flat, "no triangles", "2 of them without area"});
    // OFF variants OpenMesh reads as nothing.
    const std::string counts = writeFile(dir, "counts.off", "OFF 3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
    expectThrowWith<InvalidMeshError>([&] { readMesh(counts); }, {counts, "line 1", "header"});
    const std::string comment = writeFile(dir, "comment.off", "OFF\n# c\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
    expectThrowWith<InvalidMeshError>([&] { readMesh(comment); }, {comment, "line 2", "comments"});
}

TEST(MeshIO, OffCountsLineIsReadAsOneStreamWithTheBody)
{
    // OpenMesh reads the three counts with operator>> and goes on in the same stream: what follows
    // them on their line is the first vertex, or (no vertices) the first face's corner count.
    const fs::path dir = scratchDir("meshio_off_counts_line");
    const std::string onCounts = writeFile(dir, "vertex-on-counts.off", "OFF\n3 1 0 0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
    const TriangleMesh m = readMesh(onCounts);
    ASSERT_EQ(m.points.size(), 3u);
    ASSERT_EQ(m.triangles.size(), 1u);
    EXPECT_EQ(m.points[0], Vec3d(0, 0, 0));
    EXPECT_EQ(m.points[2], Vec3d(0, 1, 0));

    // tests/data/fuzz/off/oom-negative-face-valence.off: OpenMesh took -2 as the first face's
    // corner count (4294967294 as unsigned) and pushed corners until memory ran out.
    const std::string negative = writeFile(dir, "negative-valence.off", "OFF\n0 1 0 -2\n0\n");
    expectThrowWith<InvalidMeshError>([&] { readMesh(negative); },
                                      {negative, "line 2", "face 0", "negative corner count", "-2"});
    // a corner count the rest of the file cannot hold, in range for OpenMesh's unsigned int
    const std::string absurd = writeFile(dir, "absurd-valence.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n4000000000 0 1 2\n");
    expectThrowWith<InvalidMeshError>([&] { readMesh(absurd); }, {absurd, "line 6", "face 0", "corner count 4000000000"});
    const std::string tooBig = writeFile(dir, "huge-valence.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n5000000000 0 1 2\n");
    expectThrowWith<InvalidMeshError>([&] { readMesh(tooBig); }, {tooBig, "line 6", "face 0", "corner count"});
    // negative header counts: OpenMesh would read -3 as 4294967293
    const std::string negV = writeFile(dir, "negative-vertices.off", "OFF\n-3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
    expectThrowWith<InvalidMeshError>([&] { readMesh(negV); }, {negV, "line 2", "negative vertex count"});
    const std::string negF = writeFile(dir, "negative-faces.off", "OFF\n3 -1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
    expectThrowWith<InvalidMeshError>([&] { readMesh(negF); }, {negF, "line 2", "negative face count"});
}

TEST(MeshIO, BinaryOff)
{
    const fs::path dir = scratchDir("meshio_binary_off");
    auto make = [](const std::vector<std::array<float, 3>>& v, const std::vector<std::array<uint32_t, 3>>& f) {
        std::string s = "OFF BINARY\n";
        const uint32_t counts[3] = {uint32_t(v.size()), uint32_t(f.size()), 0};
        appendBytes(s, counts, 12);
        for (const auto& p : v) appendBytes(s, p.data(), 12);
        for (const auto& t : f) {
            const uint32_t n = 3;
            appendBytes(s, &n, 4);
            appendBytes(s, t.data(), 12);
        }
        return s;
    };
    const std::vector<std::array<float, 3>> v = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    const std::string good = writeFile(dir, "tet.off", make(v, {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}}));
    MeshReadInfo info;
    const TriangleMesh m = readMesh(good, info);
    EXPECT_TRUE(info.binary);
    EXPECT_EQ(m.triangles.size(), 4u);
    EXPECT_TRUE(validateMesh(m).closed());
    const std::string bad = writeFile(dir, "bad.off", make(v, {{0, 2, 1}, {0, 1, 9}}));
    expectThrowWith<InvalidMeshError>([&] { readMesh(bad); }, {bad, "face 1", "vertex index 9"});
    std::vector<std::array<float, 3>> nanV = v;
    nanV[2][1] = std::numeric_limits<float>::quiet_NaN();
    const std::string nan = writeFile(dir, "nan.off", make(nanV, {{0, 2, 1}}));
    expectThrowWith<InvalidMeshError>([&] { readMesh(nan); }, {nan, "vertex 2", "non-finite"});
}

TEST(MeshIO, MalformedHeadersFailFastInsteadOfHangingOpenMesh)
{
    // OpenMesh 9's PLY header parser loops forever on each of these, its binary OFF and binary
    // STL readers trust the counts in the file: the pre-scan must stop them first.
    const fs::path dir = scratchDir("meshio_headers");
    const std::string body = "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
    const std::string props = "property float x\nproperty float y\nproperty float z\nelement face 1\n"
                              "property list uchar int vertex_indices\n";
    struct Case { const char* name; std::string content; std::vector<std::string> parts; };
    const std::vector<Case> cases = {
        {"version.ply", "ply\nformat ascii 1.e\nelement vertex 3\n" + props + "end_header\n" + body,
         {"line 2", "format"}},
        {"count.ply", "ply\nformat ascii 1.0\nelement vertex abc\n" + props + "end_header\n" + body,
         {"line 3", "element"}},
        {"nocount.ply", "ply\nformat ascii 1.0\nelement vertex\n" + props + "end_header\n" + body,
         {"line 3", "element"}},
        {"propname.ply", "ply\nformat ascii 1.0\nelement vertex 3\n" + props + "property float\nend_header\n" + body,
         {"line 9", "property"}},
        {"listtypes.ply", "ply\nformat ascii 1.0\nelement vertex 3\n" + props + "property list uchar\nend_header\n" + body,
         {"line 9", "property list"}},
        {"keyword.ply", "ply\nformat ascii 1.0\nfoo bar\nelement vertex 3\n" + props + "end_header\n" + body,
         {"line 3", "keyword 'foo'"}},
        {"noend.ply", "ply\nformat ascii 1.0\nelement vertex 3\n" + props + body, {"end_header"}},
        {"short.ply", "ply\nformat ascii 1.0\nelement vertex 3\n" + props + "end_header\n0 0 0\n1 0 0\n",
         {"ends inside vertex 2"}},
    };
    for (const Case& c : cases) {
        SCOPED_TRACE(c.name);
        const std::string p = writeFile(dir, c.name, c.content);
        std::vector<std::string> parts = c.parts;
        parts.insert(parts.begin(), p);
        expectThrowWith<InvalidMeshError>([&] { readMesh(p); }, parts);
    }
    // Binary OFF announcing four billion faces, binary STL (.stlb) announcing more facets than
    // it holds.
    std::string off = "OFF BINARY\n";
    const uint32_t counts[3] = {3, 4000000000u, 0};
    appendBytes(off, counts, 12);
    const float xyz[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    appendBytes(off, xyz, 36);
    const std::string offPath = writeFile(dir, "huge.off", off);
    expectThrowWith<InvalidMeshError>([&] { readMesh(offPath); }, {offPath});
    std::string stl = binaryStl({{0, 0, 0, 1, 0, 0, 0, 1, 0}});
    const uint32_t lie = 1000000;
    std::memcpy(&stl[80], &lie, 4);
    const std::string stlPath = writeFile(dir, "lie.stlb", stl);
    expectThrowWith<InvalidMeshError>([&] { readMesh(stlPath); }, {stlPath, "ends inside facet 1"});
}

TEST(MeshIO, FacesWithoutThreeDistinctCornersAreCounted)
{
    const fs::path dir = scratchDir("meshio_dropped");
    const std::string obj = writeFile(dir, "d.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 1 2\n");
    const std::string off = writeFile(dir, "d.off", "OFF\n3 4 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n3 0 0 1\n2 0 1\n4 0 1 1 0\n");
    for (const std::string& p : {obj, off}) {
        SCOPED_TRACE(p);
        MeshReadInfo info;
        const TriangleMesh m = readMesh(p, info);
        EXPECT_EQ(m.triangles.size(), 1u);
        EXPECT_EQ(info.droppedFaces, info.fileFaces - 1);
    }
}

TEST(MeshIO, NonFiniteCoordinatesNameTheVertex)
{
    const fs::path dir = scratchDir("meshio_nan");
    struct Case { const char* name; std::string content; std::vector<std::string> parts; };
    const std::vector<Case> cases = {
        {"nan.obj", "v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n", {"line 2", "vertex 1", "non-finite", "nan"}},
        {"inf.obj", "v 0 0 0\nv 1 0 0\nv 0 -inf 0\nf 1 2 3\n", {"line 3", "vertex 2", "non-finite"}},
        {"huge.obj", "v 0 0 0\nv 1e39 0 0\nv 0 1 0\nf 1 2 3\n", {"vertex 1", "single-precision range"}},
        {"junk.obj", "v 0 0 0\nv 1.5abc 0 0\nv 0 1 0\nf 1 2 3\n", {"vertex 1", "cannot parse", "1.5abc"}},
        {"short.obj", "v 0 0 0\nv 1 0\nv 0 1 0\nf 1 2 3\n", {"line 2", "vertex 1", "fewer than 3"}},
        {"nan.off", "OFF\n3 1 0\n0 0 0\n1 NaN 0\n0 1 0\n3 0 1 2\n", {"line 4", "vertex 1", "non-finite"}},
        {"nan.ply",
         "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
         "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 nan\n0 1 0\n3 0 1 2\n",
         {"line 11", "vertex 1", "non-finite"}},
        {"nanb.ply",
         binaryPly({Vec3d(0, 0, 0), Vec3d(1, 0, 0), Vec3d(0, std::numeric_limits<double>::quiet_NaN(), 0)},
                   {{0, 1, 2}}),
         {"vertex 2", "non-finite"}},
        {"nan.stl",
         "solid x\nfacet normal 0 0 0\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\n"
         "facet normal 0 0 0\nouter loop\nvertex 0 0 0\nvertex inf 0 0\nvertex 0 1 0\nendloop\nendfacet\nendsolid\n",
         {"line 12", "facet 1", "corner 1", "non-finite"}},
        {"nanb.stl",
         binaryStl({{0, 0, 0, 1, 0, 0, 0, 1, 0}, {0, 0, 0, 1, 0, 0, std::numeric_limits<float>::quiet_NaN(), 1, 0}}),
         {"facet 1", "corner 2", "non-finite"}},
    };
    for (const Case& c : cases) {
        SCOPED_TRACE(c.name);
        const std::string p = writeFile(dir, c.name, c.content);
        std::vector<std::string> parts = c.parts;
        parts.insert(parts.begin(), p);
        expectThrowWith<InvalidMeshError>([&] { readMesh(p); }, parts);
    }
}

TEST(MeshIO, OutOfRangeIndicesNameTheFace)
{
    const fs::path dir = scratchDir("meshio_index");
    struct Case { const char* name; std::string content; std::vector<std::string> parts; };
    const std::vector<Case> cases = {
        {"big.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 5\n", {"line 5", "face 1", "vertex index 5", "3 vertices"}},
        {"zero.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n", {"line 4", "face 0", "vertex index 0"}},
        {"neg.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf -1 -2 -4\n", {"line 5", "face 1", "vertex index -4"}},
        {"forward.obj", "v 0 0 0\nf 1 2 3\nv 1 0 0\nv 0 1 0\nf 1 2 9\n", {"line 5", "face 1", "vertex index 9"}},
        {"corner.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 x\n", {"face 0", "cannot parse corner 'x'"}},
        {"big.off", "OFF\n3 2 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n3 0 1 7\n", {"line 7", "face 1", "vertex index 7"}},
        {"neg.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 -1 2\n", {"face 0", "vertex index -1"}},
        {"short.off", "OFF\n4 1 0\n0 0 0\n1 0 0\n0 1 0\n", {"ends inside vertex 3"}},
        {"shortf.off", "OFF\n3 2 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", {"ends before face 1"}},
        {"big.ply",
         "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
         "element face 2\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n3 0 1 3\n",
         {"line 14", "face 1", "vertex index 3"}},
        {"bigb.ply", binaryPly({Vec3d(0, 0, 0), Vec3d(1, 0, 0), Vec3d(0, 1, 0)}, {{0, 1, 2}, {2, 1, 12}}),
         {"face 1", "vertex index 12"}},
    };
    for (const Case& c : cases) {
        SCOPED_TRACE(c.name);
        const std::string p = writeFile(dir, c.name, c.content);
        std::vector<std::string> parts = c.parts;
        parts.insert(parts.begin(), p);
        expectThrowWith<InvalidMeshError>([&] { readMesh(p); }, parts);
    }
}

TEST(MeshIO, HeaderCountsBeyondTheFileNameTheCount)
{
    // Counts the rest of the file cannot hold are caught before anything is sized from them; the
    // message names the file, the count and the bytes that are there.
    const fs::path dir = scratchDir("meshio_claims");
    const std::string props = "property float x\nproperty float y\nproperty float z\n";
    const std::string faceProp = "property list uchar int vertex_indices\n";
    std::string plyBin = binaryPly({Vec3d(0, 0, 0), Vec3d(1, 0, 0), Vec3d(0, 1, 0)}, {{0, 1, 2}});
    plyBin.replace(plyBin.find("element vertex 3"), 16, "element vertex 400000000");
    std::string plyList = binaryPly({Vec3d(0, 0, 0), Vec3d(1, 0, 0), Vec3d(0, 1, 0)}, {{0, 1, 2}});
    plyList[plyList.size() - 13] = char(250); // the face's list length
    std::string offBin = "OFF BINARY\n";
    const uint32_t counts[3] = {3, 2000000000u, 0};
    appendBytes(offBin, counts, 12);
    const float xyz[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    appendBytes(offBin, xyz, 36);
    std::string stlb = binaryStl({{0, 0, 0, 1, 0, 0, 0, 1, 0}});
    const uint32_t lie = 1000000;
    std::memcpy(&stlb[80], &lie, 4);
    std::string stlNul = stlb;
    stlNul[0] = '\0'; // a binary header (not "solid ...")
    struct Case { const char* name; std::string content; std::vector<std::string> parts; };
    const std::vector<Case> cases = {
        {"v.off", "OFF\n400000000 1 0\n0 0 0\n1 0 0\n", {"400000000 vertices", "only 12 bytes after the header"}},
        {"f.off", "OFF\n3 100000000 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", {"100000000 faces", "bytes after the header"}},
        {"fb.off", offBin, {"2000000000 faces", "only 36 bytes after the header"}},
        {"v.ply", "ply\nformat ascii 1.0\nelement vertex 400000000\n" + props + "element face 1\n" + faceProp +
                  "end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", {"400000000 vertices", "only 26 bytes after the header"}},
        {"f.ply", "ply\nformat ascii 1.0\nelement vertex 3\n" + props + "element face 300000000\n" + faceProp +
                  "end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", {"300000000 faces", "bytes after the header"}},
        {"vb.ply", plyBin, {"400000000 vertices", "bytes after the header"}},
        {"list.ply", plyList, {"face 0", "claims 250 items"}},
        {"lie.stlb", stlb, {"1000000 triangles", "only 50 bytes after the header", "ends inside facet 1"}},
        {"lie.stl", stlNul, {"not a valid binary STL", "1000000 triangles", "only 50 bytes after the header"}},
    };
    for (const Case& c : cases) {
        SCOPED_TRACE(c.name);
        const std::string p = writeFile(dir, c.name, c.content);
        std::vector<std::string> parts = c.parts;
        parts.insert(parts.begin(), p);
        expectThrowWith<InvalidMeshError>([&] { readMesh(p); }, parts);
    }
}

namespace {

/// A torus grid of u x v vertices and 2uv triangles, written in every readable layout the
/// parallel reader handles (several of its 1 MiB chunks each).
std::vector<std::string> writeTorusFiles(const fs::path& dir, int u, int v)
{
    std::vector<Vec3d> pts;
    for (int i = 0; i < u; ++i) {
        for (int j = 0; j < v; ++j) {
            const double a = 2 * M_PI * i / u, b = 2 * M_PI * j / v;
            pts.emplace_back((1 + 0.35 * std::cos(b)) * std::cos(a), (1 + 0.35 * std::cos(b)) * std::sin(a),
                             0.35 * std::sin(b));
        }
    }
    std::vector<std::array<int, 3>> tris;
    for (int i = 0; i < u; ++i) {
        for (int j = 0; j < v; ++j) {
            const int a = i * v + j, b = ((i + 1) % u) * v + j, c = ((i + 1) % u) * v + (j + 1) % v,
                      d = i * v + (j + 1) % v;
            tris.push_back({a, b, c});
            tris.push_back({a, c, d});
        }
    }
    char buf[256];
    std::string obj, plyA, stlA = "solid t\n";
    std::vector<std::string> text(pts.size());
    for (size_t i = 0; i < pts.size(); ++i) {
        std::snprintf(buf, sizeof(buf), "%.9g %.9g %.9g", pts[i][0], pts[i][1], pts[i][2]);
        text[i] = buf;
        obj += "v " + text[i] + "\n";
    }
    plyA = "ply\nformat ascii 1.0\nelement vertex " + std::to_string(pts.size()) +
           "\nproperty double x\nproperty double y\nproperty double z\nelement face " +
           std::to_string(tris.size()) + "\nproperty list uchar int vertex_indices\nend_header\n";
    for (const std::string& t : text) plyA += t + "\n";
    std::vector<std::vector<int32_t>> faces;
    std::vector<std::array<float, 9>> facets;
    for (const auto& t : tris) {
        obj += "f " + std::to_string(t[0] + 1) + "/" + std::to_string(t[0] + 1) + " " + std::to_string(t[1] + 1) +
               " " + std::to_string(t[2] + 1) + "\n";
        plyA += "3 " + std::to_string(t[0]) + " " + std::to_string(t[1]) + " " + std::to_string(t[2]) + "\n";
        faces.push_back({t[0], t[1], t[2]});
        std::array<float, 9> f;
        stlA += " facet normal 0 0 0\n  outer loop\n";
        for (int c = 0; c < 3; ++c) {
            for (int k = 0; k < 3; ++k) f[size_t(3 * c + k)] = float(pts[size_t(t[size_t(c)])][k]);
            stlA += "   vertex " + text[size_t(t[size_t(c)])] + "\n";
        }
        stlA += "  endloop\n endfacet\n";
        facets.push_back(f);
    }
    stlA += "endsolid t\n";
    return {writeFile(dir, "t.obj", obj), writeFile(dir, "ta.ply", plyA), writeFile(dir, "tb.ply", binaryPly(pts, faces)),
            writeFile(dir, "ta.stl", stlA), writeFile(dir, "tb.stl", binaryStl(facets))};
}

void expectSameMesh(const TriangleMesh& a, const TriangleMesh& b)
{
    ASSERT_EQ(a.points.size(), b.points.size());
    ASSERT_EQ(a.triangles.size(), b.triangles.size());
    for (size_t i = 0; i < a.points.size(); ++i) {
        ASSERT_TRUE(a.points[i] == b.points[i]) << "vertex " << i;
    }
    for (size_t i = 0; i < a.triangles.size(); ++i) {
        ASSERT_TRUE(a.triangles[i] == b.triangles[i]) << "triangle " << i;
    }
}

} // namespace

TEST(MeshIO, ParallelReadingDoesNotDependOnTheThreadCount)
{
    const fs::path dir = scratchDir("meshio_parallel");
    const std::vector<std::string> files = writeTorusFiles(dir, 120, 250); // 30000 vertices, 60000 triangles
    for (const std::string& path : files) {
        SCOPED_TRACE(path);
        MeshReadInfo info1, infoN;
        TriangleMesh one, many;
        {
            tbb::global_control gc(tbb::global_control::max_allowed_parallelism, 1);
            one = readMesh(path, info1);
        }
        {
            tbb::global_control gc(tbb::global_control::max_allowed_parallelism, 8);
            many = readMesh(path, infoN);
        }
        expectSameMesh(one, many);
        EXPECT_EQ(one.points.size(), 30000u);
        EXPECT_EQ(one.triangles.size(), 60000u);
        EXPECT_EQ(info1.fileFaces, infoN.fileFaces);
        EXPECT_EQ(info1.doublePrecision, infoN.doublePrecision);
        EXPECT_EQ(info1.doublePrecision, path.find(".stl") == std::string::npos);
    }
    // The sequential path (a trailing comment on a face line sends an OBJ there) reads the same.
    std::ifstream in(files[0], std::ios::binary);
    std::string obj((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    const size_t f = obj.find("\nf ");
    obj.insert(obj.find('\n', f + 1), " # comment");
    const std::string slow = writeFile(dir, "slow.obj", obj);
    MeshReadInfo infoSlow, infoFast;
    const TriangleMesh a = readMesh(slow, infoSlow);
    const TriangleMesh b = readMesh(files[0], infoFast);
    expectSameMesh(a, b);
    EXPECT_EQ(infoSlow.fileFaces, infoFast.fileFaces);
    EXPECT_EQ(infoSlow.doublePrecision, infoFast.doublePrecision);
}
