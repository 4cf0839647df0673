// SPDX-License-Identifier: Apache-2.0
// Shared by the Vulkan tests: the fixture (validation layer on, skip without a usable device, no
// validation message allowed) and the bit-for-bit grid comparison.
#pragma once

#include <levelforge/gpu/VulkanDevices.h>

#include <gtest/gtest.h>

#include <openvdb/openvdb.h>

#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <string>

namespace levelforge_test {

class VulkanFixture : public ::testing::Test
{
protected:
    void SetUp() override
    {
        openvdb::initialize();
        // every test is its own process (gtest_discover_tests): validation on before first use
        if (std::filesystem::exists("/usr/share/vulkan/explicit_layer.d/VkLayer_khronos_validation.json"))
            setenv("LEVELFORGE_VULKAN_VALIDATION", "1", 1);
        unsetenv("LEVELFORGE_VULKAN_DEVICE");
        const levelforge::VulkanDeviceList list = levelforge::listVulkanDevices();
        bool usable = false;
        for (const levelforge::VulkanDeviceInfo& d : list.devices) usable = usable || d.chosen;
        if (!usable) GTEST_SKIP() << "no usable Vulkan device (" << list.problem << "); install mesa-vulkan-drivers";
        mValidationBefore = levelforge::vulkanValidationMessages();
    }
    void TearDown() override
    {
        if (!IsSkipped())
            EXPECT_EQ(levelforge::vulkanValidationMessages(), mValidationBefore) << "the Vulkan validation layer reported problems";
    }
    uint64_t mValidationBefore = 0;
};

/// Every voxel of a's leaves equals b's, value and state, bit for bit (same active count and
/// leaf count), and a's tiles hold b's values.
inline void expectIdenticalGrids(const openvdb::FloatGrid& a, const openvdb::FloatGrid& b, const std::string& what)
{
    ASSERT_EQ(a.activeVoxelCount(), b.activeVoxelCount()) << what;
    ASSERT_EQ(a.tree().leafCount(), b.tree().leafCount()) << what;
    uint64_t bad = 0;
    auto acc = b.getConstAccessor();
    for (auto it = a.tree().cbeginLeaf(); it; ++it)
        for (auto v = it->cbeginValueAll(); v; ++v) {
            float value;
            const bool on = acc.probeValue(v.getCoord(), value);
            if (on != v.isValueOn() || std::memcmp(&value, &*v, sizeof(float)) != 0) ++bad;
        }
    EXPECT_EQ(bad, 0u) << what << ": voxels that differ";
    uint64_t tileBad = 0;
    for (auto it = a.cbeginValueOff(); it; ++it)
        if (!it.isVoxelValue() && b.tree().getValue(it.getCoord()) != *it) ++tileBad;
    EXPECT_EQ(tileBad, 0u) << what << ": tiles that differ";
}

} // namespace levelforge_test
