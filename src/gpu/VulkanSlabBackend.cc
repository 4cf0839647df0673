// SPDX-License-Identifier: Apache-2.0
// T4 dense slabs on a Vulkan device. See gpu/VulkanSlabBackend.h.
#include <levelforge/gpu/VulkanSlabBackend.h>

#include "gpu/VulkanRuntime.h"
#include "detail/Timer.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <mutex>

namespace levelforge {
namespace gpu_internal {
extern const uint32_t kSpirv_slab_fill[];
extern const size_t kSpirv_slab_fillBytes;
} // namespace gpu_internal

using namespace gpu_internal;

namespace {
using detail::Clock;
struct Push
{
    double h;
    uint32_t groupCount;
    uint32_t groupsX;
    uint32_t itemBegin;
    uint32_t itemEnd;
};
static_assert(sizeof(Push) == 24, "push constants as the shader declares them");
constexpr uint32_t kGroup = 256;
constexpr uint64_t kItemBytes = 32 * sizeof(double) + 8 * sizeof(int32_t);
constexpr uint64_t kVoxelBytes = sizeof(uint32_t) + sizeof(double);
} // namespace

struct VulkanSlabBackend::Impl
{
    std::shared_ptr<Context> ctx;
    Kernel kernel;
    uint64_t budget = 0;
    std::mutex mutex;
    const SlabTriangles* cached = nullptr;
    size_t cachedTriangles = 0;
    double cachedVoxel = 0.0;
    Buffer corners, normals;
    // per batch: device buffers and their staging twins
    enum { XY, Info, Slabs, Ranges, Groups, Tri, D2, Raster, kCount };
    Buffer dev[kCount], stage[kCount];
    std::unique_ptr<Submission> sub;
    VulkanSlabStats stats;
    uint64_t deviceBytes = 0;
    // host arrays of one batch
    std::vector<double> xy;
    std::vector<int32_t> info, slabInfo;
    std::vector<uint32_t> ranges, groups;

    void ensure(Buffer& b, VkDeviceSize bytes, Memory where, const char* what)
    {
        if (b.buffer != VK_NULL_HANDLE && b.size >= bytes) return;
        if (b.buffer != VK_NULL_HANDLE) { deviceBytes -= b.size; ctx->destroy(b); }
        b = ctx->create(bytes + bytes / 4, where, what);
        deviceBytes += b.size;
        stats.peakDeviceBytes = std::max(stats.peakDeviceBytes, deviceBytes);
    }
    /// dev[k] holds `bytes` of `data` (staged unless unified)
    void put(int k, const void* data, size_t bytes, const char* what)
    {
        ensure(dev[k], std::max<size_t>(bytes, 4), Memory::Device, what);
        void* dst = dev[k].mapped;
        if (!ctx->unifiedMemory()) {
            ensure(stage[k], std::max<size_t>(bytes, 4), Memory::Upload, what);
            dst = stage[k].mapped;
            sub->copy(stage[k], dev[k], std::max<size_t>(bytes, 4));
        }
        if (bytes) std::memcpy(dst, data, bytes);
        stats.bytesUp += bytes;
    }
    void uploadTriangles(const SlabTriangles& tris)
    {
        const size_t nt = tris.corners.size() / 3;
        ctx->requireRange(nt * 21 * sizeof(double), "the triangles' normals");
        if (cached == &tris && cachedTriangles == nt && cachedVoxel == tris.voxelSize) return;
        std::vector<double> c(9 * nt), n(21 * nt);
        for (size_t i = 0; i < 3 * nt; ++i)
            for (int j = 0; j < 3; ++j) c[3 * i + size_t(j)] = tris.corners[i][j];
        for (size_t i = 0; i < 7 * nt; ++i)
            for (int j = 0; j < 3; ++j) n[3 * i + size_t(j)] = tris.normals[i][j];
        for (auto [buf, src, what] : {std::make_tuple(&corners, &c, "the triangles"), std::make_tuple(&normals, &n, "the normals")}) {
            const size_t bytes = std::max<size_t>(src->size() * sizeof(double), 4);
            ensure(*buf, bytes, Memory::Device, what);
            if (ctx->unifiedMemory()) {
                if (!src->empty()) std::memcpy(buf->mapped, src->data(), src->size() * sizeof(double));
            } else {
                Buffer up = ctx->create(bytes, Memory::Upload, what);
                if (!src->empty()) std::memcpy(up.mapped, src->data(), src->size() * sizeof(double));
                sub->begin();
                sub->copy(up, *buf, bytes);
                sub->barrier();
                sub->submit();
                try { sub->wait(); } catch (...) { ctx->destroy(up); throw; }
                ctx->destroy(up);
            }
            stats.bytesUp += bytes;
        }
        cached = &tris;
        cachedTriangles = nt;
        cachedVoxel = tris.voxelSize;
    }
    /// Fills jobs [b, e) in one dispatch.
    void run(const SlabJob* jobs, size_t b, size_t e, const SlabTriangles& tris)
    {
        constexpr double tol = 1e-7;
        xy.clear(); info.clear(); slabInfo.clear(); ranges.clear(); groups.clear();
        uint64_t voxels = 0;
        std::vector<uint32_t> order;
        for (size_t s = b; s < e; ++s) {
            const DenseSlab& slab = *jobs[s].slab;
            const openvdb::Coord lo = slab.box.min(), dim = slab.box.dim();
            slabInfo.insert(slabInfo.end(), {lo.x(), lo.y(), lo.z(), dim.x(), dim.y(), dim.z(), int32_t(ranges.size()), int32_t(voxels)});
            // items by plane (stable: the order within a plane does not matter, ties go by index)
            order.clear();
            for (uint32_t i = 0; i < jobs[s].count; ++i) {
                const CrossSection& cs = jobs[s].items[i];
                if (cs.count == 0 || cs.z < lo.z() || cs.z > slab.box.max().z()) continue;
                order.push_back(i);
            }
            std::stable_sort(order.begin(), order.end(), [&](uint32_t a, uint32_t c) { return jobs[s].items[a].z < jobs[s].items[c].z; });
            size_t k = 0;
            for (int z = lo.z(); z <= slab.box.max().z(); ++z) {
                const uint32_t first = uint32_t(info.size() / 8);
                for (; k < order.size() && jobs[s].items[order[k]].z == z; ++k) {
                    const CrossSection& cs = jobs[s].items[order[k]];
                    double ymin = cs.y[0], ymax = cs.y[0];
                    for (uint32_t i = 1; i < cs.count; ++i) { ymin = std::min(ymin, cs.y[i]); ymax = std::max(ymax, cs.y[i]); }
                    info.insert(info.end(), {int32_t(cs.triangle), cs.z, int32_t(cs.count), int(std::ceil(ymin - tol)),
                                             int(std::floor(ymax + tol)), 0, 0, 0});
                    xy.insert(xy.end(), cs.x.begin(), cs.x.end());
                    xy.insert(xy.end(), cs.y.begin(), cs.y.end());
                }
                ranges.push_back(first);
                ranges.push_back(uint32_t(info.size() / 8) - first);
            }
            const uint64_t vol = uint64_t(slab.size());
            for (uint64_t v = 0; v < vol; v += kGroup) groups.insert(groups.end(), {uint32_t(s - b), uint32_t(v)});
            voxels += vol;
        }
        stats.items += info.size() / 8;
        for (const uint64_t bytes : {uint64_t(xy.size() * sizeof(double)), uint64_t(voxels * sizeof(double))})
            ctx->requireRange(bytes, "a batch of slabs (one slab's cross-sections)");
        sub->begin();
        put(XY, xy.data(), xy.size() * sizeof(double), "the slabs' polygons");
        put(Info, info.data(), info.size() * sizeof(int32_t), "the slabs' items");
        put(Slabs, slabInfo.data(), slabInfo.size() * sizeof(int32_t), "the slabs");
        put(Ranges, ranges.data(), ranges.size() * sizeof(uint32_t), "the slabs' planes");
        put(Groups, groups.data(), groups.size() * sizeof(uint32_t), "the slabs' workgroups");
        const VkDeviceSize tb = std::max<VkDeviceSize>(voxels * sizeof(uint32_t), 4), db = std::max<VkDeviceSize>(voxels * sizeof(double), 4),
                           rb = (e - b) * sizeof(uint32_t);
        ensure(dev[Tri], tb, Memory::Device, "the slabs' triangles");
        ensure(dev[D2], db, Memory::Device, "the slabs' distances");
        ensure(dev[Raster], rb, Memory::Device, "the slabs' counters");
        if (!ctx->unifiedMemory()) {
            ensure(stage[Tri], tb, Memory::Readback, "reading back the slabs' triangles");
            ensure(stage[D2], db, Memory::Readback, "reading back the slabs' distances");
            ensure(stage[Raster], rb, Memory::Readback, "reading back the slabs' counters");
        }
        sub->zero(dev[Raster], rb);
        sub->barrier();
        const uint32_t count = uint32_t(groups.size() / 2);
        const uint32_t maxX = std::min<uint32_t>(ctx->limits().maxComputeWorkGroupCount[0], 65535u);
        // item windows: one on a GPU; on a CPU device (lavapipe cuts loops after 65535
        // iterations per invocation; an item costs up to 17) windows of 2048 items per plane
        uint32_t maxPlane = 0;
        for (size_t r = 1; r < ranges.size(); r += 2) maxPlane = std::max(maxPlane, ranges[r]);
        const uint32_t window = ctx->info().type == "cpu" ? 2048u : std::max(maxPlane, 1u);
        Push push{tris.voxelSize, count, std::min(count, maxX), 0u, 0u};
        for (uint32_t begin = 0; begin == 0 || begin < maxPlane; begin += window) {
            push.itemBegin = begin;
            push.itemEnd = begin + window;
            sub->dispatch(kernel,
                          {&corners, &normals, &dev[XY], &dev[Info], &dev[Slabs], &dev[Ranges], &dev[Groups], &dev[Tri], &dev[D2],
                           &dev[Raster]},
                          &push, push.groupsX, (count + push.groupsX - 1) / push.groupsX);
            sub->barrier();
        }
        if (!ctx->unifiedMemory()) {
            sub->copy(dev[Tri], stage[Tri], tb);
            sub->copy(dev[D2], stage[D2], db);
            sub->copy(dev[Raster], stage[Raster], rb);
            sub->barrier();
        }
        sub->submit();
        const auto t = Clock::now();
        sub->wait();
        stats.secondsWait += detail::secondsSince(t);
        const Buffer* out[3];
        for (int k : {Tri, D2, Raster}) {
            const Buffer& r = ctx->unifiedMemory() ? dev[k] : stage[k];
            ctx->invalidate(r);
            out[k - Tri] = &r;
        }
        const uint32_t* tri = static_cast<const uint32_t*>(out[0]->mapped);
        const double* d2 = static_cast<const double*>(out[1]->mapped);
        const uint32_t* raster = static_cast<const uint32_t*>(out[2]->mapped);
        tbb::parallel_for(tbb::blocked_range<size_t>(b, e, 1), [&](const tbb::blocked_range<size_t>& r) {
            for (size_t s = r.begin(); s != r.end(); ++s) {
                DenseSlab& slab = *jobs[s].slab;
                const size_t at = size_t(uint32_t(slabInfo[8 * (s - b) + 7]));
                for (size_t v = 0; v < slab.size(); ++v) {
                    const uint32_t t = tri[at + v];
                    if (t == DenseSlab::kNone) continue;
                    slab.tri[v] = t;
                    slab.dist[v] = std::sqrt(std::abs(d2[at + v])) * (std::signbit(d2[at + v]) ? -1.0 : 1.0);
                }
                slab.rasterized += raster[s - b];
            }
        });
        stats.bytesDown += tb + db + rb;
        ++stats.batches;
        stats.slabs += e - b;
    }
};

VulkanSlabBackend::VulkanSlabBackend(uint64_t memoryBudget) : mImpl(new Impl)
{
    Impl& m = *mImpl;
    m.ctx = Context::get();
    m.kernel = m.ctx->createKernel(kSpirv_slab_fill, kSpirv_slab_fillBytes, 10, sizeof(Push));
    m.sub.reset(new Submission(*m.ctx));
    m.budget = memoryBudget ? memoryBudget : std::min<uint64_t>(m.ctx->info().deviceLocalBytes / 4, uint64_t(512) << 20);
    m.budget = std::min<uint64_t>(m.budget, m.ctx->maxBufferRange());
}

VulkanSlabBackend::~VulkanSlabBackend()
{
    if (!mImpl || !mImpl->ctx) return;
    Impl& m = *mImpl;
    m.sub.reset();
    for (Buffer* b : {&m.corners, &m.normals})
        if (b->buffer != VK_NULL_HANDLE) m.ctx->destroy(*b);
    for (int k = 0; k < Impl::kCount; ++k) {
        if (m.dev[k].buffer != VK_NULL_HANDLE) m.ctx->destroy(m.dev[k]);
        if (m.stage[k].buffer != VK_NULL_HANDLE) m.ctx->destroy(m.stage[k]);
    }
    m.ctx->destroy(m.kernel);
}

std::string VulkanSlabBackend::deviceName() const { return mImpl->ctx->info().name + " (" + mImpl->ctx->info().type + ")"; }

VulkanSlabStats VulkanSlabBackend::stats() const
{
    std::lock_guard<std::mutex> lock(mImpl->mutex);
    return mImpl->stats;
}

void VulkanSlabBackend::fill(DenseSlab& slab, const CrossSection* items, size_t count, const SlabTriangles& tris) const
{
    const SlabJob job{&slab, items, count};
    fillBatch(&job, 1, tris);
}

void VulkanSlabBackend::fillBatch(const SlabJob* jobs, size_t n, const SlabTriangles& tris) const
{
    Impl& m = *mImpl;
    std::lock_guard<std::mutex> lock(m.mutex);
    m.uploadTriangles(tris);
    size_t b = 0;
    while (b < n) {
        uint64_t bytes = 0;
        size_t e = b;
        while (e < n) {
            const uint64_t need = uint64_t(jobs[e].slab->size()) * kVoxelBytes + uint64_t(jobs[e].count) * kItemBytes + 64;
            if (e > b && bytes + need > m.budget) break;
            bytes += need;
            ++e;
        }
        m.run(jobs, b, e, tris);
        b = e;
    }
}

} // namespace levelforge
