// SPDX-License-Identifier: Apache-2.0
// levelforge operator `devices`: the compute devices (the CPU and every Vulkan device).
#include "Operator.h"
#include "OperatorText.h"

#include <levelforge/gpu/VulkanDevices.h>

#include <tbb/info.h>

#include <ostream>

namespace levelforge::ops {
namespace {

void cookDevices(OperatorArgs& args)
{
    std::ostream& os = args.out();
    os << "cpu: " << tbb::info::default_concurrency() << " threads (TBB)\n";
    const VulkanDeviceList list = listVulkanDevices();
    if (!list.compiledIn || !list.loaderFound) {
        os << "vulkan: none (" << list.problem << ")\n";
    } else if (list.devices.empty()) {
        os << "vulkan: no device (" << list.problem << ")\n";
    }
    for (const VulkanDeviceInfo& d : list.devices) {
        os << "vulkan " << d.index << ": " << d.name << "\n"
           << "  type:           " << d.type << "\n"
           << "  api version:    " << d.apiVersion << "\n"
           << "  device memory:  " << fmt("%.2f", double(d.deviceLocalBytes) / double(uint64_t(1) << 30)) << " GiB\n"
           << "  float64:        " << (d.float64 ? "yes" : "no (levelforge's kernels need it)") << "\n"
           << "  chosen:         "
           << (d.chosen ? (d.type == "discrete" ? "yes (--device vulkan and auto)" : "yes (--device vulkan; auto stays on the CPU)")
                        : "no")
           << "\n";
    }
    if (list.loaderFound && !list.devices.empty() && !list.problem.empty()) os << "vulkan: " << list.problem << "\n";
}

} // namespace

LEVELFORGE_REGISTER_OPERATOR(
    OperatorSpec("devices", "List the compute devices: the CPU and the Vulkan devices (--device)")
        .description("For every Vulkan device: name, type (discrete, integrated, virtual, cpu), API\n"
                     "version, device memory, 64-bit float support, and whether --device vulkan\n"
                     "(and auto) would choose it. LEVELFORGE_VULKAN_DEVICE=<index|name|none> picks\n"
                     "a device or hides them all.")
        .example("levelforge devices")
        .example("LEVELFORGE_VULKAN_DEVICE=none levelforge devices")
        .cook(cookDevices));

} // namespace levelforge::ops
