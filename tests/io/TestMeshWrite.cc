// SPDX-License-Identifier: Apache-2.0
// writeMesh(): what the writers choose (tests/io/TestMeshIO.cc has the round trips and errors).
#include "TestUtil.h"

#include <levelforge/io/MeshIO.h>
#include <levelforge/reference/MeshShapes.h>

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <utility>

namespace fs = std::filesystem;
using namespace levelforge;
using levelforge_test::scratchDir;

namespace {

TEST(MeshIO, PlyIsWrittenInFloatOnlyWhenThatLosesNothing)
{
    // A mesh whose coordinates are all floats (extracted from a float grid) is written with float
    // properties, half the size; one double-only coordinate keeps the whole file in double.
    const fs::path dir = scratchDir("meshio_ply_float");
    TriangleMesh m = makeIcosphere(Vec3d(0.0), 1.0, 2);
    for (Vec3d& p : m.points) {
        for (int k = 0; k < 3; ++k) {
            volatile float f = static_cast<float>(p[k]); // GCC 12.2 -O2 would drop a plain round trip
            p[k] = f;
        }
    }
    const std::string f = (dir / "f.ply").string(), d = (dir / "d.ply").string();
    writeMesh(m, f);
    TriangleMesh md = m;
    md.points[5][1] = 0.1; // not a float
    writeMesh(md, d);
    const auto header = [](const std::string& path) {
        std::ifstream in(path, std::ios::binary);
        std::string text, line;
        while (std::getline(in, line) && line != "end_header") text += line + "\n";
        return text;
    };
    EXPECT_NE(header(f).find("property float x\nproperty float y\nproperty float z\n"), std::string::npos) << header(f);
    EXPECT_NE(header(d).find("property double x\nproperty double y\nproperty double z\n"), std::string::npos) << header(d);
    EXPECT_LT(fs::file_size(f) + 12 * m.points.size(), fs::file_size(d) + 1);
    for (const auto& [path, mesh] : {std::pair{f, m}, std::pair{d, md}}) {
        const TriangleMesh back = readMesh(path);
        ASSERT_EQ(back.points.size(), mesh.points.size()) << path;
        ASSERT_EQ(back.triangles.size(), mesh.triangles.size()) << path;
        for (size_t i = 0; i < mesh.points.size(); ++i) ASSERT_EQ(back.points[i], mesh.points[i]) << path << " " << i;
        for (size_t i = 0; i < mesh.triangles.size(); ++i) ASSERT_EQ(back.triangles[i], mesh.triangles[i]) << path << " " << i;
    }
}

} // namespace
