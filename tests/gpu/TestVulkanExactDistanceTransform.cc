// SPDX-License-Identifier: Apache-2.0
// The dense exact EDT on a Vulkan device (ExactTransformOptions::device, shaders/edt_lines.comp):
// the device's distances against exactDistanceTransform() on the CPU, bit for bit, on random
// masks of several shapes and densities, anisotropic spacing, a single feature and none; slabs
// and batches of lines (tiny budgets) against one slab; interruption; hidden devices and Auto;
// volume-to-sdf --device on the command line. Runs on any Vulkan device with 64-bit floats (in
// CI: Mesa's lavapipe, with the Khronos validation layer on and no message allowed); skips with a
// message where there is none.
#include <levelforge/gpu/VulkanDevices.h>
#include <levelforge/volume/ExactDistanceTransform.h>
#include <levelforge/volume/VolumeToLevelSet.h>

#include "TestUtil.h"
#include "tools/CliRunner.h"

#include <gtest/gtest.h>

#include <openvdb/openvdb.h>
#include <openvdb/util/NullInterrupter.h>

#include "gpu/VulkanTestSupport.h"

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <random>
#include <sstream>
#include <string>
#include <vector>

using namespace levelforge;

namespace {

class VulkanEdtTest : public levelforge_test::VulkanFixture
{
};

/// Features with probability `density` (at least one unless `density` is 0).
MaskVolume randomMask(int nx, int ny, int nz, double density, uint32_t seed,
                      const openvdb::Vec3d& spacing = openvdb::Vec3d(1.0))
{
    MaskVolume m(openvdb::Coord(nx, ny, nz), uint8_t(0), spacing);
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    for (uint8_t& v : m.data) v = u(rng) < density ? uint8_t(1 + rng() % 255) : uint8_t(0);
    if (density > 0.0) m.data[rng() % m.data.size()] = 1;
    return m;
}

std::string shape(const MaskVolume& m)
{
    std::ostringstream os;
    os << m.dims.x() << " x " << m.dims.y() << " x " << m.dims.z() << " spacing " << m.spacing;
    return os.str();
}

/// Voxels whose bits differ.
uint64_t differing(const ScalarVolume& a, const ScalarVolume& b)
{
    if (a.dims != b.dims || a.data.size() != b.data.size()) return ~uint64_t(0);
    uint64_t bad = 0;
    for (size_t i = 0; i < a.data.size(); ++i)
        if (std::memcmp(&a.data[i], &b.data[i], sizeof(float)) != 0) ++bad;
    return bad;
}

ScalarVolume onDevice(const MaskVolume& m, ComputeDevice d, uint64_t budget = 0, ExactTransformStats* stats = nullptr)
{
    ExactTransformOptions o;
    o.device = d;
    o.deviceMemoryBudget = budget;
    return exactDistanceTransform(m, o, stats);
}

/// The CPU's distances and the Vulkan device's, bit for bit.
void expectIdentical(const MaskVolume& m, uint64_t budget = 0)
{
    const ScalarVolume cpu = exactDistanceTransform(m);
    ExactTransformStats s;
    const ScalarVolume gpu = onDevice(m, ComputeDevice::Vulkan, budget, &s);
    EXPECT_EQ(s.device.rfind("vulkan: ", 0), 0u) << s.device;
    EXPECT_EQ(differing(cpu, gpu), 0u) << shape(m) << " budget " << budget;
    EXPECT_EQ(gpu.spacing, m.spacing);
    EXPECT_EQ(gpu.origin, m.origin);
}

struct StopAfter : openvdb::util::NullInterrupter
{
    int calls = 0, limit, starts = 0, ends = 0;
    explicit StopAfter(int n) : limit(n) {}
    void start(const char* = nullptr) override { ++starts; }
    void end() override { ++ends; }
    bool wasInterrupted(int = -1) override { return ++calls > limit; }
};

} // namespace

TEST_F(VulkanEdtTest, RandomMasksOfSeveralShapesAreBitIdenticalToTheCpu)
{
    struct Size { int x, y, z; };
    const Size sizes[] = {{1, 1, 1}, {1, 1, 57}, {61, 1, 1}, {1, 43, 1}, {17, 23, 19}, {33, 8, 1},
                          {1, 9, 31}, {32, 32, 32}, {5, 64, 3}, {71, 45, 38}};
    uint32_t seed = 1;
    for (const Size& s : sizes)
        for (const double density : {0.002, 0.05, 0.6}) expectIdentical(randomMask(s.x, s.y, s.z, density, seed++));
}

TEST_F(VulkanEdtTest, AnisotropicSpacingIsBitIdenticalToTheCpu)
{
    uint32_t seed = 100;
    for (const openvdb::Vec3d& sp : {openvdb::Vec3d(0.7, 1.3, 2.1), openvdb::Vec3d(1e-3, 1.0, 5.0),
                                     openvdb::Vec3d(3.0, 0.25, 0.1), openvdb::Vec3d(0.1)}) {
        for (const double density : {0.01, 0.2}) {
            expectIdentical(randomMask(29, 37, 21, density, seed++, sp));
            expectIdentical(randomMask(1, 1, 40, density, seed++, sp));
        }
    }
}

TEST_F(VulkanEdtTest, InexactDeviceDivisionAndSqrtAreCorrected)
{
    // the kernel's divisions and square roots start 2 ulps or 2^-30 off (as a device with
    // Vulkan's minimal double precision might give them): the distances stay the CPU's
    setenv("LEVELFORGE_VULKAN_EDT_PERTURB", "1", 1);
    uint32_t seed = 300;
    for (const openvdb::Vec3d& sp : {openvdb::Vec3d(1.0), openvdb::Vec3d(0.7, 1.3, 2.1), openvdb::Vec3d(0.1, 3.0, 0.01)})
        for (const double density : {0.003, 0.1, 0.5}) expectIdentical(randomMask(27, 31, 25, density, seed++, sp));
    unsetenv("LEVELFORGE_VULKAN_EDT_PERTURB");
}

TEST_F(VulkanEdtTest, ASingleFeatureAndNoFeature)
{
    for (const openvdb::Vec3d& sp : {openvdb::Vec3d(1.0), openvdb::Vec3d(0.3, 1.7, 0.9)}) {
        MaskVolume one(openvdb::Coord(23, 17, 29), uint8_t(0), sp);
        one(4, 11, 20) = 1;
        expectIdentical(one);
        const ScalarVolume d = onDevice(one, ComputeDevice::Vulkan);
        EXPECT_EQ(d(4, 11, 20), 0.0f);
        EXPECT_TRUE(std::isfinite(d(22, 0, 0)));
        MaskVolume corner(openvdb::Coord(40, 1, 1), uint8_t(0), sp);
        corner(39, 0, 0) = 1;
        expectIdentical(corner);
    }
    const MaskVolume none(openvdb::Coord(19, 13, 11), uint8_t(0));
    expectIdentical(none);
    const ScalarVolume d = onDevice(none, ComputeDevice::Vulkan, 1);
    for (float v : d.data) ASSERT_TRUE(std::isinf(v) && v > 0.0f) << v;
}

TEST_F(VulkanEdtTest, TinyBudgetsMeanManySlabsAndTheSameDistances)
{
    const MaskVolume m = randomMask(40, 36, 44, 0.01, 7, openvdb::Vec3d(0.9, 1.1, 1.3));
    ExactTransformStats whole, some, tiny;
    const ScalarVolume ref = onDevice(m, ComputeDevice::Vulkan, 0, &whole);
    EXPECT_EQ(whole.slabs, 2u); // one slab of z-slices, one of y-rows: resident on the device
    EXPECT_EQ(whole.dispatches, 3u);
    EXPECT_EQ(whole.bytesUp, m.voxelCount());
    EXPECT_EQ(whole.bytesDown, 4 * m.voxelCount());
    EXPECT_GT(whole.peakDeviceBytes, 5 * m.voxelCount());
    const ScalarVolume mid = onDevice(m, ComputeDevice::Vulkan, 96 << 10, &some); // a few slices and rows
    EXPECT_GT(some.slabs, 4u);
    EXPECT_GT(some.dispatches, some.slabs);
    EXPECT_LE(some.peakDeviceBytes, uint64_t(96 << 10));
    const ScalarVolume one = onDevice(m, ComputeDevice::Vulkan, 1, &tiny); // one slice, row, line at a time
    EXPECT_EQ(tiny.slabs, uint64_t(m.dims.z() + m.dims.y()));
    EXPECT_EQ(tiny.dispatches, uint64_t(m.dims.y() * m.dims.z() + m.dims.x() * m.dims.z() + m.dims.x() * m.dims.y()));
    EXPECT_EQ(differing(ref, mid), 0u);
    EXPECT_EQ(differing(ref, one), 0u);
    EXPECT_EQ(differing(ref, exactDistanceTransform(m)), 0u);
}

TEST_F(VulkanEdtTest, ALargerVolumeInSlabsMatchesTheCpu)
{
    // a sphere shell and scattered points, 1 MiB of device memory for a 4.7 MB volume
    MaskVolume m = randomMask(112, 96, 88, 0.0005, 11);
    for (int k = 0; k < 88; ++k)
        for (int j = 0; j < 96; ++j)
            for (int i = 0; i < 112; ++i) {
                const double r = std::sqrt((i - 50.3) * (i - 50.3) + (j - 47.1) * (j - 47.1) + (k - 40.7) * (k - 40.7));
                if (std::abs(r - 30.0) < 0.6) m(i, j, k) = 1;
            }
    ExactTransformStats s;
    const ScalarVolume gpu = onDevice(m, ComputeDevice::Vulkan, 1 << 20, &s);
    EXPECT_GT(s.slabs, 4u);
    EXPECT_LE(s.peakDeviceBytes, uint64_t(1) << 20);
    EXPECT_EQ(differing(exactDistanceTransform(m), gpu), 0u);
    // 512-sample lines along each axis, a 1 MiB budget: slabs of slices or rows
    for (const openvdb::Coord& d : {openvdb::Coord(512, 384, 3), openvdb::Coord(3, 512, 5), openvdb::Coord(4, 3, 512)}) {
        const MaskVolume thin = randomMask(d.x(), d.y(), d.z(), 0.001, uint32_t(d.x() + d.y() + d.z()));
        expectIdentical(thin, 1 << 20);
    }
}

TEST_F(VulkanEdtTest, InterruptionStopsBetweenAndDuringDispatches)
{
    const MaskVolume m = randomMask(40, 36, 44, 0.01, 3);
    ExactTransformOptions o;
    o.device = ComputeDevice::Vulkan;
    o.deviceMemoryBudget = 16 << 10;
    // never interrupted: the same distances; count the polls
    StopAfter never(1 << 30);
    o.interrupter = &never;
    EXPECT_EQ(differing(exactDistanceTransform(m, o), exactDistanceTransform(m)), 0u);
    EXPECT_EQ(never.starts, 1);
    EXPECT_EQ(never.ends, 1);
    ASSERT_GT(never.calls, 8);
    for (const int after : {0, 2, never.calls / 2, never.calls - 1}) {
        StopAfter stop(after);
        o.interrupter = &stop;
        EXPECT_THROW(exactDistanceTransform(m, o), InterruptedError) << "after " << after << " of " << never.calls;
        EXPECT_EQ(stop.starts, 1);
        EXPECT_EQ(stop.ends, 1);
    }
}

TEST_F(VulkanEdtTest, HiddenDevicesFailVulkanAndLeaveAutoOnTheCpu)
{
    setenv("LEVELFORGE_VULKAN_DEVICE", "none", 1);
    const MaskVolume m = randomMask(21, 22, 23, 0.02, 5);
    try {
        onDevice(m, ComputeDevice::Vulkan);
        ADD_FAILURE() << "no DeviceError";
    } catch (const DeviceError& e) {
        EXPECT_NE(std::string(e.what()).find("LEVELFORGE_VULKAN_DEVICE=none"), std::string::npos) << e.what();
    }
    ExactTransformOptions o;
    o.device = ComputeDevice::Auto;
    o.deviceMinVoxels = 0;
    ExactTransformStats s;
    const ScalarVolume d = exactDistanceTransform(m, o, &s);
    EXPECT_EQ(s.device, "cpu");
    EXPECT_NE(s.deviceNote.find("hidden"), std::string::npos) << s.deviceNote;
    EXPECT_EQ(differing(d, exactDistanceTransform(m)), 0u);
    unsetenv("LEVELFORGE_VULKAN_DEVICE");
}

TEST_F(VulkanEdtTest, OutOfDeviceMemoryAndDeviceLostFailVulkanAndFallBackUnderAuto)
{
    const MaskVolume m = randomMask(33, 21, 26, 0.02, 21);
    const ScalarVolume cpu = exactDistanceTransform(m);
    setenv("LEVELFORGE_VULKAN_DEVICE", "0", 1); // picked by index: auto uses it, whatever its type
    for (const char* fault : {"oom", "lost"}) {
        setenv("LEVELFORGE_VULKAN_INJECT", fault, 1);
        try {
            onDevice(m, ComputeDevice::Vulkan, 64 << 10);
            ADD_FAILURE() << fault << ": no DeviceError";
        } catch (const DeviceError& e) {
            const std::string msg = e.what();
            EXPECT_NE(msg.find(std::string(fault) == "oom" ? "out of device memory" : "device lost"), std::string::npos) << msg;
        }
        ExactTransformOptions o;
        o.device = ComputeDevice::Auto;
        o.deviceMinVoxels = 0;
        o.deviceMemoryBudget = 64 << 10;
        ExactTransformStats s;
        EXPECT_EQ(differing(exactDistanceTransform(m, o, &s), cpu), 0u) << fault;
        EXPECT_EQ(s.device, "cpu") << fault;
        EXPECT_NE(s.deviceNote.find("the CPU was used"), std::string::npos) << s.deviceNote;
    }
    unsetenv("LEVELFORGE_VULKAN_INJECT");
    // the device works again afterwards (a lost device is opened afresh); auto takes the picked device
    ExactTransformOptions o;
    o.device = ComputeDevice::Auto;
    o.deviceMinVoxels = 0;
    ExactTransformStats s;
    EXPECT_EQ(differing(exactDistanceTransform(m, o, &s), cpu), 0u);
    EXPECT_EQ(s.device.rfind("vulkan: ", 0), 0u) << s.device;
    unsetenv("LEVELFORGE_VULKAN_DEVICE");
}

TEST_F(VulkanEdtTest, AutoUsesOnlyADiscreteGpuAndLargeVolumes)
{
    const VulkanDeviceList list = listVulkanDevices();
    bool discrete = false;
    for (const VulkanDeviceInfo& d : list.devices) discrete = discrete || (d.chosen && d.type == "discrete");
    const MaskVolume m = randomMask(30, 20, 10, 0.02, 9);
    ExactTransformOptions o;
    o.device = ComputeDevice::Auto;
    o.deviceMinVoxels = 0;
    ExactTransformStats s;
    const ScalarVolume d = exactDistanceTransform(m, o, &s);
    if (discrete) {
        EXPECT_EQ(s.device.rfind("vulkan: ", 0), 0u) << s.device;
    } else {
        EXPECT_EQ(s.device, "cpu");
        EXPECT_TRUE(s.deviceNote.find("not a discrete GPU") != std::string::npos ||
                    s.deviceNote.find("no GPU on this machine") != std::string::npos)
            << s.deviceNote;
    }
    EXPECT_EQ(differing(d, exactDistanceTransform(m)), 0u);
    o.deviceMinVoxels = m.voxelCount() + 1; // small work never asks for a device
    ExactTransformStats small;
    exactDistanceTransform(m, o, &small);
    EXPECT_EQ(small.device, "cpu");
    EXPECT_TRUE(small.deviceNote.empty()) << small.deviceNote;
}

TEST_F(VulkanEdtTest, VolumeToLevelSetOnTheDeviceIsTheCpuGrid)
{
    const ScalarVolume field = makeSphereField(openvdb::Coord(48, 40, 44), openvdb::Vec3d(23.3, 19.6, 21.45), 15.5);
    VolumeToLevelSetOptions o;
    o.method = VolumeDistanceMethod::Exact;
    o.subvoxel = false;
    const ScalarVolume cpu = volumeSignedDistance(field, o);
    o.device = ComputeDevice::Vulkan;
    o.deviceMemoryBudget = 128 << 10;
    VolumeToLevelSetStats s;
    const ScalarVolume gpu = volumeSignedDistance(field, o, &s);
    EXPECT_EQ(s.device.rfind("vulkan: ", 0), 0u) << s.device;
    EXPECT_TRUE(s.deviceNote.empty()) << s.deviceNote;
    EXPECT_EQ(differing(cpu, gpu), 0u);
    // a method without a device path says so and runs on the CPU
    o.method = VolumeDistanceMethod::VCVDT8;
    VolumeToLevelSetStats v;
    volumeSignedDistance(field, o, &v);
    EXPECT_EQ(v.device, "cpu");
    EXPECT_NE(v.deviceNote.find("only the exact transform"), std::string::npos) << v.deviceNote;
}

#ifdef LEVELFORGE_CLI_PATH
TEST_F(VulkanEdtTest, CliVolumeToSdfDeviceVulkanWritesTheCpuGridAndFailsCleanlyWithoutADevice)
{
    namespace fs = std::filesystem;
    const fs::path dir = levelforge_test::scratchDir("cli_vulkan_edt");
    const std::string cpu = (dir / "cpu.vdb").string(), gpu = (dir / "gpu.vdb").string(),
                      none = (dir / "none.vdb").string(), vc = (dir / "vc.vdb").string();
    auto run = [&](const std::string& out, const std::string& device, const std::string& method = "exact") {
        const std::vector<std::string> a = {"volume-to-sdf", "builtin:sphere", out, "--method", method, "--iso", "0",
                                            "--exterior-band", "6", "--quiet", "--device", device};
        return levelforge_test::runLevelforge(dir, a);
    };
    auto r = run(cpu, "cpu");
    ASSERT_EQ(r.code, 0) << r.err;
    EXPECT_EQ(r.out.find("  device:"), std::string::npos) << r.out;
    r = run(gpu, "vulkan");
    ASSERT_EQ(r.code, 0) << r.err;
    EXPECT_NE(r.out.find("  device: vulkan: "), std::string::npos) << r.out;
    EXPECT_EQ(r.err.find("warning"), std::string::npos) << r.err;
    const auto a = levelforge_test::readSingleFloatGrid(cpu), b = levelforge_test::readSingleFloatGrid(gpu);
    ASSERT_TRUE(a && b);
    ASSERT_EQ(a->activeVoxelCount(), b->activeVoxelCount());
    uint64_t bad = 0;
    auto acc = b->getConstAccessor();
    for (auto it = a->cbeginValueAll(); it; ++it) {
        float v;
        const bool on = acc.probeValue(it.getCoord(), v);
        if (it.isVoxelValue() && (on != it.isValueOn() || std::memcmp(&v, &*it, sizeof(float)) != 0)) ++bad;
    }
    EXPECT_EQ(bad, 0u);
    // a method without a device path: a warning, the CPU's grid
    r = run(vc, "vulkan", "vcvdt8");
    EXPECT_EQ(r.code, 0) << r.err;
    EXPECT_EQ(levelforge_test::countLines(r.err, "levelforge: warning:"), 1) << r.err;
    setenv("LEVELFORGE_VULKAN_DEVICE", "none", 1);
    r = run(none, "vulkan");
    EXPECT_NE(r.code, 0);
    EXPECT_EQ(levelforge_test::countLines(r.err, "levelforge: error:"), 1) << r.err;
    EXPECT_NE(r.err.find("hidden"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(none));
    r = run(none, "auto"); // a small volume: the CPU, no warning
    EXPECT_EQ(r.code, 0) << r.err;
    EXPECT_EQ(r.err.find("warning"), std::string::npos) << r.err;
    EXPECT_TRUE(fs::exists(none));
    unsetenv("LEVELFORGE_VULKAN_DEVICE");
}
#endif
