// SPDX-License-Identifier: Apache-2.0
// The Vulkan compute runtime. See VulkanRuntime.h and VulkanDevices.h.
#include "gpu/VulkanRuntime.h"

#include <dlfcn.h>

#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <sstream>

namespace levelforge {
namespace gpu_internal {
namespace {

std::atomic<uint64_t> gValidationMessages{0};

VKAPI_ATTR VkBool32 VKAPI_CALL onValidation(VkDebugUtilsMessageSeverityFlagBitsEXT severity,
                                             VkDebugUtilsMessageTypeFlagsEXT, const VkDebugUtilsMessengerCallbackDataEXT* data,
                                             void*)
{
    if (severity >= VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT) {
        gValidationMessages.fetch_add(1);
        std::fprintf(stderr, "levelforge: Vulkan validation: %s\n", data && data->pMessage ? data->pMessage : "(no text)");
    }
    return VK_FALSE;
}

const char* resultName(VkResult r)
{
    switch (r) {
    case VK_ERROR_OUT_OF_HOST_MEMORY: return "out of host memory";
    case VK_ERROR_OUT_OF_DEVICE_MEMORY: return "out of device memory";
    case VK_ERROR_INITIALIZATION_FAILED: return "initialization failed";
    case VK_ERROR_DEVICE_LOST: return "device lost";
    case VK_ERROR_MEMORY_MAP_FAILED: return "memory map failed";
    case VK_ERROR_LAYER_NOT_PRESENT: return "layer not present";
    case VK_ERROR_EXTENSION_NOT_PRESENT: return "extension not present";
    case VK_ERROR_FEATURE_NOT_PRESENT: return "feature not present";
    case VK_ERROR_INCOMPATIBLE_DRIVER: return "incompatible driver (no Vulkan driver installed?)";
    case VK_ERROR_TOO_MANY_OBJECTS: return "too many objects";
    case VK_TIMEOUT: return "timeout";
    default: return "error";
    }
}

std::string versionText(uint32_t v)
{
    std::ostringstream os;
    os << VK_API_VERSION_MAJOR(v) << '.' << VK_API_VERSION_MINOR(v) << '.' << VK_API_VERSION_PATCH(v);
    return os.str();
}

const char* typeName(VkPhysicalDeviceType t)
{
    switch (t) {
    case VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU: return "discrete";
    case VK_PHYSICAL_DEVICE_TYPE_INTEGRATED_GPU: return "integrated";
    case VK_PHYSICAL_DEVICE_TYPE_VIRTUAL_GPU: return "virtual";
    case VK_PHYSICAL_DEVICE_TYPE_CPU: return "cpu";
    default: return "other";
    }
}

/// Test aid: LEVELFORGE_VULKAN_INJECT=oom fails device allocations as out of device memory,
/// =lost reports the device lost after each submission completes.
bool injected(const char* what)
{
    const char* v = std::getenv("LEVELFORGE_VULKAN_INJECT");
    return v && std::strcmp(v, what) == 0;
}

bool validationWanted()
{
    const char* v = std::getenv("LEVELFORGE_VULKAN_VALIDATION");
    return v && *v && std::strcmp(v, "0") != 0;
}

/// The loader's entry points (global and instance-independent), loaded once.
const Api* loader(std::string& why)
{
    static std::once_flag once;
    static Api api;
    static bool ok = false;
    static std::string problem;
    std::call_once(once, [] {
        void* lib = dlopen("libvulkan.so.1", RTLD_NOW | RTLD_LOCAL);
        if (!lib) lib = dlopen("libvulkan.so", RTLD_NOW | RTLD_LOCAL);
        if (!lib) { problem = "no Vulkan loader (libvulkan.so.1; Debian package libvulkan1)"; return; }
        api.vkGetInstanceProcAddr = reinterpret_cast<PFN_vkGetInstanceProcAddr>(dlsym(lib, "vkGetInstanceProcAddr"));
        if (!api.vkGetInstanceProcAddr) { problem = "the Vulkan loader has no vkGetInstanceProcAddr"; return; }
        auto g = [](const char* n) { return api.vkGetInstanceProcAddr(VK_NULL_HANDLE, n); };
        api.vkCreateInstance = reinterpret_cast<PFN_vkCreateInstance>(g("vkCreateInstance"));
        api.vkEnumerateInstanceLayerProperties =
            reinterpret_cast<PFN_vkEnumerateInstanceLayerProperties>(g("vkEnumerateInstanceLayerProperties"));
        api.vkEnumerateInstanceExtensionProperties =
            reinterpret_cast<PFN_vkEnumerateInstanceExtensionProperties>(g("vkEnumerateInstanceExtensionProperties"));
        if (!api.vkCreateInstance) { problem = "the Vulkan loader has no vkCreateInstance"; return; }
        ok = true; // the library stays loaded for the life of the process
    });
    why = problem;
    return ok ? &api : nullptr;
}

/// An instance (with validation when asked for) and its entry points.
struct Instance
{
    Api api;
    VkInstance instance = VK_NULL_HANDLE;
    VkDebugUtilsMessengerEXT messenger = VK_NULL_HANDLE;
};

bool createInstance(Instance& out, std::string& why)
{
    const Api* base = loader(why);
    if (!base) return false;
    out.api = *base;
    Api& api = out.api;
    std::vector<const char*> layers, extensions;
    if (validationWanted()) {
        uint32_t n = 0;
        api.vkEnumerateInstanceLayerProperties(&n, nullptr);
        std::vector<VkLayerProperties> props(n);
        api.vkEnumerateInstanceLayerProperties(&n, props.data());
        bool have = false;
        for (const auto& p : props) have = have || std::strcmp(p.layerName, "VK_LAYER_KHRONOS_validation") == 0;
        if (!have) {
            why = "LEVELFORGE_VULKAN_VALIDATION is set but VK_LAYER_KHRONOS_validation is not installed "
                  "(Debian package vulkan-validationlayers)";
            return false;
        }
        layers.push_back("VK_LAYER_KHRONOS_validation");
        extensions.push_back(VK_EXT_DEBUG_UTILS_EXTENSION_NAME);
    }
    VkApplicationInfo app{};
    app.sType = VK_STRUCTURE_TYPE_APPLICATION_INFO;
    app.pApplicationName = "levelforge";
    app.pEngineName = "levelforge";
    app.apiVersion = VK_API_VERSION_1_1;
    VkInstanceCreateInfo ci{};
    ci.sType = VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO;
    ci.pApplicationInfo = &app;
    ci.enabledLayerCount = uint32_t(layers.size());
    ci.ppEnabledLayerNames = layers.data();
    ci.enabledExtensionCount = uint32_t(extensions.size());
    ci.ppEnabledExtensionNames = extensions.data();
    const VkResult r = api.vkCreateInstance(&ci, nullptr, &out.instance);
    if (r != VK_SUCCESS) {
        why = std::string("no Vulkan instance: ") + resultName(r);
        return false;
    }
    auto gi = [&](const char* n) { return api.vkGetInstanceProcAddr(out.instance, n); };
#define LF_VK_LOAD(name) api.name = reinterpret_cast<PFN_##name>(gi(#name));
    LF_VK_INSTANCE_FUNCTIONS(LF_VK_LOAD)
#undef LF_VK_LOAD
    if (!layers.empty()) {
        api.vkCreateDebugUtilsMessengerEXT =
            reinterpret_cast<PFN_vkCreateDebugUtilsMessengerEXT>(gi("vkCreateDebugUtilsMessengerEXT"));
        api.vkDestroyDebugUtilsMessengerEXT =
            reinterpret_cast<PFN_vkDestroyDebugUtilsMessengerEXT>(gi("vkDestroyDebugUtilsMessengerEXT"));
        if (api.vkCreateDebugUtilsMessengerEXT) {
            VkDebugUtilsMessengerCreateInfoEXT mi{};
            mi.sType = VK_STRUCTURE_TYPE_DEBUG_UTILS_MESSENGER_CREATE_INFO_EXT;
            mi.messageSeverity = VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT | VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT;
            mi.messageType = VK_DEBUG_UTILS_MESSAGE_TYPE_GENERAL_BIT_EXT | VK_DEBUG_UTILS_MESSAGE_TYPE_VALIDATION_BIT_EXT |
                             VK_DEBUG_UTILS_MESSAGE_TYPE_PERFORMANCE_BIT_EXT;
            mi.pfnUserCallback = onValidation;
            api.vkCreateDebugUtilsMessengerEXT(out.instance, &mi, nullptr, &out.messenger);
        }
    }
    return true;
}

void destroyInstance(Instance& in)
{
    if (in.instance == VK_NULL_HANDLE) return;
    if (in.messenger != VK_NULL_HANDLE && in.api.vkDestroyDebugUtilsMessengerEXT)
        in.api.vkDestroyDebugUtilsMessengerEXT(in.instance, in.messenger, nullptr);
    in.api.vkDestroyInstance(in.instance, nullptr);
    in.instance = VK_NULL_HANDLE;
}

struct Candidate
{
    VkPhysicalDevice physical;
    VulkanDeviceInfo info;
    uint32_t family;
};

/// Every device the instance sees, hidden ones left out, the chosen one marked.
std::vector<Candidate> enumerate(const Instance& in, std::string& why)
{
    const Api& api = in.api;
    std::vector<Candidate> out;
    const char* env = std::getenv("LEVELFORGE_VULKAN_DEVICE");
    const std::string select = env ? env : "";
    if (select == "none") { why = "every Vulkan device is hidden (LEVELFORGE_VULKAN_DEVICE=none)"; return out; }
    uint32_t n = 0;
    api.vkEnumeratePhysicalDevices(in.instance, &n, nullptr);
    std::vector<VkPhysicalDevice> phys(n);
    if (n) api.vkEnumeratePhysicalDevices(in.instance, &n, phys.data());
    for (uint32_t i = 0; i < n; ++i) {
        VkPhysicalDeviceProperties p;
        api.vkGetPhysicalDeviceProperties(phys[i], &p);
        VkPhysicalDeviceFeatures f;
        api.vkGetPhysicalDeviceFeatures(phys[i], &f);
        VkPhysicalDeviceMemoryProperties m;
        api.vkGetPhysicalDeviceMemoryProperties(phys[i], &m);
        uint32_t nq = 0;
        api.vkGetPhysicalDeviceQueueFamilyProperties(phys[i], &nq, nullptr);
        std::vector<VkQueueFamilyProperties> q(nq);
        api.vkGetPhysicalDeviceQueueFamilyProperties(phys[i], &nq, q.data());
        uint32_t family = ~0u;
        for (uint32_t k = 0; k < nq && family == ~0u; ++k)
            if (q[k].queueFlags & VK_QUEUE_COMPUTE_BIT) family = k;
        Candidate c{phys[i], {}, family};
        c.info.index = i;
        c.info.name = p.deviceName;
        c.info.type = typeName(p.deviceType);
        c.info.apiVersion = versionText(p.apiVersion);
        for (uint32_t h = 0; h < m.memoryHeapCount; ++h)
            if (m.memoryHeaps[h].flags & VK_MEMORY_HEAP_DEVICE_LOCAL_BIT)
                c.info.deviceLocalBytes = std::max<uint64_t>(c.info.deviceLocalBytes, m.memoryHeaps[h].size);
        c.info.float64 = f.shaderFloat64 == VK_TRUE;
        c.info.usable = c.info.float64 && family != ~0u;
        if (!select.empty()) {
            char* end = nullptr;
            const long idx = std::strtol(select.c_str(), &end, 10);
            const bool isIndex = end && *end == '\0';
            if (isIndex ? idx != long(i) : c.info.name.find(select) == std::string::npos) continue;
        }
        out.push_back(c);
    }
    int best = -1;
    auto rank = [](const VulkanDeviceInfo& d) {
        return d.type == "discrete" ? 0 : d.type == "integrated" ? 1 : d.type == "virtual" ? 2 : 3;
    };
    for (size_t i = 0; i < out.size(); ++i) {
        if (!out[i].info.usable) continue;
        if (best < 0 || rank(out[i].info) < rank(out[size_t(best)].info) ||
            (rank(out[i].info) == rank(out[size_t(best)].info) &&
             out[i].info.deviceLocalBytes > out[size_t(best)].info.deviceLocalBytes))
            best = int(i);
    }
    if (best >= 0) out[size_t(best)].info.chosen = true;
    else if (out.empty()) why = select.empty() ? "no Vulkan device" : "no Vulkan device matches LEVELFORGE_VULKAN_DEVICE=" + select;
    else why = "no Vulkan device with a compute queue and 64-bit floats (shaderFloat64)";
    return out;
}

} // namespace

struct ContextFactory
{
    static std::shared_ptr<Context> make()
    {
        std::string why;
        Instance in;
        if (!createInstance(in, why)) throw DeviceError("Vulkan: " + why);
        std::vector<Candidate> cands = enumerate(in, why);
        const Candidate* pick = nullptr;
        for (const Candidate& c : cands)
            if (c.info.chosen) pick = &c;
        if (!pick) {
            destroyInstance(in);
            throw DeviceError("Vulkan: " + why);
        }
        std::shared_ptr<Context> ctx(new Context());
        ctx->mApi = in.api;
        ctx->mInstance = in.instance;
        ctx->mMessenger = in.messenger;
        ctx->mPhysical = pick->physical;
        ctx->mInfo = pick->info;
        ctx->mFamily = pick->family;
        Api& api = ctx->mApi;
        api.vkGetPhysicalDeviceMemoryProperties(ctx->mPhysical, &ctx->mMemory);
        VkPhysicalDeviceProperties props;
        api.vkGetPhysicalDeviceProperties(ctx->mPhysical, &props);
        ctx->mLimits = props.limits;
        const float priority = 1.0f;
        VkDeviceQueueCreateInfo qi{};
        qi.sType = VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO;
        qi.queueFamilyIndex = ctx->mFamily;
        qi.queueCount = 1;
        qi.pQueuePriorities = &priority;
        VkPhysicalDeviceFeatures features{};
        features.shaderFloat64 = VK_TRUE;
        VkDeviceCreateInfo di{};
        di.sType = VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO;
        di.queueCreateInfoCount = 1;
        di.pQueueCreateInfos = &qi;
        di.pEnabledFeatures = &features;
        ctx->check(api.vkCreateDevice(ctx->mPhysical, &di, nullptr, &ctx->mDevice), "creating the device");
        auto gd = [&](const char* n) { return api.vkGetDeviceProcAddr(ctx->mDevice, n); };
#define LF_VK_LOAD(name) api.name = reinterpret_cast<PFN_##name>(gd(#name));
        LF_VK_DEVICE_FUNCTIONS(LF_VK_LOAD)
#undef LF_VK_LOAD
        api.vkGetDeviceQueue(ctx->mDevice, ctx->mFamily, 0, &ctx->mQueue);
        // unified: some device-local type is also host-visible and coherent on the largest heap
        ctx->mUnified = ctx->mInfo.type == "cpu" || ctx->mInfo.type == "integrated";
        return ctx;
    }
};

std::shared_ptr<Context> Context::get()
{
    static std::mutex m;
    // Never destroyed: at exit the driver's own statics may already be gone (the OS reclaims the
    // device); reachable from here, so leak checkers do not report it.
    static std::shared_ptr<Context>& shared = *new std::shared_ptr<Context>();
    const char* env = std::getenv("LEVELFORGE_VULKAN_DEVICE");
    if (env && std::strcmp(env, "none") == 0)
        throw DeviceError("Vulkan: every Vulkan device is hidden (LEVELFORGE_VULKAN_DEVICE=none)");
    std::lock_guard<std::mutex> lock(m);
    if (!shared || shared->mLost) shared = ContextFactory::make(); // a lost device is opened afresh
    return shared;
}

Context::~Context()
{
    if (mDevice != VK_NULL_HANDLE) {
        mApi.vkDeviceWaitIdle(mDevice);
        mApi.vkDestroyDevice(mDevice, nullptr);
    }
    Instance in;
    in.api = mApi;
    in.instance = mInstance;
    in.messenger = mMessenger;
    destroyInstance(in);
}

void Context::check(VkResult r, const char* what) const
{
    if (r == VK_SUCCESS) return;
    if (r == VK_ERROR_DEVICE_LOST) mLost = true;
    std::ostringstream os;
    os << "Vulkan device '" << mInfo.name << "': " << resultName(r) << " (VkResult " << int(r) << ") while " << what;
    throw DeviceError(os.str());
}

void Context::requireRange(uint64_t bytes, const char* what) const
{
    if (bytes <= maxBufferRange()) return;
    std::ostringstream os;
    os << "Vulkan device '" << mInfo.name << "': " << what << " need " << (double(bytes) / 1048576.0)
       << " MiB in one storage buffer; this device allows " << (double(maxBufferRange()) / 1048576.0) << " MiB";
    throw DeviceError(os.str());
}

Buffer Context::create(VkDeviceSize bytes, Memory where, const char* what)
{
    Buffer b;
    b.size = std::max<VkDeviceSize>(bytes, 4);
    VkBufferCreateInfo bi{};
    bi.sType = VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO;
    bi.size = b.size;
    bi.usage = VK_BUFFER_USAGE_TRANSFER_SRC_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT;
    if (where == Memory::Device || mUnified) bi.usage |= VK_BUFFER_USAGE_STORAGE_BUFFER_BIT;
    bi.sharingMode = VK_SHARING_MODE_EXCLUSIVE;
    std::string ctxText = std::string("creating a buffer for ") + what;
    check(mApi.vkCreateBuffer(mDevice, &bi, nullptr, &b.buffer), ctxText.c_str());
    VkMemoryRequirements req;
    mApi.vkGetBufferMemoryRequirements(mDevice, b.buffer, &req);
    VkMemoryPropertyFlags want = 0, avoid = 0;
    switch (where) {
    case Memory::Device: want = VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT; break;
    case Memory::Upload: want = VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT; break;
    case Memory::Readback: want = VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_CACHED_BIT; break;
    }
    if (mUnified) want |= VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT;
    if (where == Memory::Upload && !mUnified) avoid = VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT;
    uint32_t type = ~0u;
    for (int pass = 0; pass < 3 && type == ~0u; ++pass) {
        for (uint32_t i = 0; i < mMemory.memoryTypeCount; ++i) {
            if (!(req.memoryTypeBits & (1u << i))) continue;
            const VkMemoryPropertyFlags f = mMemory.memoryTypes[i].propertyFlags;
            if ((f & want) != want) continue;
            if (pass == 0 && (f & avoid)) continue;
            type = i;
            break;
        }
        if (pass == 1 && type == ~0u && where == Memory::Readback) // no cached host memory: coherent will do
            want = VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT;
    }
    if (type == ~0u) {
        mApi.vkDestroyBuffer(mDevice, b.buffer, nullptr);
        throw DeviceError("Vulkan device '" + mInfo.name + "': no suitable memory type for " + what);
    }
    VkMemoryAllocateInfo ai{};
    ai.sType = VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO;
    ai.allocationSize = req.size;
    ai.memoryTypeIndex = type;
    const VkResult r = where == Memory::Device && bytes > 4 && injected("oom")
                           ? VK_ERROR_OUT_OF_DEVICE_MEMORY
                           : mApi.vkAllocateMemory(mDevice, &ai, nullptr, &b.memory);
    if (r != VK_SUCCESS) {
        mApi.vkDestroyBuffer(mDevice, b.buffer, nullptr);
        std::ostringstream os;
        os << "allocating " << (double(req.size) / 1048576.0) << " MiB for " << what;
        check(r, os.str().c_str());
    }
    mApi.vkBindBufferMemory(mDevice, b.buffer, b.memory, 0);
    const VkMemoryPropertyFlags f = mMemory.memoryTypes[type].propertyFlags;
    b.coherent = (f & VK_MEMORY_PROPERTY_HOST_COHERENT_BIT) != 0;
    if (f & VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT) {
        const VkResult mr = mApi.vkMapMemory(mDevice, b.memory, 0, VK_WHOLE_SIZE, 0, &b.mapped);
        if (mr != VK_SUCCESS) {
            destroy(b);
            check(mr, ctxText.c_str());
        }
    }
    return b;
}

void Context::destroy(Buffer& b)
{
    if (b.mapped) mApi.vkUnmapMemory(mDevice, b.memory);
    if (b.buffer != VK_NULL_HANDLE) mApi.vkDestroyBuffer(mDevice, b.buffer, nullptr);
    if (b.memory != VK_NULL_HANDLE) mApi.vkFreeMemory(mDevice, b.memory, nullptr);
    b = Buffer{};
}

void Context::invalidate(const Buffer& b)
{
    if (b.coherent || !b.mapped) return;
    VkMappedMemoryRange r{};
    r.sType = VK_STRUCTURE_TYPE_MAPPED_MEMORY_RANGE;
    r.memory = b.memory;
    r.offset = 0;
    r.size = VK_WHOLE_SIZE;
    check(mApi.vkInvalidateMappedMemoryRanges(mDevice, 1, &r), "reading results back");
}

Kernel Context::createKernel(const uint32_t* spirv, size_t bytes, uint32_t bindings, uint32_t pushBytes)
{
    Kernel k;
    k.bindings = bindings;
    k.pushBytes = pushBytes;
    VkShaderModuleCreateInfo si{};
    si.sType = VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO;
    si.codeSize = bytes;
    si.pCode = spirv;
    check(mApi.vkCreateShaderModule(mDevice, &si, nullptr, &k.module), "creating a shader module");
    std::vector<VkDescriptorSetLayoutBinding> b(bindings);
    for (uint32_t i = 0; i < bindings; ++i) {
        b[i] = VkDescriptorSetLayoutBinding{};
        b[i].binding = i;
        b[i].descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
        b[i].descriptorCount = 1;
        b[i].stageFlags = VK_SHADER_STAGE_COMPUTE_BIT;
    }
    VkDescriptorSetLayoutCreateInfo li{};
    li.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO;
    li.bindingCount = bindings;
    li.pBindings = b.data();
    check(mApi.vkCreateDescriptorSetLayout(mDevice, &li, nullptr, &k.setLayout), "creating a descriptor set layout");
    VkPushConstantRange pr{VK_SHADER_STAGE_COMPUTE_BIT, 0, pushBytes};
    VkPipelineLayoutCreateInfo pi{};
    pi.sType = VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO;
    pi.setLayoutCount = 1;
    pi.pSetLayouts = &k.setLayout;
    pi.pushConstantRangeCount = pushBytes ? 1 : 0;
    pi.pPushConstantRanges = &pr;
    check(mApi.vkCreatePipelineLayout(mDevice, &pi, nullptr, &k.layout), "creating a pipeline layout");
    VkComputePipelineCreateInfo ci{};
    ci.sType = VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO;
    ci.stage.sType = VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO;
    ci.stage.stage = VK_SHADER_STAGE_COMPUTE_BIT;
    ci.stage.module = k.module;
    ci.stage.pName = "main";
    ci.layout = k.layout;
    check(mApi.vkCreateComputePipelines(mDevice, VK_NULL_HANDLE, 1, &ci, nullptr, &k.pipeline), "creating a compute pipeline");
    return k;
}

void Context::destroy(Kernel& k)
{
    if (k.pipeline != VK_NULL_HANDLE) mApi.vkDestroyPipeline(mDevice, k.pipeline, nullptr);
    if (k.layout != VK_NULL_HANDLE) mApi.vkDestroyPipelineLayout(mDevice, k.layout, nullptr);
    if (k.setLayout != VK_NULL_HANDLE) mApi.vkDestroyDescriptorSetLayout(mDevice, k.setLayout, nullptr);
    if (k.module != VK_NULL_HANDLE) mApi.vkDestroyShaderModule(mDevice, k.module, nullptr);
    k = Kernel{};
}

void parallelCopy(void* dst, const void* src, uint64_t bytes)
{
    constexpr uint64_t kPiece = uint64_t(4) << 20;
    auto* d = static_cast<unsigned char*>(dst);
    const auto* s = static_cast<const unsigned char*>(src);
    if (bytes <= kPiece) {
        if (bytes) std::memcpy(d, s, bytes);
        return;
    }
    tbb::parallel_for(tbb::blocked_range<uint64_t>(0, (bytes + kPiece - 1) / kPiece), [&](const tbb::blocked_range<uint64_t>& r) {
        for (uint64_t c = r.begin(); c != r.end(); ++c)
            std::memcpy(d + c * kPiece, s + c * kPiece, std::min(kPiece, bytes - c * kPiece));
    });
}

// ------------------------------------------------------------------------------------ Submission

Submission::Submission(Context& ctx, uint32_t maxSets, uint32_t maxBuffers) : mCtx(ctx)
{
    const Api& api = ctx.api();
    VkCommandPoolCreateInfo pi{};
    pi.sType = VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO;
    pi.flags = VK_COMMAND_POOL_CREATE_RESET_COMMAND_BUFFER_BIT;
    pi.queueFamilyIndex = ctx.queueFamily();
    ctx.check(api.vkCreateCommandPool(ctx.device(), &pi, nullptr, &mPool), "creating a command pool");
    VkCommandBufferAllocateInfo ai{};
    ai.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO;
    ai.commandPool = mPool;
    ai.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
    ai.commandBufferCount = 1;
    ctx.check(api.vkAllocateCommandBuffers(ctx.device(), &ai, &mCmd), "allocating a command buffer");
    VkFenceCreateInfo fi{};
    fi.sType = VK_STRUCTURE_TYPE_FENCE_CREATE_INFO;
    ctx.check(api.vkCreateFence(ctx.device(), &fi, nullptr, &mFence), "creating a fence");
    VkDescriptorPoolSize ps{VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, maxBuffers};
    VkDescriptorPoolCreateInfo di{};
    di.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO;
    di.maxSets = maxSets;
    di.poolSizeCount = 1;
    di.pPoolSizes = &ps;
    ctx.check(api.vkCreateDescriptorPool(ctx.device(), &di, nullptr, &mDescriptors), "creating a descriptor pool");
}

Submission::~Submission()
{
    const Api& api = mCtx.api();
    if (mPending) api.vkWaitForFences(mCtx.device(), 1, &mFence, VK_TRUE, UINT64_MAX);
    api.vkDestroyDescriptorPool(mCtx.device(), mDescriptors, nullptr);
    api.vkDestroyFence(mCtx.device(), mFence, nullptr);
    api.vkDestroyCommandPool(mCtx.device(), mPool, nullptr);
}

void Submission::begin()
{
    const Api& api = mCtx.api();
    mCtx.check(api.vkResetCommandBuffer(mCmd, 0), "resetting a command buffer");
    mCtx.check(api.vkResetDescriptorPool(mCtx.device(), mDescriptors, 0), "resetting a descriptor pool");
    mLastSet = VK_NULL_HANDLE;
    VkCommandBufferBeginInfo bi{};
    bi.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO;
    bi.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
    mCtx.check(api.vkBeginCommandBuffer(mCmd, &bi), "recording commands");
}

void Submission::copy(const Buffer& src, const Buffer& dst, VkDeviceSize bytes)
{
    if (bytes == 0) return;
    VkBufferCopy c{0, 0, bytes};
    mCtx.api().vkCmdCopyBuffer(mCmd, src.buffer, dst.buffer, 1, &c);
}

void Submission::zero(const Buffer& b, VkDeviceSize bytes)
{
    if (bytes) mCtx.api().vkCmdFillBuffer(mCmd, b.buffer, 0, bytes, 0u);
}

void Submission::barrier()
{
    VkMemoryBarrier mb{};
    mb.sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER;
    mb.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT | VK_ACCESS_SHADER_WRITE_BIT;
    mb.dstAccessMask = VK_ACCESS_TRANSFER_READ_BIT | VK_ACCESS_TRANSFER_WRITE_BIT | VK_ACCESS_SHADER_READ_BIT |
                       VK_ACCESS_SHADER_WRITE_BIT | VK_ACCESS_HOST_READ_BIT;
    const VkPipelineStageFlags stages = VK_PIPELINE_STAGE_TRANSFER_BIT | VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT;
    mCtx.api().vkCmdPipelineBarrier(mCmd, stages, stages | VK_PIPELINE_STAGE_HOST_BIT, 0, 1, &mb, 0, nullptr, 0, nullptr);
}

void Submission::dispatch(const Kernel& k, const std::vector<const Buffer*>& buffers, const void* push, uint32_t gx,
                          uint32_t gy)
{
    const Api& api = mCtx.api();
    std::vector<VkBuffer> handles(buffers.size());
    for (size_t i = 0; i < buffers.size(); ++i) handles[i] = buffers[i]->buffer;
    if (mLastSet != VK_NULL_HANDLE && mLastPipeline == k.pipeline && mLastBuffers == handles) {
        api.vkCmdBindPipeline(mCmd, VK_PIPELINE_BIND_POINT_COMPUTE, k.pipeline);
        api.vkCmdBindDescriptorSets(mCmd, VK_PIPELINE_BIND_POINT_COMPUTE, k.layout, 0, 1, &mLastSet, 0, nullptr);
        if (k.pushBytes) api.vkCmdPushConstants(mCmd, k.layout, VK_SHADER_STAGE_COMPUTE_BIT, 0, k.pushBytes, push);
        if (gx && gy) api.vkCmdDispatch(mCmd, gx, gy, 1);
        return;
    }
    VkDescriptorSetAllocateInfo ai{};
    ai.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO;
    ai.descriptorPool = mDescriptors;
    ai.descriptorSetCount = 1;
    ai.pSetLayouts = &k.setLayout;
    VkDescriptorSet set;
    mCtx.check(api.vkAllocateDescriptorSets(mCtx.device(), &ai, &set), "allocating a descriptor set");
    std::vector<VkDescriptorBufferInfo> infos(buffers.size());
    std::vector<VkWriteDescriptorSet> writes(buffers.size());
    for (size_t i = 0; i < buffers.size(); ++i) {
        // the buffer may be larger than its data (grown by a quarter): bind at most what the
        // device can address (the callers check that their data fits)
        infos[i] = VkDescriptorBufferInfo{buffers[i]->buffer, 0, std::min<VkDeviceSize>(buffers[i]->size, mCtx.maxBufferRange())};
        writes[i] = VkWriteDescriptorSet{};
        writes[i].sType = VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET;
        writes[i].dstSet = set;
        writes[i].dstBinding = uint32_t(i);
        writes[i].descriptorCount = 1;
        writes[i].descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
        writes[i].pBufferInfo = &infos[i];
    }
    api.vkUpdateDescriptorSets(mCtx.device(), uint32_t(writes.size()), writes.data(), 0, nullptr);
    api.vkCmdBindPipeline(mCmd, VK_PIPELINE_BIND_POINT_COMPUTE, k.pipeline);
    api.vkCmdBindDescriptorSets(mCmd, VK_PIPELINE_BIND_POINT_COMPUTE, k.layout, 0, 1, &set, 0, nullptr);
    if (k.pushBytes) api.vkCmdPushConstants(mCmd, k.layout, VK_SHADER_STAGE_COMPUTE_BIT, 0, k.pushBytes, push);
    if (gx && gy) api.vkCmdDispatch(mCmd, gx, gy, 1);
    mLastSet = set;
    mLastPipeline = k.pipeline;
    mLastBuffers = std::move(handles);
}

void Submission::submit()
{
    const Api& api = mCtx.api();
    mCtx.check(api.vkEndCommandBuffer(mCmd), "recording commands");
    mCtx.check(api.vkResetFences(mCtx.device(), 1, &mFence), "resetting a fence");
    VkSubmitInfo si{};
    si.sType = VK_STRUCTURE_TYPE_SUBMIT_INFO;
    si.commandBufferCount = 1;
    si.pCommandBuffers = &mCmd;
    std::lock_guard<std::mutex> lock(mCtx.queueMutex());
    mCtx.check(api.vkQueueSubmit(mCtx.queue(), 1, &si, mFence), "submitting work");
    mPending = true;
}

bool Submission::wait(const std::function<bool()>& interrupted)
{
    if (!mPending) return true;
    const Api& api = mCtx.api();
    bool stop = false;
    for (;;) {
        const VkResult r = api.vkWaitForFences(mCtx.device(), 1, &mFence, VK_TRUE, 20'000'000);
        if (r == VK_SUCCESS) break;
        if (r != VK_TIMEOUT) {
            mPending = false;
            mCtx.check(r, "waiting for the device");
        }
        if (!stop && interrupted && interrupted()) stop = true; // the dispatch in flight still completes
    }
    mPending = false;
    if (injected("lost")) mCtx.check(VK_ERROR_DEVICE_LOST, "waiting for the device (injected by LEVELFORGE_VULKAN_INJECT)");
    return !stop;
}

} // namespace gpu_internal

// ------------------------------------------------------------------------------------ public

VulkanDeviceList listVulkanDevices()
{
    VulkanDeviceList out;
    out.compiledIn = true;
    gpu_internal::Instance in;
    std::string why;
    if (!gpu_internal::createInstance(in, why)) { out.problem = why; return out; }
    out.loaderFound = true;
    for (const auto& c : gpu_internal::enumerate(in, why)) out.devices.push_back(c.info);
    out.problem = why;
    gpu_internal::destroyInstance(in);
    return out;
}

uint64_t vulkanValidationMessages() { return gpu_internal::gValidationMessages.load(); }

} // namespace levelforge
