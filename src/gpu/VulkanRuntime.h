// SPDX-License-Identifier: Apache-2.0
// Private: the Vulkan compute runtime (instance and device, buffers with staging, compute
// kernels from embedded SPIR-V, submissions with fences). See VulkanDevices.h for the public
// side. The loader is opened with dlopen, so nothing here needs libvulkan at link time.
#pragma once

#include <levelforge/gpu/VulkanDevices.h>

#ifndef VK_NO_PROTOTYPES
#define VK_NO_PROTOTYPES
#endif
#include <vulkan/vulkan.h>

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

namespace levelforge::gpu_internal {

#define LF_VK_INSTANCE_FUNCTIONS(X)                                                                          \
    X(vkDestroyInstance) X(vkEnumeratePhysicalDevices) X(vkGetPhysicalDeviceProperties)                      \
    X(vkGetPhysicalDeviceFeatures) X(vkGetPhysicalDeviceMemoryProperties)                                    \
    X(vkGetPhysicalDeviceQueueFamilyProperties) X(vkCreateDevice) X(vkGetDeviceProcAddr)

#define LF_VK_DEVICE_FUNCTIONS(X)                                                                            \
    X(vkDestroyDevice) X(vkGetDeviceQueue) X(vkCreateBuffer) X(vkDestroyBuffer)                              \
    X(vkGetBufferMemoryRequirements) X(vkAllocateMemory) X(vkFreeMemory) X(vkBindBufferMemory)               \
    X(vkMapMemory) X(vkUnmapMemory) X(vkInvalidateMappedMemoryRanges) X(vkCreateShaderModule)                \
    X(vkDestroyShaderModule) X(vkCreateDescriptorSetLayout) X(vkDestroyDescriptorSetLayout)                 \
    X(vkCreatePipelineLayout) X(vkDestroyPipelineLayout) X(vkCreateComputePipelines) X(vkDestroyPipeline)  \
    X(vkCreateDescriptorPool) X(vkDestroyDescriptorPool) X(vkAllocateDescriptorSets)                        \
    X(vkUpdateDescriptorSets) X(vkResetDescriptorPool) X(vkCreateCommandPool) X(vkDestroyCommandPool)      \
    X(vkAllocateCommandBuffers) X(vkResetCommandBuffer) X(vkBeginCommandBuffer) X(vkEndCommandBuffer)      \
    X(vkCmdBindPipeline) X(vkCmdBindDescriptorSets) X(vkCmdPushConstants) X(vkCmdDispatch)                 \
    X(vkCmdCopyBuffer) X(vkCmdPipelineBarrier) X(vkCmdFillBuffer) X(vkQueueSubmit) X(vkCreateFence)        \
    X(vkDestroyFence) X(vkWaitForFences) X(vkResetFences) X(vkDeviceWaitIdle)

/// The entry points levelforge uses, loaded from libvulkan.so.1.
struct Api
{
    PFN_vkGetInstanceProcAddr vkGetInstanceProcAddr = nullptr;
    PFN_vkCreateInstance vkCreateInstance = nullptr;
    PFN_vkEnumerateInstanceLayerProperties vkEnumerateInstanceLayerProperties = nullptr;
    PFN_vkEnumerateInstanceExtensionProperties vkEnumerateInstanceExtensionProperties = nullptr;
    PFN_vkCreateDebugUtilsMessengerEXT vkCreateDebugUtilsMessengerEXT = nullptr;
    PFN_vkDestroyDebugUtilsMessengerEXT vkDestroyDebugUtilsMessengerEXT = nullptr;
#define LF_VK_DECLARE(name) PFN_##name name = nullptr;
    LF_VK_INSTANCE_FUNCTIONS(LF_VK_DECLARE)
    LF_VK_DEVICE_FUNCTIONS(LF_VK_DECLARE)
#undef LF_VK_DECLARE
};

/// Where a buffer lives: on the device (storage, copy source and target), or host-visible for
/// uploads (write-combined) or read-backs (cached).
enum class Memory { Device, Upload, Readback };

struct Buffer
{
    VkBuffer buffer = VK_NULL_HANDLE;
    VkDeviceMemory memory = VK_NULL_HANDLE;
    VkDeviceSize size = 0;
    void* mapped = nullptr; ///< host pointer when host-visible
    bool coherent = true;
};

class Context;

/// A compute pipeline: storage buffers at bindings 0..n-1 of set 0, push constants.
struct Kernel
{
    VkShaderModule module = VK_NULL_HANDLE;
    VkDescriptorSetLayout setLayout = VK_NULL_HANDLE;
    VkPipelineLayout layout = VK_NULL_HANDLE;
    VkPipeline pipeline = VK_NULL_HANDLE;
    uint32_t bindings = 0;
    uint32_t pushBytes = 0;
};

/// The Vulkan instance and the chosen device with one compute queue. One per process (shared),
/// made on first use; submissions are serialised by the queue mutex.
class Context
{
public:
    /// The process's context on the chosen device. Throws DeviceError when there is none.
    static std::shared_ptr<Context> get();
    ~Context();
    Context(const Context&) = delete;
    Context& operator=(const Context&) = delete;

    const Api& api() const { return mApi; }
    VkDevice device() const { return mDevice; }
    const VulkanDeviceInfo& info() const { return mInfo; }
    /// True when device-local memory is also host-visible (CPU and unified-memory devices):
    /// staging copies are then skipped.
    bool unifiedMemory() const { return mUnified; }

    /// Allocates a buffer of `bytes` (at least 4). Throws DeviceError (out of device memory, ...).
    Buffer create(VkDeviceSize bytes, Memory where, const char* what);
    void destroy(Buffer& b);
    /// Makes host writes visible to the device / device writes visible to the host, for
    /// non-coherent memory (a no-op otherwise).
    void invalidate(const Buffer& b);

    /// A kernel from SPIR-V words. Throws DeviceError.
    Kernel createKernel(const uint32_t* spirv, size_t bytes, uint32_t bindings, uint32_t pushBytes);
    void destroy(Kernel& k);

    /// The largest storage buffer a kernel can address (maxStorageBufferRange: 128 MiB on
    /// lavapipe).
    uint64_t maxBufferRange() const { return mLimits.maxStorageBufferRange; }
    /// Throws DeviceError when `bytes` do not fit one storage buffer of this device.
    void requireRange(uint64_t bytes, const char* what) const;
    /// Throws DeviceError naming the device and `what` when r is not VK_SUCCESS.
    void check(VkResult r, const char* what) const;

    VkQueue queue() const { return mQueue; }
    uint32_t queueFamily() const { return mFamily; }
    std::mutex& queueMutex() { return mQueueMutex; }
    const VkPhysicalDeviceLimits& limits() const { return mLimits; }

private:
    Context() = default;
    Api mApi;
    VkInstance mInstance = VK_NULL_HANDLE;
    VkDebugUtilsMessengerEXT mMessenger = VK_NULL_HANDLE;
    VkPhysicalDevice mPhysical = VK_NULL_HANDLE;
    VkDevice mDevice = VK_NULL_HANDLE;
    VkQueue mQueue = VK_NULL_HANDLE;
    uint32_t mFamily = 0;
    VkPhysicalDeviceMemoryProperties mMemory{};
    VkPhysicalDeviceLimits mLimits{};
    VulkanDeviceInfo mInfo;
    bool mUnified = false;
    mutable bool mLost = false; // set by check() on VK_ERROR_DEVICE_LOST: get() opens a new one
    std::mutex mQueueMutex;
    friend struct ContextFactory;
};

/// memcpy in 4 MiB pieces on every thread: staging memory is written and read at memory speed
/// only with several cores (one call below 4 MiB).
void parallelCopy(void* dst, const void* src, uint64_t bytes);

/// One in-flight unit of work: a command buffer, its fence and descriptor pool. Record with
/// begin() ... submit(), then wait().
class Submission
{
public:
    Submission(Context& ctx, uint32_t maxSets = 8, uint32_t maxBuffers = 64);
    ~Submission();
    Submission(const Submission&) = delete;
    Submission& operator=(const Submission&) = delete;

    void begin();
    /// Copies `bytes` from src to dst (both at offset 0).
    void copy(const Buffer& src, const Buffer& dst, VkDeviceSize bytes);
    /// Sets the first `bytes` (a multiple of 4) of b to zero.
    void zero(const Buffer& b, VkDeviceSize bytes);
    /// Orders earlier transfers and dispatches before later ones (compute and transfer stages).
    void barrier();
    /// Binds `buffers` to bindings 0..n-1 and dispatches gx × gy workgroups.
    void dispatch(const Kernel& k, const std::vector<const Buffer*>& buffers, const void* push, uint32_t gx,
                  uint32_t gy = 1);
    void submit();
    /// Waits for the submission; `interrupted` is polled about every 20 ms (the work in flight
    /// still finishes). Returns true when the wait ended with the work done and no interruption
    /// was asked for. Throws DeviceError when the device was lost.
    bool wait(const std::function<bool()>& interrupted = {});
    bool pending() const { return mPending; }

private:
    Context& mCtx;
    VkCommandPool mPool = VK_NULL_HANDLE;
    VkCommandBuffer mCmd = VK_NULL_HANDLE;
    VkFence mFence = VK_NULL_HANDLE;
    VkDescriptorPool mDescriptors = VK_NULL_HANDLE;
    bool mPending = false;
    // the last dispatch's descriptor set, reused while kernel and buffers repeat
    VkDescriptorSet mLastSet = VK_NULL_HANDLE;
    VkPipeline mLastPipeline = VK_NULL_HANDLE;
    std::vector<VkBuffer> mLastBuffers;
};

} // namespace levelforge::gpu_internal
