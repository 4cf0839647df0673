// SPDX-License-Identifier: Apache-2.0
// The main road's band leaves on a Vulkan device. See VulkanLeafDistance.h.
#include "gpu/VulkanLeafDistance.h"
#include "gpu/VulkanRuntime.h"
#include "detail/Timer.h"

#include <algorithm>
#include <cstring>

namespace levelforge::gpu_internal {

extern const uint32_t kSpirv_leaf_distance[];
extern const size_t kSpirv_leaf_distanceBytes;

namespace {
using detail::Clock;

struct Push
{
    double limit2;
    uint32_t leafCount;
    uint32_t groupsX;
    uint32_t signs;
    uint32_t candBegin;
    uint32_t candEnd;
    uint32_t last;
};
static_assert(sizeof(Push) == 32, "push constants as the shader declares them");
} // namespace

struct LeafDistanceDevice::Impl
{
    std::shared_ptr<Context> ctx;
    Kernel kernel;
    Buffer corners, triNormals, vertexNormals, triVertices;
    bool signs = false;
    struct Slot
    {
        Buffer leaves, cands, tri, d2;               // device
        Buffer upLeaves, upCands, downTri, downD2;   // staging (unused on unified memory)
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
    /// A device buffer of `bytes` filled by `fill` (through a staging buffer unless unified).
    void upload(Buffer& dst, VkDeviceSize bytes, const char* what, const std::function<void(void*)>& fill)
    {
        ensure(dst, bytes, Memory::Device, what);
        if (ctx->unifiedMemory()) { fill(dst.mapped); return; }
        Buffer up = ctx->create(bytes, Memory::Upload, what);
        try {
            fill(up.mapped);
            Submission& s = *slots[0].sub;
            s.begin();
            s.copy(up, dst, bytes);
            s.barrier();
            s.submit();
            s.wait();
        } catch (...) {
            ctx->destroy(up);
            throw;
        }
        ctx->destroy(up);
    }
    ~Impl()
    {
        if (!ctx) return;
        for (Slot& s : slots) {
            s.sub.reset(); // waits for work in flight
            for (Buffer* b : {&s.leaves, &s.cands, &s.tri, &s.d2, &s.upLeaves, &s.upCands, &s.downTri, &s.downD2})
                if (b->buffer != VK_NULL_HANDLE) ctx->destroy(*b);
        }
        for (Buffer* b : {&corners, &triNormals, &vertexNormals, &triVertices})
            if (b->buffer != VK_NULL_HANDLE) ctx->destroy(*b);
        ctx->destroy(kernel);
    }
};

LeafDistanceDevice::LeafDistanceDevice(const LeafDeviceInput& in) : mImpl(new Impl)
{
    Impl& m = *mImpl;
    m.ctx = Context::get();
    m.kernel = m.ctx->createKernel(kSpirv_leaf_distance, kSpirv_leaf_distanceBytes, 8, sizeof(Push));
    for (auto& s : m.slots) s.sub.reset(new Submission(*m.ctx));
    const auto t = Clock::now();
    const VkDeviceSize cb = in.triangles * 9 * sizeof(double);
    m.ctx->requireRange(cb, "the triangles' corners");
    if (in.fillNormals) m.ctx->requireRange(in.triangles * 12 * sizeof(double), "the triangles' normals");
    m.upload(m.corners, cb, "the triangles", [&](void* p) { in.fillCorners(static_cast<double*>(p)); });
    mStats.bytesUp += cb;
    m.signs = bool(in.fillNormals);
    if (m.signs) {
        // the three arrays are filled by one call: stage them in one buffer, copy out in three
        const VkDeviceSize nb = in.triangles * 12 * sizeof(double), vb = in.vertices * 3 * sizeof(double),
                           ib = in.triangles * 3 * sizeof(uint32_t);
        m.ensure(m.triNormals, nb, Memory::Device, "the triangles' normals");
        m.ensure(m.vertexNormals, vb, Memory::Device, "the vertex normals");
        m.ensure(m.triVertices, ib, Memory::Device, "the triangles' vertices");
        if (m.ctx->unifiedMemory()) {
            in.fillNormals(static_cast<double*>(m.triNormals.mapped), static_cast<double*>(m.vertexNormals.mapped),
                           static_cast<uint32_t*>(m.triVertices.mapped));
        } else {
            Buffer up[3] = {m.ctx->create(nb, Memory::Upload, "the triangles' normals"),
                            m.ctx->create(vb, Memory::Upload, "the vertex normals"),
                            m.ctx->create(ib, Memory::Upload, "the triangles' vertices")};
            try {
                in.fillNormals(static_cast<double*>(up[0].mapped), static_cast<double*>(up[1].mapped),
                               static_cast<uint32_t*>(up[2].mapped));
                Submission& s = *m.slots[0].sub;
                s.begin();
                s.copy(up[0], m.triNormals, nb);
                s.copy(up[1], m.vertexNormals, vb);
                s.copy(up[2], m.triVertices, ib);
                s.barrier();
                s.submit();
                s.wait();
            } catch (...) {
                for (Buffer& b : up) m.ctx->destroy(b);
                throw;
            }
            for (Buffer& b : up) m.ctx->destroy(b);
        }
        mStats.bytesUp += nb + vb + ib;
    } else {
        for (Buffer* b : {&m.triNormals, &m.vertexNormals, &m.triVertices}) m.ensure(*b, 4, Memory::Device, "a placeholder");
    }
    mStats.secondsCopy += detail::secondsSince(t);
}

LeafDistanceDevice::~LeafDistanceDevice() = default;

std::string LeafDistanceDevice::deviceName() const
{
    return mImpl->ctx->info().name + " (" + mImpl->ctx->info().type + ")";
}

uint64_t LeafDistanceDevice::slotBudget(uint64_t override) const
{
    const uint64_t b = override ? override : std::min<uint64_t>(mImpl->ctx->info().deviceLocalBytes / 4, uint64_t(512) << 20);
    return std::min<uint64_t>(b, mImpl->ctx->maxBufferRange());
}

void LeafDistanceDevice::start(int slot, const LeafBatch& b, double limit2)
{
    Impl& m = *mImpl;
    Impl::Slot& s = m.slots[slot];
    s.count = b.count();
    if (s.count == 0) return;
    const auto t = Clock::now();
    const VkDeviceSize lb = b.leaves.size() * sizeof(int32_t), cb = std::max<size_t>(b.cands.size(), 1) * sizeof(uint32_t);
    const VkDeviceSize tb = s.count * 512 * sizeof(uint32_t), db = s.count * 512 * sizeof(double);
    m.ctx->requireRange(std::max(cb, db), "a batch of leaves (one leaf's candidate triangles)");
    m.ensure(s.leaves, lb, Memory::Device, "a batch of leaves");
    m.ensure(s.cands, cb, Memory::Device, "a batch's candidate triangles");
    m.ensure(s.tri, tb, Memory::Device, "a batch's closest triangles");
    m.ensure(s.d2, db, Memory::Device, "a batch's distances");
    Submission& sub = *s.sub;
    sub.begin();
    if (m.ctx->unifiedMemory()) {
        std::memcpy(s.leaves.mapped, b.leaves.data(), lb);
        if (!b.cands.empty()) parallelCopy(s.cands.mapped, b.cands.data(), b.cands.size() * sizeof(uint32_t));
    } else {
        m.ensure(s.upLeaves, lb, Memory::Upload, "staging a batch of leaves");
        m.ensure(s.upCands, cb, Memory::Upload, "staging a batch's candidate triangles");
        m.ensure(s.downTri, tb, Memory::Readback, "reading back a batch's closest triangles");
        m.ensure(s.downD2, db, Memory::Readback, "reading back a batch's distances");
        std::memcpy(s.upLeaves.mapped, b.leaves.data(), lb);
        if (!b.cands.empty()) parallelCopy(s.upCands.mapped, b.cands.data(), b.cands.size() * sizeof(uint32_t));
        sub.copy(s.upLeaves, s.leaves, lb);
        sub.copy(s.upCands, s.cands, cb);
        sub.barrier();
    }
    mStats.secondsCopy += detail::secondsSince(t);
    const uint32_t maxX = std::min<uint32_t>(m.ctx->limits().maxComputeWorkGroupCount[0], 65535u);
    // candidate windows: one on a GPU; on a CPU device (lavapipe cuts loops after 65535
    // iterations per invocation) windows of 16384 candidates, one dispatch each
    uint32_t maxCount = 0;
    for (size_t j = 0; j < s.count; ++j) maxCount = std::max(maxCount, uint32_t(b.leaves[8 * j + 4]));
    const uint32_t window = m.ctx->info().type == "cpu" ? 16384u : std::max(maxCount, 1u);
    Push push{limit2, uint32_t(s.count), uint32_t(std::min<size_t>(s.count, maxX)), m.signs ? 1u : 0u, 0u, 0u, 0u};
    const uint32_t gy = uint32_t((s.count + push.groupsX - 1) / push.groupsX);
    for (uint32_t begin = 0; begin == 0 || begin < maxCount; begin += window) {
        push.candBegin = begin;
        push.candEnd = begin + window;
        push.last = push.candEnd >= maxCount ? 1u : 0u;
        sub.dispatch(m.kernel, {&m.corners, &s.leaves, &s.cands, &s.tri, &s.d2, &m.triNormals, &m.vertexNormals, &m.triVertices},
                     &push, push.groupsX, gy);
        sub.barrier();
    }
    if (!m.ctx->unifiedMemory()) {
        sub.copy(s.tri, s.downTri, tb);
        sub.copy(s.d2, s.downD2, db);
        sub.barrier();
    }
    sub.submit();
    ++mStats.batches;
    mStats.leaves += s.count;
    mStats.pairs += uint64_t(b.cands.size()) * 512;
    mStats.bytesUp += lb + b.cands.size() * sizeof(uint32_t);
    mStats.peakDeviceBytes = m.peak;
}

bool LeafDistanceDevice::finish(int slot, const std::function<bool()>& interrupted)
{
    Impl& m = *mImpl;
    Impl::Slot& s = m.slots[slot];
    if (s.count == 0) return true;
    const auto t = Clock::now();
    const bool done = s.sub->wait(interrupted);
    mStats.secondsWait += detail::secondsSince(t);
    if (!done) return false;
    const bool unified = m.ctx->unifiedMemory();
    m.ctx->invalidate(unified ? s.tri : s.downTri);
    m.ctx->invalidate(unified ? s.d2 : s.downD2);
    mStats.bytesDown += s.count * 512 * (sizeof(uint32_t) + sizeof(double));
    return true;
}

const uint32_t* LeafDistanceDevice::triangles(int slot) const
{
    const Impl::Slot& s = mImpl->slots[slot];
    return static_cast<const uint32_t*>(mImpl->ctx->unifiedMemory() ? s.tri.mapped : s.downTri.mapped);
}

const double* LeafDistanceDevice::distances(int slot) const
{
    const Impl::Slot& s = mImpl->slots[slot];
    return static_cast<const double*>(mImpl->ctx->unifiedMemory() ? s.d2.mapped : s.downD2.mapped);
}

} // namespace levelforge::gpu_internal
