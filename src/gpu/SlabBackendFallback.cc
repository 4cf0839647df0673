// SPDX-License-Identifier: Apache-2.0
// VulkanSlabBackend in a build without the Vulkan backend: construction fails with DeviceError.
#include <levelforge/gpu/VulkanSlabBackend.h>

#ifndef LEVELFORGE_HAVE_VULKAN
namespace levelforge {
struct VulkanSlabBackend::Impl {};
VulkanSlabBackend::VulkanSlabBackend(uint64_t)
{
    throw DeviceError("Vulkan: this levelforge was built without the Vulkan backend (needs libvulkan-dev and glslc)");
}
VulkanSlabBackend::~VulkanSlabBackend() = default;
void VulkanSlabBackend::fill(DenseSlab&, const CrossSection*, size_t, const SlabTriangles&) const {}
void VulkanSlabBackend::fillBatch(const SlabJob*, size_t, const SlabTriangles&) const {}
std::string VulkanSlabBackend::deviceName() const { return {}; }
VulkanSlabStats VulkanSlabBackend::stats() const { return {}; }
} // namespace levelforge
#endif
