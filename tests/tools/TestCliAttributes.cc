// SPDX-License-Identifier: Apache-2.0
// `levelforge mesh-to-sdf --attribute` end to end (issue 16, item 6): the attribute grids in the
// output file, and an attribute the mesh does not have: one error line, no output.
#include "CliRunner.h"
#include "TestUtil.h"

#include <levelforge/io/VdbIO.h>

#include <openvdb/openvdb.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

namespace fs = std::filesystem;
using levelforge_test::scratchDir;

#ifdef LEVELFORGE_CLI_PATH

namespace {

using levelforge_test::CliRun;
using levelforge_test::countLines;

/// A unit box of 6 quads with a colour per vertex (its position) and a uv per corner.
std::string writeColourBox(const fs::path& dir)
{
    const std::string path = (dir / "box.obj").string();
    std::ofstream out(path);
    out << "v -0.5 -0.5 -0.5 0 0 0\nv 0.5 -0.5 -0.5 1 0 0\nv 0.5 0.5 -0.5 1 1 0\nv -0.5 0.5 -0.5 0 1 0\n"
           "v -0.5 -0.5 0.5 0 0 1\nv 0.5 -0.5 0.5 1 0 1\nv 0.5 0.5 0.5 1 1 1\nv -0.5 0.5 0.5 0 1 1\n"
           "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
           "f 1/1 4/2 3/3 2/4\nf 5/1 6/2 7/3 8/4\nf 1/1 2/2 6/3 5/4\n"
           "f 2/1 3/2 7/3 6/4\nf 3/1 4/2 8/3 7/4\nf 4/1 1/2 5/3 8/4\n";
    return path;
}

using levelforge_test::expectCleanFailure;

} // namespace

TEST(CliAttributes, ColourAndUvGridsInTheOutput)
{
    openvdb::initialize();
    const fs::path dir = scratchDir("cli_attributes");
    const std::string mesh = writeColourBox(dir);
    const std::string out = (dir / "box.vdb").string();
    // repeated and comma-separated are the same
    const std::string repeated = (dir / "box_repeated.vdb").string();
    const CliRun rr = levelforge_test::runLevelforge(dir, {"mesh-to-sdf", mesh, repeated, "--voxel-size", "0.05", "--quiet",
                                                           "--attribute", "Cd", "--attribute", "uv"});
    ASSERT_EQ(rr.code, 0) << rr.command << "\n" << rr.err;
    EXPECT_NE(rr.out.find("attribute grid 'Cd' (vec3s)"), std::string::npos) << rr.out;
    EXPECT_NE(rr.out.find("attribute grid 'uv' (vec3s)"), std::string::npos) << rr.out;
    EXPECT_EQ(levelforge::readGrids(repeated)->size(), 3u);
    const CliRun r = levelforge_test::runLevelforge(dir, {"mesh-to-sdf", mesh, out, "--voxel-size", "0.05", "--quiet",
                                                          "--attribute", "Cd,uv", "--primitive-index-grid", "prim"});
    ASSERT_EQ(r.code, 0) << r.command << "\n" << r.err;
    EXPECT_NE(r.out.find("attribute grid 'Cd' (vec3s)"), std::string::npos) << r.out;
    const auto grids = levelforge::readGrids(out);
    ASSERT_EQ(grids->size(), 4u);
    openvdb::FloatGrid::Ptr sdf;
    openvdb::Vec3SGrid::Ptr cd, uv;
    for (const auto& g : *grids) {
        if (g->getName() == "surface") sdf = openvdb::gridPtrCast<openvdb::FloatGrid>(g);
        if (g->getName() == "Cd") cd = openvdb::gridPtrCast<openvdb::Vec3SGrid>(g);
        if (g->getName() == "uv") uv = openvdb::gridPtrCast<openvdb::Vec3SGrid>(g);
    }
    ASSERT_TRUE(sdf && cd && uv);
    EXPECT_EQ(cd->transform(), sdf->transform());
    EXPECT_EQ(cd->activeVoxelCount(), sdf->activeVoxelCount());
    EXPECT_EQ(uv->activeVoxelCount(), sdf->activeVoxelCount());
    // the colour is the position + 0.5, linear on every face: at every voxel it is the closest
    // point + 0.5, which lies on the box's surface
    double worst = 0.0;
    for (auto it = cd->tree().cbeginValueOn(); it; ++it) {
        const openvdb::Vec3d p = cd->transform().indexToWorld(it.getCoord());
        openvdb::Vec3d q;
        for (int c = 0; c < 3; ++c) q[c] = std::clamp(p[c], -0.5, 0.5);
        const bool inside = std::abs(p[0]) < 0.5 && std::abs(p[1]) < 0.5 && std::abs(p[2]) < 0.5;
        if (inside) continue; // the closest face of an inside voxel: checked by the library tests
        for (int c = 0; c < 3; ++c) worst = std::max(worst, std::abs(double((*it)[c]) - (q[c] + 0.5)));
    }
    EXPECT_LE(worst, 1e-5);
    // above the middle of the top face (z = 0.5, vt 1..4 at 5 6 7 8): uv (0.5, 0.5, 0)
    const openvdb::Vec3s top = uv->tree().getValue(openvdb::Coord(0, 0, 11));
    EXPECT_NEAR(top[0], 0.5f, 1e-6);
    EXPECT_NEAR(top[1], 0.5f, 1e-6);
    EXPECT_EQ(top[2], 0.0f);
}

TEST(CliAttributes, UnknownAttributeLeavesNoOutput)
{
    const fs::path dir = scratchDir("cli_attributes_bad");
    const std::string mesh = writeColourBox(dir);
    const std::string out = (dir / "out.vdb").string();
    auto run = [&](std::vector<std::string> extra) {
        std::vector<std::string> args = {"mesh-to-sdf", mesh, out, "--voxel-size", "0.1", "--quiet"};
        args.insert(args.end(), extra.begin(), extra.end());
        return levelforge_test::runLevelforge(dir, args);
    };
    expectCleanFailure(run({"--attribute", "N"}), out, "no vertex attribute 'N' (it has: Cd, uv)");
    expectCleanFailure(run({"--attribute", "Cd,,uv"}), out, "--attribute");
    expectCleanFailure(run({"--attribute", "Cd", "--expansion", "sweep", "--exterior-band", "6"}), out,
                       "attribute transfer");
    expectCleanFailure(run({"--attribute", "Cd", "--fill-interior"}), out, "attribute transfer");
    expectCleanFailure(run({"--attribute", "Cd", "--grid-name", "Cd"}), out, "distinct");
    const CliRun builtin = levelforge_test::runLevelforge(
        dir, {"mesh-to-sdf", "builtin:sphere", out, "--voxel-count", "16", "--quiet", "--attribute", "Cd"});
    expectCleanFailure(builtin, out, "no vertex attribute 'Cd' (it has none)");
}

#endif // LEVELFORGE_CLI_PATH
