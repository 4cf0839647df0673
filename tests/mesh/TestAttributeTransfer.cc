// SPDX-License-Identifier: Apache-2.0
// Attribute transfer (issue 16, item 6): per-corner attributes read from OBJ / PLY files, and
// their transfer to grids at each voxel's exact closest point (mesh/AttributeTransfer.h,
// MeshToSdfOptions::attributes).
#include "TestUtil.h"

#include <levelforge/core/Exceptions.h>
#include <levelforge/core/TriangleDistance.h>
#include <levelforge/io/MeshIO.h>
#include <levelforge/mesh/AttributeTransfer.h>
#include <levelforge/pipeline/MeshToSdf.h>
#include <levelforge/reference/MeshShapes.h>

#include <openvdb/openvdb.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

namespace fs = std::filesystem;
using namespace levelforge;
using levelforge_test::scratchDir;

namespace {

/// The linear colour ramp of the plane tests.
Vec3d ramp(const Vec3d& p) { return Vec3d(0.3 * p[0] + 0.1, -0.2 * p[1] + 0.5, 0.1 * p[0] + 0.4 * p[1] - 0.05 * p[2]); }

/// A square [-1, 1]^2 at z = 0 of n x n quads (two triangles each, alternating diagonals), with
/// "Cd" the ramp at every corner.
TriangleMesh rampPlane(int n)
{
    TriangleMesh m;
    m.source = "ramp plane";
    for (int j = 0; j <= n; ++j)
        for (int i = 0; i <= n; ++i) m.points.emplace_back(-1.0 + 2.0 * i / n, -1.0 + 2.0 * j / n, 0.0);
    auto id = [n](int i, int j) { return uint32_t(j * (n + 1) + i); };
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
            if ((i + j) % 2) {
                m.triangles.emplace_back(id(i, j), id(i + 1, j), id(i + 1, j + 1));
                m.triangles.emplace_back(id(i, j), id(i + 1, j + 1), id(i, j + 1));
            } else {
                m.triangles.emplace_back(id(i, j), id(i + 1, j), id(i, j + 1));
                m.triangles.emplace_back(id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
            }
        }
    MeshAttribute cd;
    cd.name = "Cd";
    for (const Vec3I& t : m.triangles)
        for (int k = 0; k < 3; ++k) {
            const Vec3d c = ramp(m.points[t[k]]);
            cd.values.insert(cd.values.end(), {float(c[0]), float(c[1]), float(c[2])});
        }
    m.attributes.push_back(cd);
    return m;
}

/// The exact closest point of @p mesh to @p p (brute force).
Vec3d closestOnMesh(const TriangleMesh& mesh, const Vec3d& p)
{
    double best = 1e300;
    Vec3d q(0.0);
    for (const Vec3I& t : mesh.triangles) {
        const TriangleClosestPoint c = closestPointOnTriangle(p, mesh.points[t[0]], mesh.points[t[1]], mesh.points[t[2]]);
        if (c.distanceSqr < best) {
            best = c.distanceSqr;
            q = c.point;
        }
    }
    return q;
}

void writeText(const fs::path& path, const std::string& text) { std::ofstream(path, std::ios::binary) << text; }

/// Corner k of triangle t of attribute @p a.
Vec3d corner(const MeshAttribute& a, size_t t, int k)
{
    const float* v = a.values.data() + (3 * t + size_t(k)) * size_t(a.components);
    return a.components == 3 ? Vec3d(v[0], v[1], v[2]) : Vec3d(v[0], 0.0, 0.0);
}

const MeshAttribute& attribute(const TriangleMesh& m, const std::string& name) { return findMeshAttribute(m, name); }

} // namespace

TEST(AttributeTransfer, LinearColourRampOnAPlaneIsExact)
{
    openvdb::initialize();
    const TriangleMesh mesh = rampPlane(6);
    MeshToSdfOptions o;
    o.voxelSize = 0.07;
    o.exteriorWidth = o.interiorWidth = 3.0;
    o.sign = SignMode::Unsigned;
    o.attributes = {"Cd"};
    const MeshToSdfGrids g = meshToSdfGrids(mesh, o);
    ASSERT_EQ(g.attributes.size(), 1u);
    auto cd = openvdb::gridPtrCast<openvdb::Vec3SGrid>(g.attributes[0]);
    ASSERT_TRUE(cd);
    EXPECT_EQ(cd->getName(), "Cd");
    EXPECT_EQ(cd->transform(), g.sdf->transform());
    EXPECT_EQ(cd->activeVoxelCount(), g.sdf->activeVoxelCount());
    EXPECT_TRUE(cd->tree().hasSameTopology(g.sdf->tree()));
    size_t checked = 0;
    double worst = 0.0;
    for (auto it = cd->tree().cbeginValueOn(); it; ++it) {
        const Vec3d p = cd->transform().indexToWorld(it.getCoord());
        const Vec3d want = ramp(closestOnMesh(mesh, p));
        for (int c = 0; c < 3; ++c) worst = std::max(worst, std::abs(double((*it)[c]) - want[c]));
        ++checked;
    }
    EXPECT_GT(checked, 1000u);
    EXPECT_LE(worst, 1e-5);
}

TEST(AttributeTransfer, RampExactUnderAReflectedRotatedReferenceTransform)
{
    openvdb::initialize();
    const TriangleMesh mesh = rampPlane(4);
    // rotation about z by 30 degrees, a reflection of x, voxel size 0.09, an offset
    const double h = 0.09, a = M_PI / 6.0;
    openvdb::math::Mat4d m = openvdb::math::Mat4d::identity();
    m(0, 0) = -h * std::cos(a); m(0, 1) = -h * std::sin(a);
    m(1, 0) = -h * std::sin(a); m(1, 1) = h * std::cos(a);
    m(2, 2) = h;
    m.setTranslation(openvdb::Vec3d(0.013, -0.021, 0.034));
    MeshToSdfOptions o;
    o.transform = openvdb::math::Transform::createLinearTransform(m);
    o.exteriorWidth = o.interiorWidth = 2.0;
    o.sign = SignMode::Unsigned;
    o.attributes = {"Cd"};
    o.primitiveIndexGridName = "primitive";
    const MeshToSdfGrids g = meshToSdfGrids(mesh, o);
    auto cd = openvdb::gridPtrCast<openvdb::Vec3SGrid>(g.attributes.at(0));
    ASSERT_TRUE(cd && g.primitiveIndex);
    EXPECT_EQ(cd->transform(), *o.transform);
    EXPECT_EQ(cd->activeVoxelCount(), g.primitiveIndex->activeVoxelCount());
    double worst = 0.0;
    for (auto it = cd->tree().cbeginValueOn(); it; ++it) {
        const Vec3d p = cd->transform().indexToWorld(it.getCoord());
        const Vec3d want = ramp(closestOnMesh(mesh, p));
        for (int c = 0; c < 3; ++c) worst = std::max(worst, std::abs(double((*it)[c]) - want[c]));
    }
    EXPECT_GT(cd->activeVoxelCount(), 100u);
    EXPECT_LE(worst, 1e-5);
}

TEST(AttributeTransfer, NormalsOnASphere)
{
    openvdb::initialize();
    const Vec3d c(0.1, -0.2, 0.3);
    TriangleMesh mesh = makeIcosphere(c, 1.0, 4);
    MeshAttribute n;
    n.name = "N";
    for (const Vec3I& t : mesh.triangles)
        for (int k = 0; k < 3; ++k) {
            const Vec3d d = (mesh.points[t[k]] - c).unitSafe();
            n.values.insert(n.values.end(), {float(d[0]), float(d[1]), float(d[2])});
        }
    mesh.attributes.push_back(n);
    MeshToSdfOptions o;
    o.voxelCount = 48;
    o.attributes = {"N"};
    const MeshToSdfGrids g = meshToSdfGrids(mesh, o);
    auto grid = openvdb::gridPtrCast<openvdb::Vec3SGrid>(g.attributes.at(0));
    ASSERT_TRUE(grid);
    EXPECT_EQ(grid->getVectorType(), openvdb::VEC_COVARIANT_NORMALIZE);
    EXPECT_EQ(grid->activeVoxelCount(), g.sdf->activeVoxelCount());
    double worstDot = 1.0;
    for (auto it = grid->tree().cbeginValueOn(); it; ++it) {
        const Vec3d p = grid->transform().indexToWorld(it.getCoord());
        const Vec3d radial = (p - c).unitSafe();
        const Vec3d v{double((*it)[0]), double((*it)[1]), double((*it)[2])};
        // the interpolated normal at the closest point: radial, within the flat facets' error
        worstDot = std::min(worstDot, v.dot(radial) / v.length());
        EXPECT_GT(v.length(), 0.99);
        EXPECT_LE(v.length(), 1.0 + 1e-6);
    }
    EXPECT_GT(worstDot, 0.995); // within 0.1 radian (the facets span about 0.07)
}

TEST(AttributeTransfer, DirectCallOnAClosestTriangleGrid)
{
    openvdb::initialize();
    TriangleMesh mesh = rampPlane(2);
    // a float attribute: the ramp's first component
    MeshAttribute s;
    s.name = "red";
    s.components = 1;
    const MeshAttribute& cd = mesh.attributes[0];
    for (size_t i = 0; i < cd.values.size(); i += 3) s.values.push_back(cd.values[i]);
    mesh.attributes.push_back(s);
    auto tris = openvdb::Int32Grid::create(-1);
    tris->setTransform(openvdb::math::Transform::createLinearTransform(0.25));
    // voxel (1, 1, 2) is centred at (0.25, 0.25, 0.5): above triangle 0 or 1 of the plane
    const openvdb::Coord ijk(1, 1, 2);
    const Vec3d p = tris->transform().indexToWorld(ijk);
    int32_t best = -1;
    double bestD = 1e300;
    for (size_t t = 0; t < mesh.triangles.size(); ++t) {
        const Vec3I& tri = mesh.triangles[t];
        const double d = closestPointOnTriangle(p, mesh.points[tri[0]], mesh.points[tri[1]], mesh.points[tri[2]]).distanceSqr;
        if (d < bestD) { bestD = d; best = int32_t(t); }
    }
    tris->tree().setValueOn(ijk, best);
    tris->tree().setValueOn(openvdb::Coord(0, 0, 0), 1000); // out of range: left inactive
    AttributeTransferOptions ao;
    ao.gridName = "r";
    auto g = openvdb::gridPtrCast<openvdb::FloatGrid>(transferAttribute(mesh, "red", *tris, ao));
    ASSERT_TRUE(g);
    EXPECT_EQ(g->getName(), "r");
    EXPECT_EQ(g->activeVoxelCount(), 1u);
    EXPECT_NEAR(g->tree().getValue(ijk), ramp(Vec3d(0.25, 0.25, 0.0))[0], 1e-6);
    EXPECT_THROW(transferAttribute(mesh, "N", *tris), InvalidArgumentError);
    try {
        transferAttribute(mesh, "uv", *tris);
        ADD_FAILURE() << "no error";
    } catch (const InvalidArgumentError& e) {
        EXPECT_NE(std::string(e.what()).find("no vertex attribute 'uv' (it has: Cd, red)"), std::string::npos) << e.what();
    }
    mesh.attributes[1].values.pop_back(); // out of step with the triangles
    EXPECT_THROW(transferAttribute(mesh, "red", *tris), InvalidMeshError);
}

TEST(AttributeTransfer, UnknownAttributeAndUnsupportedModesThrowBeforeWork)
{
    openvdb::initialize();
    const TriangleMesh mesh = rampPlane(2);
    MeshToSdfOptions o;
    o.voxelSize = 0.1;
    o.sign = SignMode::Unsigned;
    o.attributes = {"N"};
    try {
        meshToSdfGrids(mesh, o);
        FAIL() << "no error";
    } catch (const InvalidArgumentError& e) {
        EXPECT_NE(std::string(e.what()).find("no vertex attribute 'N' (it has: Cd)"), std::string::npos) << e.what();
    }
    o.attributes = {"Cd"};
    o.gridName = "Cd";
    EXPECT_THROW(meshToSdfGrids(mesh, o), InvalidArgumentError); // names must be distinct
    o.gridName = "surface";
    o.attributes = {"Cd", "Cd"};
    EXPECT_THROW(meshToSdfGrids(mesh, o), InvalidArgumentError);
    o.attributes = {"Cd"};
    o.method = BandMethod::Scan;
    o.sign = SignMode::Auto;
    EXPECT_THROW(meshToSdfGrids(mesh, o), InvalidArgumentError);
    o.method = BandMethod::Chang;
    o.expansion = Expansion::Sweep;
    EXPECT_THROW(meshToSdfGrids(mesh, o), InvalidArgumentError);
    // meshToSdf() ignores the attributes
    o.expansion = Expansion::None;
    o.sign = SignMode::Unsigned;
    o.attributes = {"nothing"};
    EXPECT_NO_THROW(meshToSdf(mesh, o));
}

// ---------------------------------------------------------------- reading

TEST(MeshAttributesRead, ObjSeamsAreKeptPerCorner)
{
    const fs::path dir = scratchDir("attributes_obj_seams");
    const fs::path path = dir / "seam.obj";
    // two triangles sharing the edge 2-3; vertex 2 and 3 have a different uv and normal in each
    writeText(path,
              "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
              "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvt 0.5 0.5 0.25\nvt 0.75 0.125\n"
              "vn 0 0 1\nvn 0 1 0\nvn 1 0 0\n"
              "f 1/1/1 2/2/1 3/3/1\n"
              "f 1/5/2 3/6/3 4/4/2\n");
    MeshReadInfo info;
    MeshReadOptions ro;
    ro.attributes = {"uv", "N"};
    const TriangleMesh m = readMesh(path.string(), ro, info);
    ASSERT_EQ(m.triangleCount(), 2u);
    ASSERT_EQ(m.attributes.size(), 2u);
    const MeshAttribute& uv = attribute(m, "uv");
    const MeshAttribute& n = attribute(m, "N");
    EXPECT_EQ(uv.components, 3);
    // triangle 0: vertices 0 1 2 with vt 1 2 3 and vn 1
    EXPECT_EQ(corner(uv, 0, 0), Vec3d(0, 0, 0));
    EXPECT_EQ(corner(uv, 0, 1), Vec3d(1, 0, 0));
    EXPECT_EQ(corner(uv, 0, 2), Vec3d(1, 1, 0));
    // triangle 1: vertices 0 2 3 with vt 5 6 4: vertex 0 and 2 have other uvs here (seams)
    EXPECT_EQ(corner(uv, 1, 0), Vec3d(0.5, 0.5, 0.25));
    EXPECT_EQ(corner(uv, 1, 1), Vec3d(0.75, 0.125, 0));
    EXPECT_EQ(corner(uv, 1, 2), Vec3d(0, 1, 0));
    EXPECT_EQ(corner(n, 0, 2), Vec3d(0, 0, 1));
    EXPECT_EQ(corner(n, 1, 0), Vec3d(0, 1, 0));
    EXPECT_EQ(corner(n, 1, 1), Vec3d(1, 0, 0));
    EXPECT_EQ(meshFileAttributes(path.string()), (std::vector<std::string>{"N", "uv"}));
    // without options: no attributes
    EXPECT_TRUE(readMesh(path.string()).attributes.empty());
}

TEST(MeshAttributesRead, ObjQuadsAndDroppedFacesKeepTheRightCorners)
{
    const fs::path dir = scratchDir("attributes_obj_quads");
    const fs::path path = dir / "quads.obj";
    // a degenerate face first (dropped), a quad with a repeated corner, a pentagon, relative indices
    writeText(path,
              "v 0 0 0 1 0 0\nv 1 0 0 0 1 0\nv 1 1 0 0 0 1\nv 0 1 0 1 1 0\nv 0.5 1.5 0 0 1 1\n"
              "vt 0.0 0.0\nvt 0.1 0.0\nvt 0.1 0.1\nvt 0.0 0.1\nvt 0.05 0.15\n"
              "f 1/1 1/1 2/2\n"
              "f 1/4 2/3 2/3 3/2 4/1\n"
              "f -5/-5 -4/-4 -3/-3 -1/-1 -2/-2\n");
    MeshReadInfo info;
    MeshReadOptions ro;
    ro.attributes = {"Cd", "uv", "Cd"}; // a repeated name counts once
    const TriangleMesh m = readMesh(path.string(), ro, info);
    ASSERT_EQ(m.attributes.size(), 2u);
    ASSERT_EQ(m.triangleCount(), 2u + 3u);
    const MeshAttribute& cd = attribute(m, "Cd");
    const MeshAttribute& uv = attribute(m, "uv");
    const Vec3d colours[5] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {1, 1, 0}, {0, 1, 1}};
    const double quadUv[4][2] = {{0.0, 0.1}, {0.1, 0.1}, {0.1, 0.0}, {0.0, 0.0}}; // vt of 1 2 3 4 in face 1
    const double pentUv[5][2] = {{0.0, 0.0}, {0.1, 0.0}, {0.1, 0.1}, {0.0, 0.1}, {0.05, 0.15}};
    // the degenerate face never reaches the reader's face list (OpenMesh drops it): the quad is
    // face 0, the pentagon face 1
    for (size_t t = 0; t < m.triangleCount(); ++t) {
        const uint32_t f = m.sourceFace(t);
        EXPECT_EQ(f, t < 2 ? 0u : 1u);
        for (int k = 0; k < 3; ++k) {
            const uint32_t v = m.triangles[t][k];
            EXPECT_EQ(corner(cd, t, k), colours[v]) << t << " " << k;
            const double* want = t < 2 ? quadUv[v] : pentUv[v];
            EXPECT_NEAR(corner(uv, t, k)[0], want[0], 1e-7) << t << " " << k;
            EXPECT_NEAR(corner(uv, t, k)[1], want[1], 1e-7) << t << " " << k;
        }
    }
}

TEST(MeshAttributesRead, ObjErrors)
{
    const fs::path dir = scratchDir("attributes_obj_errors");
    const fs::path plain = dir / "plain.obj";
    writeText(plain, "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3\n");
    MeshReadInfo info;
    MeshReadOptions ro;
    ro.attributes = {"Cd"};
    try {
        readMesh(plain.string(), ro, info);
        FAIL() << "no error";
    } catch (const InvalidArgumentError& e) {
        EXPECT_EQ(std::string(e.what()), plain.string() + ": no vertex attribute 'Cd' (it has: N)");
    }
    ro.attributes = {"N"}; // the third corner has no normal
    EXPECT_THROW(readMesh(plain.string(), ro, info), InvalidMeshError);
    const fs::path some = dir / "some.obj";
    writeText(some, "v 0 0 0 1 0 0\nv 1 0 0\nv 0 1 0 0 0 1\nf 1 2 3\n");
    ro.attributes = {"Cd"}; // vertex 1 has no colour
    EXPECT_THROW(readMesh(some.string(), ro, info), InvalidMeshError);
    ro.attributes = {"Cd"};
    EXPECT_THROW(readMesh((dir / "missing.obj").string(), ro, info), IoError);
}

TEST(MeshAttributesRead, PlyColoursNormalsAndProperties)
{
    const fs::path dir = scratchDir("attributes_ply");
    const fs::path ascii = dir / "colour.ply";
    writeText(ascii,
              "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
              "property float nx\nproperty float ny\nproperty float nz\n"
              "property uchar red\nproperty uchar green\nproperty uchar blue\nproperty float quality\n"
              "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
              "0 0 0 0 0 1 255 0 0 0.5\n1 0 0 0 0 1 0 255 0 1.5\n1 1 0 0 0 1 0 0 255 2.5\n0 1 0 0 0 1 51 102 153 3.5\n"
              "4 0 1 2 3\n");
    EXPECT_EQ(meshFileAttributes(ascii.string()), (std::vector<std::string>{"Cd", "N", "quality"}));
    MeshReadInfo info;
    MeshReadOptions ro;
    ro.attributes = {"Cd", "quality", "N"};
    const TriangleMesh m = readMesh(ascii.string(), ro, info);
    ASSERT_EQ(m.triangleCount(), 2u); // the quad, split
    const MeshAttribute& cd = attribute(m, "Cd");
    const MeshAttribute& q = attribute(m, "quality");
    EXPECT_EQ(q.components, 1);
    const Vec3d colours[4] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {0.2, 0.4, 0.6}};
    for (size_t t = 0; t < 2; ++t)
        for (int k = 0; k < 3; ++k) {
            const uint32_t v = m.triangles[t][k];
            for (int c = 0; c < 3; ++c) EXPECT_NEAR(corner(cd, t, k)[c], colours[v][c], 1e-7);
            EXPECT_EQ(corner(q, t, k)[0], 0.5 + v);
            EXPECT_EQ(corner(attribute(m, "N"), t, k), Vec3d(0, 0, 1));
        }
    ro.attributes = {"uv"};
    try {
        readMesh(ascii.string(), ro, info);
        FAIL() << "no error";
    } catch (const InvalidArgumentError& e) {
        EXPECT_EQ(std::string(e.what()), ascii.string() + ": no vertex attribute 'uv' (it has: Cd, N, quality)");
    }

    // binary little endian: float colours and s, t
    const fs::path bin = dir / "binary.ply";
    {
        std::ofstream out(bin, std::ios::binary);
        out << "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
               "property float z\nproperty float red\nproperty float green\nproperty float blue\nproperty float s\n"
               "property float t\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n";
        const float v[3][8] = {{0, 0, 0, 0.25f, 0.5f, 0.75f, 0.0f, 0.0f},
                               {1, 0, 0, 1.0f, 0.0f, 0.5f, 1.0f, 0.0f},
                               {0, 1, 0, 0.0f, 1.0f, 0.0f, 0.0f, 1.0f}};
        out.write(reinterpret_cast<const char*>(v), sizeof(v));
        const unsigned char n = 3;
        const int32_t idx[3] = {0, 1, 2};
        out.write(reinterpret_cast<const char*>(&n), 1);
        out.write(reinterpret_cast<const char*>(idx), sizeof(idx));
    }
    ro.attributes = {"uv", "Cd"};
    const TriangleMesh b = readMesh(bin.string(), ro, info);
    ASSERT_EQ(b.triangleCount(), 1u);
    EXPECT_EQ(corner(attribute(b, "Cd"), 0, 0), Vec3d(0.25, 0.5, 0.75));
    EXPECT_EQ(corner(attribute(b, "uv"), 0, 1), Vec3d(1, 0, 0));
    EXPECT_EQ(corner(attribute(b, "uv"), 0, 2), Vec3d(0, 1, 0));
}

TEST(MeshAttributesRead, OtherFormatsHaveNone)
{
    const fs::path dir = scratchDir("attributes_off");
    const fs::path off = dir / "tri.off";
    writeText(off, "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
    EXPECT_TRUE(meshFileAttributes(off.string()).empty());
    MeshReadInfo info;
    MeshReadOptions ro;
    ro.attributes = {"Cd"};
    try {
        readMesh(off.string(), ro, info);
        FAIL() << "no error";
    } catch (const InvalidArgumentError& e) {
        EXPECT_EQ(std::string(e.what()), off.string() + ": no vertex attribute 'Cd' (it has none)");
    }
}
