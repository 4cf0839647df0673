// SPDX-License-Identifier: Apache-2.0
// The Vulkan backend of the main road (gpu/VulkanDevices.h, MeshToLevelSetOptions::device): the
// device's grids against the CPU's, bit for bit, in every sign mode, at several resolutions and
// bands, with and without closest points; batching, interruption, hidden devices, Auto, the CLI.
// Runs on any Vulkan device with 64-bit floats (in CI: Mesa's lavapipe, with the Khronos
// validation layer on and no message allowed); skips with a message where there is none.
#include <levelforge/gpu/VulkanDevices.h>
#include <levelforge/mesh/MeshToLevelSet.h>
#include <levelforge/reference/MeshShapes.h>

#include "TestUtil.h"
#include "gpu/VulkanTestSupport.h"
#include "tools/CliRunner.h"

#include <gtest/gtest.h>

#include <openvdb/openvdb.h>
#include <openvdb/util/NullInterrupter.h>

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <string>

using namespace levelforge;

namespace {

class VulkanTest : public levelforge_test::VulkanFixture
{
};

void expectIdentical(const openvdb::FloatGrid& a, const openvdb::FloatGrid& b, const std::string& what)
{
    levelforge_test::expectIdenticalGrids(a, b, what);
}

MeshToLevelSetOptions options(double voxelSize, double band, SignMode sign, ComputeDevice device)
{
    MeshToLevelSetOptions o;
    o.voxelSize = voxelSize;
    o.exteriorWidth = o.interiorWidth = band;
    o.sign = sign;
    o.device = device;
    return o;
}

TriangleMesh openTorusKnot()
{
    TriangleMesh m = makeTorusKnot();
    m.triangles.resize(m.triangles.size() - 300); // a hole: the winding sign's territory
    return m;
}

} // namespace

TEST_F(VulkanTest, ListsTheChosenDeviceWithFloat64)
{
    const VulkanDeviceList list = listVulkanDevices();
    EXPECT_TRUE(list.compiledIn);
    EXPECT_TRUE(list.loaderFound);
    int chosen = 0;
    for (const VulkanDeviceInfo& d : list.devices) {
        EXPECT_FALSE(d.name.empty());
        if (d.chosen) {
            ++chosen;
            EXPECT_TRUE(d.float64);
            EXPECT_TRUE(d.usable);
        }
    }
    EXPECT_EQ(chosen, 1);
}

TEST_F(VulkanTest, EveryModeResolutionAndBandIsBitIdenticalToTheCpu)
{
    struct Shape { std::string name; TriangleMesh mesh; };
    const Shape shapes[] = {{"torus knot", makeTorusKnot()},
                            {"sphere", makeBuiltinMesh("builtin:sphere")},
                            {"box", makeBuiltinMesh("builtin:box")},
                            {"open torus knot", openTorusKnot()}};
    const SignMode modes[] = {SignMode::Pseudonormal, SignMode::Winding, SignMode::Unsigned};
    for (const Shape& s : shapes) {
        const Vec3d ext = s.mesh.bounds().extents();
        const double extent = std::max({ext[0], ext[1], ext[2]});
        for (const double res : {24.0, 61.0}) {
            for (const double band : {1.0, 3.0, 9.5}) {
                for (const SignMode mode : modes) {
                    const double h = extent / res;
                    MeshToLevelSetStats cs, gs;
                    const auto cpu = meshToLevelSet(s.mesh, options(h, band, mode, ComputeDevice::Cpu), &cs);
                    const auto gpu = meshToLevelSet(s.mesh, options(h, band, mode, ComputeDevice::Vulkan), &gs);
                    const std::string what = s.name + " res " + std::to_string(res) + " band " + std::to_string(band) +
                                             " sign " + toString(mode);
                    EXPECT_EQ(cs.device, "cpu");
                    EXPECT_EQ(gs.device.rfind("vulkan: ", 0), 0u) << gs.device;
                    EXPECT_GT(gs.devicePairs, 0u) << what;
                    expectIdentical(*cpu, *gpu, what);
                    EXPECT_EQ(cs.activeVoxels, gs.activeVoxels) << what;
                }
            }
        }
    }
}

TEST_F(VulkanTest, ClosestPointsAndTrianglesMatchTheCpu)
{
    const TriangleMesh mesh = makeTorusKnot();
    for (const SignMode mode : {SignMode::Pseudonormal, SignMode::Winding}) {
        const auto cpu = meshToLevelSetWithClosestPoints(mesh, options(0.03, 3.0, mode, ComputeDevice::Cpu));
        const auto gpu = meshToLevelSetWithClosestPoints(mesh, options(0.03, 3.0, mode, ComputeDevice::Vulkan));
        expectIdentical(*cpu.levelSet, *gpu.levelSet, toString(mode));
        ASSERT_EQ(cpu.closestPoints->activeVoxelCount(), gpu.closestPoints->activeVoxelCount());
        uint64_t pointBad = 0, triDiff = 0;
        auto cpAcc = gpu.closestPoints->getConstAccessor();
        auto triAcc = gpu.closestTriangles->getConstAccessor();
        for (auto it = cpu.closestPoints->cbeginValueOn(); it; ++it) {
            if (cpAcc.getValue(it.getCoord()) != *it) ++pointBad;
            if (triAcc.getValue(it.getCoord()) != cpu.closestTriangles->tree().getValue(it.getCoord())) ++triDiff;
        }
        // ties (a shared vertex or edge) go to the smaller triangle index on both
        EXPECT_EQ(pointBad, 0u) << toString(mode);
        EXPECT_EQ(triDiff, 0u) << toString(mode);
    }
}

TEST_F(VulkanTest, BatchSizesDoNotChangeTheGrid)
{
    const TriangleMesh mesh = makeTorusKnot();
    MeshToLevelSetOptions o = options(0.03, 3.0, SignMode::Pseudonormal, ComputeDevice::Vulkan);
    MeshToLevelSetStats whole, tiny, one;
    const auto ref = meshToLevelSet(mesh, o, &whole);
    o.deviceMemoryBudget = 256 << 10; // a few dozen leaves per batch
    const auto small = meshToLevelSet(mesh, o, &tiny);
    o.deviceMemoryBudget = 1; // one leaf per batch (each larger than the budget)
    const auto single = meshToLevelSet(mesh, o, &one);
    EXPECT_EQ(whole.deviceBatches, 1u);
    EXPECT_GT(tiny.deviceBatches, 10u);
    EXPECT_GT(one.deviceBatches, tiny.deviceBatches);
    EXPECT_GE(one.deviceBatches, one.candidateVoxels / 512); // one per leaf with a candidate
    expectIdentical(*ref, *small, "256 KiB batches");
    expectIdentical(*ref, *single, "one leaf per batch");
}

TEST_F(VulkanTest, AnEmptyBandDispatchesNothing)
{
    // a band so narrow that no voxel centre is within it: leaves are listed but nothing is found
    TriangleMesh mesh;
    mesh.points = {Vec3d(0.25, 0.25, 0.5), Vec3d(0.75, 0.25, 0.5), Vec3d(0.25, 0.75, 0.5)};
    mesh.triangles = {Vec3I(0, 1, 2)};
    MeshToLevelSetStats s;
    const auto g = meshToLevelSet(mesh, options(1.0, 0.01, SignMode::Unsigned, ComputeDevice::Vulkan), &s);
    EXPECT_EQ(g->activeVoxelCount(), 0u);
}

namespace {
struct StopAfter : openvdb::util::NullInterrupter
{
    int calls = 0, limit;
    explicit StopAfter(int n) : limit(n) {}
    bool wasInterrupted(int = -1) override { return ++calls > limit; }
};
} // namespace

TEST_F(VulkanTest, InterruptionStopsBetweenAndDuringDispatches)
{
    const TriangleMesh mesh = makeTorusKnot();
    for (const int after : {3, 12, 40}) {
        MeshToLevelSetOptions o = options(0.02, 3.0, SignMode::Pseudonormal, ComputeDevice::Vulkan);
        o.deviceMemoryBudget = 128 << 10;
        StopAfter stop(after);
        o.interrupter = &stop;
        EXPECT_THROW(meshToLevelSet(mesh, o), InterruptedError) << "after " << after;
    }
}

TEST_F(VulkanTest, HiddenDevicesFailVulkanAndLeaveAutoOnTheCpu)
{
    setenv("LEVELFORGE_VULKAN_DEVICE", "none", 1);
    const TriangleMesh mesh = makeTorusKnot();
    const VulkanDeviceList list = listVulkanDevices();
    EXPECT_TRUE(list.devices.empty());
    EXPECT_NE(list.problem.find("hidden"), std::string::npos) << list.problem;
    try {
        meshToLevelSet(mesh, options(0.05, 3.0, SignMode::Pseudonormal, ComputeDevice::Vulkan));
        ADD_FAILURE() << "no DeviceError";
    } catch (const DeviceError& e) {
        EXPECT_NE(std::string(e.what()).find("LEVELFORGE_VULKAN_DEVICE=none"), std::string::npos) << e.what();
    }
    MeshToLevelSetOptions o = options(0.05, 3.0, SignMode::Pseudonormal, ComputeDevice::Auto);
    o.deviceMinLeaves = 0;
    MeshToLevelSetStats s;
    const auto grid = meshToLevelSet(mesh, o, &s);
    EXPECT_EQ(s.device, "cpu");
    EXPECT_NE(s.deviceNote.find("hidden"), std::string::npos) << s.deviceNote;
    expectIdentical(*meshToLevelSet(mesh, options(0.05, 3.0, SignMode::Pseudonormal, ComputeDevice::Cpu)), *grid, "auto");
    unsetenv("LEVELFORGE_VULKAN_DEVICE");
}

TEST_F(VulkanTest, AutoUsesOnlyADiscreteGpu)
{
    const VulkanDeviceList list = listVulkanDevices();
    bool discrete = false;
    for (const VulkanDeviceInfo& d : list.devices) discrete = discrete || (d.chosen && d.type == "discrete");
    MeshToLevelSetOptions o = options(0.05, 3.0, SignMode::Pseudonormal, ComputeDevice::Auto);
    o.deviceMinLeaves = 0;
    MeshToLevelSetStats s;
    meshToLevelSet(makeTorusKnot(), o, &s);
    if (discrete) {
        EXPECT_EQ(s.device.rfind("vulkan: ", 0), 0u) << s.device;
    } else {
        EXPECT_EQ(s.device, "cpu");
        EXPECT_TRUE(s.deviceNote.find("not a discrete GPU") != std::string::npos ||
                    s.deviceNote.find("no GPU on this machine") != std::string::npos)
            << s.deviceNote;
    }
    // small work never asks for a device
    o.deviceMinLeaves = 1u << 30;
    MeshToLevelSetStats small;
    meshToLevelSet(makeTorusKnot(), o, &small);
    EXPECT_EQ(small.device, "cpu");
    EXPECT_TRUE(small.deviceNote.empty()) << small.deviceNote;
}

#ifdef LEVELFORGE_CLI_PATH
TEST_F(VulkanTest, CliDeviceVulkanWritesTheCpuGridAndFailsCleanlyWithoutADevice)
{
    namespace fs = std::filesystem;
    const fs::path dir = levelforge_test::scratchDir("cli_vulkan");
    const std::string cpu = (dir / "cpu.vdb").string(), gpu = (dir / "gpu.vdb").string(), none = (dir / "none.vdb").string();
    auto r = levelforge_test::runLevelforge(dir, {"mesh-to-sdf", "builtin:torus-knot", cpu, "--voxel-size", "0.03", "--device", "cpu", "--quiet"});
    ASSERT_EQ(r.code, 0) << r.err;
    r = levelforge_test::runLevelforge(dir, {"mesh-to-sdf", "builtin:torus-knot", gpu, "--voxel-size", "0.03", "--device", "vulkan",
                                             "--quiet", "--report"});
    ASSERT_EQ(r.code, 0) << r.err;
    EXPECT_NE(r.out.find("device:                  vulkan: "), std::string::npos) << r.out;
    expectIdentical(*levelforge_test::readSingleFloatGrid(cpu), *levelforge_test::readSingleFloatGrid(gpu), "CLI");
    r = levelforge_test::runLevelforge(dir, {"devices"});
    EXPECT_EQ(r.code, 0);
    EXPECT_NE(r.out.find("float64:        yes"), std::string::npos) << r.out;
    setenv("LEVELFORGE_VULKAN_DEVICE", "none", 1);
    r = levelforge_test::runLevelforge(dir, {"mesh-to-sdf", "builtin:torus-knot", none, "--voxel-size", "0.03", "--device", "vulkan", "--quiet"});
    EXPECT_NE(r.code, 0);
    EXPECT_EQ(levelforge_test::countLines(r.err, "levelforge: error:"), 1) << r.err;
    EXPECT_NE(r.err.find("hidden"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(none));
    r = levelforge_test::runLevelforge(dir, {"mesh-to-sdf", "builtin:torus-knot", none, "--voxel-size", "0.03", "--device", "auto", "--quiet"});
    EXPECT_EQ(r.code, 0) << r.err;
    r = levelforge_test::runLevelforge(dir, {"devices"});
    EXPECT_EQ(r.code, 0);
    EXPECT_NE(r.out.find("hidden"), std::string::npos) << r.out;
    unsetenv("LEVELFORGE_VULKAN_DEVICE");
}
#endif

TEST_F(VulkanTest, OutOfDeviceMemoryAndDeviceLostFailVulkanAndFallBackUnderAuto)
{
    const TriangleMesh mesh = makeTorusKnot();
    const auto cpu = meshToLevelSet(mesh, options(0.04, 3.0, SignMode::Pseudonormal, ComputeDevice::Cpu));
    setenv("LEVELFORGE_VULKAN_DEVICE", "0", 1); // picked by index: auto uses it, whatever its type
    for (const char* fault : {"oom", "lost"}) {
        setenv("LEVELFORGE_VULKAN_INJECT", fault, 1);
        try {
            meshToLevelSet(mesh, options(0.04, 3.0, SignMode::Pseudonormal, ComputeDevice::Vulkan));
            ADD_FAILURE() << fault << ": no DeviceError";
        } catch (const DeviceError& e) {
            const std::string m = e.what();
            EXPECT_NE(m.find(std::string(fault) == "oom" ? "out of device memory" : "device lost"), std::string::npos) << m;
        }
        MeshToLevelSetOptions o = options(0.04, 3.0, SignMode::Pseudonormal, ComputeDevice::Auto);
        o.deviceMinLeaves = 0;
        MeshToLevelSetStats s;
        const auto grid = meshToLevelSet(mesh, o, &s);
        EXPECT_EQ(s.device, "cpu") << fault;
        EXPECT_NE(s.deviceNote.find("the CPU was used"), std::string::npos) << s.deviceNote;
        expectIdentical(*cpu, *grid, std::string("auto after ") + fault);
    }
    unsetenv("LEVELFORGE_VULKAN_INJECT");
    // the device works again afterwards (a lost device is opened afresh)
    MeshToLevelSetStats s;
    expectIdentical(*cpu, *meshToLevelSet(mesh, options(0.04, 3.0, SignMode::Pseudonormal, ComputeDevice::Vulkan), &s), "after");
    EXPECT_EQ(s.device.rfind("vulkan: ", 0), 0u);
    unsetenv("LEVELFORGE_VULKAN_DEVICE");
}
