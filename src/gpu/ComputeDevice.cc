// SPDX-License-Identifier: Apache-2.0
// ComputeDevice names, and what stands in for the Vulkan backend when it is not built.
#include <levelforge/gpu/VulkanDevices.h>

#include "gpu/VulkanExactDistanceTransform.h"
#include "gpu/VulkanLeafDistance.h"

#include <cstdlib>
#include <filesystem>
#include <mutex>

namespace levelforge {

const char* toString(ComputeDevice d)
{
    switch (d) {
    case ComputeDevice::Cpu: return "cpu";
    case ComputeDevice::Vulkan: return "vulkan";
    case ComputeDevice::Auto: return "auto";
    }
    return "cpu";
}

ComputeDevice parseComputeDevice(const std::string& text)
{
    if (text == "cpu") return ComputeDevice::Cpu;
    if (text == "vulkan") return ComputeDevice::Vulkan;
    if (text == "auto") return ComputeDevice::Auto;
    throw InvalidArgumentError("unknown device '" + text + "' (expected cpu, vulkan or auto)");
}

namespace {
/// Whether this machine shows the kernel device node of a GPU. A hardware GPU's Vulkan driver
/// opens one: /dev/dri/renderD* (Mesa's and AMD's drivers), /dev/nvidia0 or /dev/nvidiactl
/// (NVIDIA's), /dev/dxg (WSL2). Without any, the only Vulkan devices can be software ones
/// (lavapipe), so Auto knows there is no discrete GPU without loading the drivers (about 0.1 s:
/// lavapipe loads LLVM). Always true off Linux.
bool hasGpuDeviceNode()
{
#ifdef __linux__
    std::error_code ec;
    for (const char* node : {"/dev/nvidiactl", "/dev/nvidia0", "/dev/dxg"})
        if (std::filesystem::exists(node, ec)) return true;
    for (std::filesystem::directory_iterator it("/dev/dri", ec), end; !ec && it != end; it.increment(ec))
        if (it->path().filename().string().rfind("renderD", 0) == 0) return true;
    return false;
#else
    return true;
#endif
}
} // namespace

bool autoUsesVulkan(std::string& why)
{
    const char* env = std::getenv("LEVELFORGE_VULKAN_DEVICE");
    if (env && std::string(env) == "none") {
        why = "every Vulkan device is hidden (LEVELFORGE_VULKAN_DEVICE=none)";
        return false;
    }
    if (env && *env) return true; // a device picked by name or index: auto uses it, whatever its type
    static std::once_flag once;
    static bool discrete = false;
    static std::string reason;
    std::call_once(once, [] {
        if (!hasGpuDeviceNode()) {
            reason = "no GPU on this machine (no /dev/dri/renderD*, /dev/nvidia* or /dev/dxg device node), so no "
                     "discrete GPU; the Vulkan devices were not probed";
            return;
        }
        const VulkanDeviceList list = listVulkanDevices();
        for (const VulkanDeviceInfo& d : list.devices)
            if (d.chosen && d.type == "discrete") discrete = true;
        if (!discrete) {
            reason = list.problem.empty() ? "no discrete Vulkan GPU" : list.problem;
            for (const VulkanDeviceInfo& d : list.devices)
                if (d.chosen) reason = "the only usable Vulkan device, " + d.name + ", is not a discrete GPU";
        }
    });
    if (!discrete) why = reason;
    return discrete;
}

#ifndef LEVELFORGE_HAVE_VULKAN
VulkanDeviceList listVulkanDevices()
{
    VulkanDeviceList out;
    out.problem = "this levelforge was built without the Vulkan backend (needs libvulkan-dev and glslc)";
    return out;
}

uint64_t vulkanValidationMessages() { return 0; }

namespace gpu_internal {
struct LeafDistanceDevice::Impl {};
LeafDistanceDevice::LeafDistanceDevice(const LeafDeviceInput&)
{
    throw DeviceError("Vulkan: this levelforge was built without the Vulkan backend (needs libvulkan-dev and glslc)");
}
LeafDistanceDevice::~LeafDistanceDevice() = default;
std::string LeafDistanceDevice::deviceName() const { return {}; }
uint64_t LeafDistanceDevice::slotBudget(uint64_t) const { return 0; }
void LeafDistanceDevice::start(int, const LeafBatch&, double) {}
bool LeafDistanceDevice::finish(int, const std::function<bool()>&) { return false; }
const uint32_t* LeafDistanceDevice::triangles(int) const { return nullptr; }
const double* LeafDistanceDevice::distances(int) const { return nullptr; }
uint64_t edtDeviceBudget(uint64_t)
{
    throw DeviceError("Vulkan: this levelforge was built without the Vulkan backend (needs libvulkan-dev and glslc)");
}
ScalarVolume deviceExactDistanceTransform(const MaskVolume&, uint64_t, openvdb::util::NullInterrupter*,
                                          ExactTransformStats&)
{
    throw DeviceError("Vulkan: this levelforge was built without the Vulkan backend (needs libvulkan-dev and glslc)");
}
} // namespace gpu_internal
#endif

} // namespace levelforge
