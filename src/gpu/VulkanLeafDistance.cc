// SPDX-License-Identifier: Apache-2.0
// The main road's band leaves on a Vulkan device. See VulkanLeafDistance.h.
#include "gpu/VulkanLeafDistance.h"
#include "gpu/VulkanRuntime.h"

#include <algorithm>
#include <chrono>
#include <cstring>

namespace levelforge::gpu_internal {

extern const uint32_t kSpirv_leaf_distance[];
extern const size_t kSpirv_leaf_distanceBytes;

namespace {
using Clock = std::chrono::steady_clock;
double since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

struct Push
{
    double limit2;
    uint32_t leafCount;
    uint32_t groupsX;
};
static_assert(sizeof(Push) == 16, "push constants as the shader declares them");
} // namespace

struct LeafDistanceDevice::Impl
{
    std::shared_ptr<Context> ctx;
    Kernel kernel;
    Buffer corners;
    struct Slot
    {
        Buffer leaves, cands, d2, tri;         // device
        Buffer upLeaves, upCands, downD2, downTri; // staging (unused on unified memory)
        std::unique_ptr<Submission> sub;
        size_t count = 0;
    } slots[2];
    uint64_t deviceBytes = 0, peak = 0;

    void ensure(Buffer& b, VkDeviceSize bytes, Memory where, const char* what)
    {
        if (b.buffer != VK_NULL_HANDLE && b.size >= bytes) return;
        if (b.buffer != VK_NULL_HANDLE) { deviceBytes -= b.size; ctx->destroy(b); }
        b = ctx->create(bytes + bytes / 4, where, what);
        deviceBytes += b.size;
        peak = std::max(peak, deviceBytes);
    }
    ~Impl()
    {
        if (!ctx) return;
        for (Slot& s : slots) {
            s.sub.reset(); // waits for work in flight
            for (Buffer* b : {&s.leaves, &s.cands, &s.d2, &s.tri, &s.upLeaves, &s.upCands, &s.downD2, &s.downTri})
                if (b->buffer != VK_NULL_HANDLE) ctx->destroy(*b);
        }
        if (corners.buffer != VK_NULL_HANDLE) ctx->destroy(corners);
        ctx->destroy(kernel);
    }
};

LeafDistanceDevice::LeafDistanceDevice(const std::vector<double>& corners) : mImpl(new Impl)
{
    Impl& m = *mImpl;
    m.ctx = Context::get();
    m.kernel = m.ctx->createKernel(kSpirv_leaf_distance, kSpirv_leaf_distanceBytes, 5, sizeof(Push));
    for (auto& s : m.slots) s.sub.reset(new Submission(*m.ctx));
    const VkDeviceSize bytes = corners.size() * sizeof(double);
    const auto t = Clock::now();
    if (m.ctx->unifiedMemory()) {
        m.ensure(m.corners, bytes, Memory::Device, "the triangles");
        std::memcpy(m.corners.mapped, corners.data(), bytes);
    } else {
        m.ensure(m.corners, bytes, Memory::Device, "the triangles");
        Buffer up = m.ctx->create(bytes, Memory::Upload, "uploading the triangles");
        std::memcpy(up.mapped, corners.data(), bytes);
        Submission& s = *m.slots[0].sub;
        s.begin();
        s.copy(up, m.corners, bytes);
        s.barrier();
        s.submit();
        try { s.wait(); } catch (...) { m.ctx->destroy(up); throw; }
        m.ctx->destroy(up);
    }
    mStats.secondsCopy += since(t);
    mStats.bytesUp += bytes;
}

LeafDistanceDevice::~LeafDistanceDevice() = default;

std::string LeafDistanceDevice::deviceName() const
{
    return mImpl->ctx->info().name + " (" + mImpl->ctx->info().type + ")";
}

uint64_t LeafDistanceDevice::slotBudget(uint64_t override) const
{
    if (override) return override;
    return std::min<uint64_t>(mImpl->ctx->info().deviceLocalBytes / 4, uint64_t(512) << 20);
}

void LeafDistanceDevice::start(int slot, const LeafBatch& b, double limit2)
{
    Impl& m = *mImpl;
    Impl::Slot& s = m.slots[slot];
    s.count = b.count();
    if (s.count == 0) return;
    const auto t = Clock::now();
    const VkDeviceSize lb = b.leaves.size() * sizeof(int32_t), cb = std::max<size_t>(b.cands.size(), 1) * sizeof(uint32_t);
    const VkDeviceSize db = s.count * 512 * sizeof(double), tb = s.count * 512 * sizeof(uint32_t);
    m.ensure(s.leaves, lb, Memory::Device, "a batch of leaves");
    m.ensure(s.cands, cb, Memory::Device, "a batch's candidate triangles");
    m.ensure(s.d2, db, Memory::Device, "a batch's distances");
    m.ensure(s.tri, tb, Memory::Device, "a batch's closest triangles");
    Submission& sub = *s.sub;
    sub.begin();
    if (m.ctx->unifiedMemory()) {
        std::memcpy(s.leaves.mapped, b.leaves.data(), lb);
        if (!b.cands.empty()) std::memcpy(s.cands.mapped, b.cands.data(), b.cands.size() * sizeof(uint32_t));
    } else {
        m.ensure(s.upLeaves, lb, Memory::Upload, "staging a batch of leaves");
        m.ensure(s.upCands, cb, Memory::Upload, "staging a batch's candidate triangles");
        m.ensure(s.downD2, db, Memory::Readback, "reading back a batch's distances");
        m.ensure(s.downTri, tb, Memory::Readback, "reading back a batch's closest triangles");
        std::memcpy(s.upLeaves.mapped, b.leaves.data(), lb);
        if (!b.cands.empty()) std::memcpy(s.upCands.mapped, b.cands.data(), b.cands.size() * sizeof(uint32_t));
        sub.copy(s.upLeaves, s.leaves, lb);
        sub.copy(s.upCands, s.cands, cb);
        sub.barrier();
    }
    mStats.secondsCopy += since(t);
    const uint32_t maxX = std::min<uint32_t>(m.ctx->limits().maxComputeWorkGroupCount[0], 65535u);
    Push push{limit2, uint32_t(s.count), uint32_t(std::min<size_t>(s.count, maxX))};
    const uint32_t gy = uint32_t((s.count + push.groupsX - 1) / push.groupsX);
    sub.dispatch(m.kernel, {&m.corners, &s.leaves, &s.cands, &s.d2, &s.tri}, &push, push.groupsX, gy);
    sub.barrier();
    if (!m.ctx->unifiedMemory()) {
        sub.copy(s.d2, s.downD2, db);
        sub.copy(s.tri, s.downTri, tb);
        sub.barrier();
    }
    sub.submit();
    ++mStats.batches;
    mStats.leaves += s.count;
    mStats.pairs += uint64_t(b.cands.size()) * 512;
    mStats.bytesUp += lb + b.cands.size() * sizeof(uint32_t);
    mStats.peakDeviceBytes = m.peak;
}

bool LeafDistanceDevice::finish(int slot, LeafBatch& b, const std::function<bool()>& interrupted)
{
    Impl& m = *mImpl;
    Impl::Slot& s = m.slots[slot];
    if (s.count == 0) { b.d2.clear(); b.tri.clear(); return true; }
    auto t = Clock::now();
    const bool done = s.sub->wait(interrupted);
    mStats.secondsWait += since(t);
    if (!done) return false;
    t = Clock::now();
    const Buffer& d2 = m.ctx->unifiedMemory() ? s.d2 : s.downD2;
    const Buffer& tri = m.ctx->unifiedMemory() ? s.tri : s.downTri;
    m.ctx->invalidate(d2);
    m.ctx->invalidate(tri);
    b.d2.resize(s.count * 512);
    b.tri.resize(s.count * 512);
    std::memcpy(b.d2.data(), d2.mapped, b.d2.size() * sizeof(double));
    std::memcpy(b.tri.data(), tri.mapped, b.tri.size() * sizeof(uint32_t));
    mStats.secondsCopy += since(t);
    mStats.bytesDown += s.count * 512 * (sizeof(double) + sizeof(uint32_t));
    return true;
}

} // namespace levelforge::gpu_internal
