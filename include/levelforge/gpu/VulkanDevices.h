// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Compute devices: the CPU, or a Vulkan device (the GPU backend of the dense work).
///
/// levelforge's dense work (the main road's band leaves today; MeshToLevelSet.h) can run on a
/// Vulkan compute device. The library loads the Vulkan loader (libvulkan.so.1) at run time, so
/// it starts and works on machines without one. Kernels are SPIR-V compiled at build time
/// (glslc) and embedded in the library; no shader compiler is needed at run time.
///
/// Selection (ComputeDevice): `Cpu` never touches Vulkan; `Vulkan` uses the chosen device or
/// throws DeviceError; `Auto` uses a discrete GPU with 64-bit floats when one is present and the
/// work is large enough, else the CPU (with a note in the statistics saying why).
///
/// Environment:
///   * LEVELFORGE_VULKAN_DEVICE: `none` hides every device (simulates a machine without one);
///     a number picks the device of that index in listVulkanDevices(); any other text picks the
///     first device whose name contains it. A device picked this way is used by `Auto` too,
///     whatever its type.
///   * LEVELFORGE_VULKAN_INJECT=oom|lost (a test aid): device allocations fail as out of device
///     memory, or every completed submission reports the device lost.
///   * LEVELFORGE_VULKAN_VALIDATION=1: enables the Khronos validation layer (tests do); every
///     message it prints is counted (vulkanValidationMessages()) and echoed on stderr.
#pragma once

#include <levelforge/core/Exceptions.h>

#include <cstdint>
#include <string>
#include <vector>

namespace levelforge {

/// @brief Where dense work runs.
enum class ComputeDevice
{
    Cpu,    ///< the CPU (TBB), always available
    Vulkan, ///< a Vulkan device; an error when there is none
    Auto,   ///< a discrete Vulkan GPU when present and the work is large enough, else the CPU
};

/// @brief "cpu", "vulkan" or "auto".
/// @param[in] d  the device
/// @return its name as the CLI spells it
const char* toString(ComputeDevice d);

/// @brief Parses "cpu", "vulkan" or "auto" (case-sensitive).
/// @param[in] text  the name
/// @return the device
/// @throws InvalidArgumentError for any other text
ComputeDevice parseComputeDevice(const std::string& text);

/// @brief A Vulkan device could not be used: no loader, no device, no 64-bit floats, out of
///        device memory, device lost. The message says which, and on which device.
class DeviceError : public Error
{
public:
    /// @brief Constructs the exception.
    /// @param[in] msg  the message: what failed, on which device
    explicit DeviceError(const std::string& msg) : Error(msg) {}
};

/// @brief One Vulkan physical device, as listVulkanDevices() reports it.
struct VulkanDeviceInfo
{
    uint32_t index = 0;              ///< position in the loader's enumeration
    std::string name;                ///< e.g. "NVIDIA H200", "llvmpipe (LLVM 15.0.6, 256 bits)"
    std::string type;                ///< "discrete", "integrated", "virtual", "cpu" or "other"
    std::string apiVersion;          ///< e.g. "1.3.239"
    uint64_t deviceLocalBytes = 0;   ///< size of the largest device-local memory heap
    bool float64 = false;            ///< shaderFloat64: kernels can compute in double
    bool usable = false;             ///< has a compute queue and 64-bit floats
    bool chosen = false;             ///< the device ComputeDevice::Vulkan would use
};

/// @brief What the Vulkan loader sees.
struct VulkanDeviceList
{
    bool compiledIn = false;                ///< this build has the Vulkan backend
    bool loaderFound = false;               ///< libvulkan.so.1 was loaded and an instance created
    std::string problem;                    ///< why there is no usable device (empty when there is)
    std::vector<VulkanDeviceInfo> devices;  ///< every device (hidden ones left out)
};

/// @brief Lists the Vulkan devices, marking the one that would be chosen.
///
/// Chosen: the usable device selected by LEVELFORGE_VULKAN_DEVICE if set, else the first usable
/// discrete GPU with the most device memory, else the first usable integrated, virtual or CPU
/// device. Never throws: a missing loader or device is reported in `problem`.
/// @return the devices and, when none is usable, why
VulkanDeviceList listVulkanDevices();

/// @brief Whether ComputeDevice::Auto may use the Vulkan device for large work: a device picked
///        by LEVELFORGE_VULKAN_DEVICE (not `none`), else the chosen device when it is a discrete
///        GPU. The device list is read once per process (the environment each time). On a Linux
///        machine without a GPU's device node (/dev/dri/renderD*, /dev/nvidia*, /dev/dxg) the
///        answer is no without loading the Vulkan drivers (lavapipe's load costs about 0.1 s).
/// @param[out] why  when not: the sentence a fallback note gives (e.g. "no discrete Vulkan GPU")
/// @return true when Auto should use the device
bool autoUsesVulkan(std::string& why);

/// @brief Validation-layer messages seen so far in this process (LEVELFORGE_VULKAN_VALIDATION=1).
/// @return the count of warnings and errors reported by the layer
uint64_t vulkanValidationMessages();

} // namespace levelforge
