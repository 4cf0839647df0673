// SPDX-License-Identifier: Apache-2.0
// VulkanSlabBackend (gpu/VulkanSlabBackend.h) against CpuSlabBackend: slabs filled from random
// cross-sections, and whole T4 scan conversions with every shell, coverage and rasterization,
// bit for bit; batching (tiny budgets, one slab larger than the budget, empty slabs). Runs on
// any Vulkan device with 64-bit floats (CI: lavapipe with validation); skips where there is none.
#include <levelforge/gpu/VulkanSlabBackend.h>
#include <levelforge/core/PseudoNormals.h>
#include <levelforge/reference/MeshShapes.h>
#include <levelforge/scan/TetScanConversion.h>

#include <gtest/gtest.h>

#include "gpu/VulkanTestSupport.h"

#include <openvdb/openvdb.h>

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <random>
#include <string>

using namespace levelforge;

namespace {

class VulkanSlabTest : public levelforge_test::VulkanFixture
{
};

void expectSameSlab(const DenseSlab& a, const DenseSlab& b, const std::string& what)
{
    ASSERT_EQ(a.size(), b.size()) << what;
    uint64_t bad = 0;
    for (size_t i = 0; i < a.size(); ++i)
        if (a.tri[i] != b.tri[i] || std::memcmp(&a.dist[i], &b.dist[i], sizeof(double)) != 0) ++bad;
    EXPECT_EQ(bad, 0u) << what;
    EXPECT_EQ(a.rasterized, b.rasterized) << what;
}

void expectSameGrid(const openvdb::FloatGrid& a, const openvdb::FloatGrid& b, const std::string& what)
{
    levelforge_test::expectIdenticalGrids(a, b, what);
}

} // namespace

TEST_F(VulkanSlabTest, RandomCrossSectionsFillSlabsLikeTheCpu)
{
    const TriangleMesh mesh = makeTorusKnot();
    const PseudoNormals normals(mesh);
    const SlabTriangles tris = SlabTriangles::build(mesh, normals, 0.05);
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> u(-3.0, 35.0);
    std::uniform_int_distribution<uint32_t> pickTri(0, uint32_t(mesh.triangles.size() - 1));
    const openvdb::CoordBBox box(openvdb::Coord(-10, 4, 16), openvdb::Coord(21, 35, 23));
    std::vector<CrossSection> items;
    for (int i = 0; i < 600; ++i) {
        CrossSection cs;
        cs.triangle = pickTri(rng);
        cs.z = 14 + int(rng() % 12); // some outside the box: skipped by both
        // a convex polygon: points on an ellipse, in order (3 to 16 of them); some degenerate rows
        cs.count = 3 + rng() % 14;
        const double cx = u(rng) - 10.0, cy = u(rng) + 4.0, rx = 0.3 + std::abs(u(rng)) / 4.0, ry = (i % 17 == 0) ? 0.0 : 0.3 + std::abs(u(rng)) / 4.0;
        for (uint32_t k = 0; k < cs.count; ++k) {
            const double a = 6.283185307179586 * double(k) / double(cs.count);
            cs.x[k] = cx + rx * std::cos(a);
            cs.y[k] = (i % 5 == 0) ? std::round(cy + ry * std::sin(a)) : cy + ry * std::sin(a); // rows through vertices
        }
        if (i % 40 == 0) cs.count = 0; // empty: skipped
        items.push_back(cs);
    }
    CpuSlabBackend cpu;
    VulkanSlabBackend gpu;
    DenseSlab a, b;
    a.reset(box);
    b.reset(box);
    cpu.fill(a, items.data(), items.size(), tris);
    gpu.fill(b, items.data(), items.size(), tris);
    EXPECT_GT(a.rasterized, 1000u);
    expectSameSlab(a, b, "random items");
    // an empty slab and a slab whose items all miss it
    a.reset(box);
    b.reset(box);
    cpu.fill(a, nullptr, 0, tris);
    gpu.fill(b, nullptr, 0, tris);
    expectSameSlab(a, b, "no items");
}

TEST_F(VulkanSlabTest, EveryShellCoverageAndRasterizationIsBitIdenticalToTheCpu)
{
    // every shell, both coverages, both rasterizations (small grids: lavapipe is a CPU), and a
    // larger grid of the default shell; the complete conservative pseudonormal family gives
    // ~60k cross-sections per slab (batches split by the device's storage-buffer range)
    struct Case { ShellMethod shell; ShellCoverage coverage; bool conservative; double count; };
    std::vector<Case> cases;
    for (const ShellMethod shell : {ShellMethod::PseudoNormal, ShellMethod::Thin, ShellMethod::Offset, ShellMethod::Obb})
        for (const ShellCoverage coverage : {ShellCoverage::Complete, ShellCoverage::Paper})
            for (const bool conservative : {false, true}) cases.push_back({shell, coverage, conservative, 20.0});
    cases.push_back({ShellMethod::Obb, ShellCoverage::Complete, false, 72.0});
    VulkanSlabBackend gpu;
    const TriangleMesh knot = makeTorusKnot(), box = makeBuiltinMesh("builtin:box");
    for (const Case& c : cases)
        for (const TriangleMesh* mesh : {&knot, &box}) {
            // the knot's conservative pseudonormal-family shells give ~60k cross-sections per
            // slab: minutes on lavapipe; the box (12 triangles) has every conservative case
            if (mesh == &knot && c.conservative) continue;
            TetScanOptions o;
            o.voxelCount = c.count;
            o.exteriorWidth = o.interiorWidth = 3.0;
            o.shell = c.shell;
            o.coverage = c.coverage;
            o.conservative = c.conservative;
            TetScanStats cs, gs;
            const auto cpu = meshToLevelSetScan(*mesh, o, &cs);
            o.backend = &gpu;
            const auto g = meshToLevelSetScan(*mesh, o, &gs);
            const std::string what = std::string(mesh == &box ? "box " : "knot ") + toString(c.shell) +
                                     (c.coverage == ShellCoverage::Paper ? " paper" : " complete") +
                                     (c.conservative ? " conservative" : "") + " at " + std::to_string(c.count);
            expectSameGrid(*cpu, *g, what);
            EXPECT_EQ(cs.voxelsRasterized, gs.voxelsRasterized) << what;
        }
    EXPECT_GT(gpu.stats().batches, 0u);
}

TEST_F(VulkanSlabTest, BatchSizesDoNotChangeTheGrid)
{
    const TriangleMesh mesh = makeTorusKnot();
    TetScanOptions o;
    o.voxelCount = 48;
    o.exteriorWidth = o.interiorWidth = 3.0;
    const auto ref = meshToLevelSetScan(mesh, o);
    for (const uint64_t budget : {uint64_t(1), uint64_t(200) << 10, uint64_t(0)}) {
        VulkanSlabBackend gpu(budget); // 1 byte: every slab a batch of its own, larger than the budget
        o.backend = &gpu;
        expectSameGrid(*ref, *meshToLevelSetScan(mesh, o), "budget " + std::to_string(budget));
        if (budget == 1) EXPECT_EQ(gpu.stats().batches, gpu.stats().slabs);
    }
}

TEST_F(VulkanSlabTest, HiddenDevicesGiveADeviceError)
{
    setenv("LEVELFORGE_VULKAN_DEVICE", "none", 1);
    EXPECT_THROW(VulkanSlabBackend(), DeviceError);
    unsetenv("LEVELFORGE_VULKAN_DEVICE");
}

#ifdef LEVELFORGE_CLI_PATH
#include "TestUtil.h"
#include "tools/CliRunner.h"

TEST_F(VulkanSlabTest, CliScanOnTheDeviceWritesTheCpuGrid)
{
    namespace fs = std::filesystem;
    const fs::path dir = levelforge_test::scratchDir("cli_vulkan_scan");
    const std::string cpu = (dir / "cpu.vdb").string(), gpu = (dir / "gpu.vdb").string();
    auto r = levelforge_test::runLevelforge(dir, {"mesh-to-sdf", "builtin:torus-knot", cpu, "--voxel-count", "48", "--method", "scan",
                                                  "--device", "cpu", "--quiet"});
    ASSERT_EQ(r.code, 0) << r.err;
    r = levelforge_test::runLevelforge(dir, {"mesh-to-sdf", "builtin:torus-knot", gpu, "--voxel-count", "48", "--method", "scan",
                                             "--device", "vulkan", "--quiet", "--report"});
    ASSERT_EQ(r.code, 0) << r.err;
    EXPECT_NE(r.out.find("slab device:             vulkan: "), std::string::npos) << r.out;
    expectSameGrid(*levelforge_test::readSingleFloatGrid(cpu), *levelforge_test::readSingleFloatGrid(gpu), "CLI scan");
}
#endif
