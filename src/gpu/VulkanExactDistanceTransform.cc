// SPDX-License-Identifier: Apache-2.0
// The dense exact EDT on a Vulkan device. See VulkanExactDistanceTransform.h.
//
// Felzenszwalb & Huttenlocher's transform is separable: three passes of 1-D lower envelopes
// (x, y, z), each line independent. The x and y passes of a z-slice need only that slice, so
// they run on slabs of whole z-slices; the z pass needs whole z-columns, so it runs on slabs of
// y-rows, gathered on the host into a contiguous [k][row][i] block. When the feature bytes and
// the float distances of the whole volume fit half the budget, the volume stays on the device
// from the x pass to the z pass ([k][j][i] is then the z pass's slab layout with every row).
// The rest of the budget holds the envelopes' scratch: 16 bytes per sample of each line in flight.
//
// Testing aid: LEVELFORGE_VULKAN_EDT_PERTURB=1 makes the kernel start its divisions and square
// roots from values a few ulps (or 2^-30) off, so that the correction to the correctly rounded
// result (edt_lines.comp) is exercised on devices whose own division and sqrt are exact.
#include "gpu/VulkanExactDistanceTransform.h"
#include "gpu/VulkanRuntime.h"
#include "detail/Timer.h"
#include "volume/DenseVolumeHelpers.h"

#include <levelforge/core/Exceptions.h>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <memory>
#include <sstream>

namespace levelforge::gpu_internal {

extern const uint32_t kSpirv_edt_lines[];
extern const size_t kSpirv_edt_linesBytes;

namespace {

using detail::Clock;

/// The push constants of edt_lines.comp.
struct Push
{
    double s2;
    uint32_t n, lines, firstLine, linesA, strideA, strideB, step, mode;
};
static_assert(sizeof(Push) == 40, "push constants as the shader declares them");

constexpr uint32_t kGroup = 64;         // edt_lines.comp's local_size_x
constexpr uint32_t kMaxDispatches = 64; // per submission (one descriptor set each)
constexpr uint32_t kPerturb = 16;       // edt_lines.comp's test hook: division and sqrt start off

/// One pass over `lines` lines of `n` samples: line L starts at (L % linesA) * strideA +
/// (L / linesA) * strideB, its samples `step` apart.
struct Pass
{
    uint32_t n, lines, linesA, strideA, strideB, step, mode;
    double s2;
};

/// Scratch bytes of one line of n samples: sites (int), values (float), n + 1 breakpoints (double).
uint64_t scratchPerLine(uint64_t n) { return 8 * n + 8 * (n + 1); }

/// The device, the kernel, the buffers and the one submission slot of one transform.
struct DeviceEdt
{
    ExactTransformStats& stats;
    openvdb::util::NullInterrupter* interrupter;
    std::shared_ptr<Context> ctx;
    Kernel kernel;
    Buffer mask, field, sites, values, breaks; // device
    Buffer upMask, upField, down;              // staging (unused on unified memory)
    std::unique_ptr<Submission> sub;
    uint64_t deviceBytes = 0;
    uint64_t linesInFlight = 1;
    uint32_t modeFlags = 0; // kPerturb: the tests' hook (LEVELFORGE_VULKAN_EDT_PERTURB=1)
    int percent = 0;

    DeviceEdt(ExactTransformStats& s, openvdb::util::NullInterrupter* i) : stats(s), interrupter(i) {}
    DeviceEdt(const DeviceEdt&) = delete;
    DeviceEdt& operator=(const DeviceEdt&) = delete;
    ~DeviceEdt()
    {
        if (!ctx) return;
        sub.reset(); // waits for work in flight
        for (Buffer* b : {&mask, &field, &sites, &values, &breaks, &upMask, &upField, &down})
            if (b->buffer != VK_NULL_HANDLE) ctx->destroy(*b);
        ctx->destroy(kernel);
    }

    bool unified() const { return ctx->unifiedMemory(); }

    Buffer make(uint64_t bytes, Memory where, const char* what)
    {
        Buffer b = ctx->create(bytes, where, what);
        if (where == Memory::Device) {
            deviceBytes += b.size;
            stats.peakDeviceBytes = std::max(stats.peakDeviceBytes, deviceBytes);
        }
        return b;
    }

    bool interrupted() { return interrupter && interrupter->wasInterrupted(percent); }

    /// Submits what was recorded and waits, adding the wait to `seconds`.
    void submitAndWait(double& seconds)
    {
        sub->submit();
        ++stats.submissions;
        const auto t = Clock::now();
        const bool done = sub->wait([this] { return interrupted(); });
        seconds += detail::secondsSince(t);
        if (!done) throw InterruptedError("exact distance transform interrupted");
    }

    /// Where the host writes `dst`'s next contents: dst itself on unified memory, else staging.
    void* uploadTarget(const Buffer& dst, const Buffer& staging) const
    {
        return unified() ? dst.mapped : staging.mapped;
    }

    /// Makes the host's `bytes` written at uploadTarget() the contents of dst.
    void commitUpload(const Buffer& dst, const Buffer& staging, uint64_t bytes)
    {
        stats.bytesUp += bytes;
        if (unified()) return;
        sub->begin();
        sub->copy(staging, dst, bytes);
        sub->barrier();
        submitAndWait(stats.secondsTransfer);
    }

    /// The first `bytes` of the field buffer, readable by the host.
    const float* downloadField(uint64_t bytes)
    {
        stats.bytesDown += bytes;
        if (unified()) {
            ctx->invalidate(field);
            return static_cast<const float*>(field.mapped);
        }
        sub->begin();
        sub->copy(field, down, bytes);
        sub->barrier();
        submitAndWait(stats.secondsTransfer);
        ctx->invalidate(down);
        return static_cast<const float*>(down.mapped);
    }

    /// Every line of a pass, linesInFlight per dispatch (the scratch holds that many lines),
    /// kMaxDispatches dispatches per submission; the interrupter is polled between and during.
    void run(const Pass& p)
    {
        const uint32_t perDispatch = uint32_t(std::min<uint64_t>(linesInFlight, p.lines));
        uint32_t first = 0;
        while (first < p.lines) {
            if (interrupted()) throw InterruptedError("exact distance transform interrupted");
            sub->begin();
            for (uint32_t d = 0; d < kMaxDispatches && first < p.lines; ++d) {
                const uint32_t count = std::min(perDispatch, p.lines - first);
                const Push push{p.s2, p.n, count, first, p.linesA, p.strideA, p.strideB, p.step, p.mode | modeFlags};
                sub->dispatch(kernel, {&mask, &field, &sites, &values, &breaks}, &push, (count + kGroup - 1) / kGroup);
                sub->barrier(); // the next dispatch reuses the scratch (and reads these results)
                first += count;
                ++stats.dispatches;
            }
            submitAndWait(stats.secondsCompute);
        }
    }
};

/// `rows` floats from each of `count` blocks of src (`srcStride` apart) into dst (`dstStride`
/// apart), in parallel over the blocks.
void copyBlocks(float* dst, uint64_t dstStride, const float* src, uint64_t srcStride, uint64_t rows, uint64_t count)
{
    tbb::parallel_for(tbb::blocked_range<uint64_t>(0, count), [&](const tbb::blocked_range<uint64_t>& r) {
        for (uint64_t k = r.begin(); k != r.end(); ++k) std::memcpy(dst + k * dstStride, src + k * srcStride, 4 * rows);
    });
}

[[noreturn]] void tooLarge(const Context& ctx, const char* what, uint64_t bytes)
{
    std::ostringstream os;
    os << "Vulkan device '" << ctx.info().name << "': " << what << " (" << double(bytes) / 1048576.0
       << " MiB) exceeds the largest storage buffer (" << double(ctx.limits().maxStorageBufferRange) / 1048576.0
       << " MiB); use the CPU";
    throw DeviceError(os.str());
}

} // namespace

uint64_t edtDeviceBudget(uint64_t override)
{
    if (override) return override;
    const std::shared_ptr<Context> ctx = Context::get();
    return std::min<uint64_t>(ctx->info().deviceLocalBytes / 2, uint64_t(4) << 30);
}

ScalarVolume deviceExactDistanceTransform(const MaskVolume& features, uint64_t budget,
                                          openvdb::util::NullInterrupter* interrupter, ExactTransformStats& stats)
{
    const uint64_t nx = uint64_t(features.dims.x()), ny = uint64_t(features.dims.y()), nz = uint64_t(features.dims.z());
    const uint64_t nxy = nx * ny, voxels = nxy * nz;
    const double sx2 = features.spacing[0] * features.spacing[0];
    const double sy2 = features.spacing[1] * features.spacing[1];
    const double sz2 = features.spacing[2] * features.spacing[2];
    DeviceEdt e(stats, interrupter);
    e.ctx = Context::get();
    Context& ctx = *e.ctx;
    stats.device = "vulkan: " + ctx.info().name + " (" + ctx.info().type + ")";
    const uint64_t range = ctx.limits().maxStorageBufferRange;
    auto round4 = [](uint64_t b) { return (b + 3) / 4 * 4; };

    // slabs: the whole volume when features + distances fit half the budget, else z-slices for
    // the x and y passes and y-rows for the z pass, each slab within half the budget
    const uint64_t half = budget / 2;
    uint64_t dz = nz, dj = ny;
    const bool whole = round4(voxels) + 4 * voxels <= half && 4 * voxels <= range;
    if (!whole) {
        if (4 * nxy > range) tooLarge(ctx, "one z-slice of float distances", 4 * nxy);
        if (4 * nx * nz > range) tooLarge(ctx, "one y-row of float distances", 4 * nx * nz);
        dz = std::clamp<uint64_t>(half / (5 * nxy), 1, std::min(nz, range / (4 * nxy)));
        dj = std::clamp<uint64_t>(half / (4 * nx * nz), 1, std::min(ny, range / (4 * nx * nz)));
    }
    const uint64_t maskBytes = round4(dz * nxy), fieldBytes = 4 * std::max(dz * nxy, dj * nx * nz);
    const uint64_t nmax = std::max({nx, ny, nz});
    const uint64_t mostLines = std::max({ny * dz, nx * dz, nx * dj});
    const uint64_t used = maskBytes + fieldBytes;
    const uint64_t room = budget > used ? budget - used : 0;
    if (8 * (nmax + 1) > range) tooLarge(ctx, "the scratch of one line", 8 * (nmax + 1));
    e.linesInFlight = std::clamp<uint64_t>(room / scratchPerLine(nmax), 1,
                                           std::min<uint64_t>({mostLines, uint64_t(65535) * kGroup,
                                                               range / (8 * (nmax + 1))}));

    const char* perturb = std::getenv("LEVELFORGE_VULKAN_EDT_PERTURB");
    if (perturb && std::strcmp(perturb, "1") == 0) e.modeFlags = kPerturb;
    e.kernel = ctx.createKernel(kSpirv_edt_lines, kSpirv_edt_linesBytes, 5, sizeof(Push));
    e.sub.reset(new Submission(ctx, kMaxDispatches, kMaxDispatches * 5));
    e.mask = e.make(maskBytes, Memory::Device, "the feature voxels");
    e.field = e.make(fieldBytes, Memory::Device, "the squared distances");
    e.sites = e.make(4 * nmax * e.linesInFlight, Memory::Device, "the envelopes' sites");
    e.values = e.make(4 * nmax * e.linesInFlight, Memory::Device, "the envelopes' values");
    e.breaks = e.make(8 * (nmax + 1) * e.linesInFlight, Memory::Device, "the envelopes' breakpoints");
    if (!e.unified()) {
        e.upMask = e.make(maskBytes, Memory::Upload, "staging the feature voxels");
        if (!whole) e.upField = e.make(fieldBytes, Memory::Upload, "staging the squared distances");
        e.down = e.make(fieldBytes, Memory::Readback, "reading back the distances");
    }

    ScalarVolume out = volume_internal::like<float>(features, std::numeric_limits<float>::infinity());
    float* g = out.data.data();
    const auto u32 = [](uint64_t v) { return uint32_t(v); };

    // x and y passes, per slab of z-slices
    for (uint64_t k0 = 0; k0 < nz; k0 += dz) {
        const uint64_t kk = std::min(dz, nz - k0);
        e.percent = int(66 * k0 / nz);
        auto t = Clock::now();
        parallelCopy(e.uploadTarget(e.mask, e.upMask), features.data.data() + k0 * nxy, kk * nxy);
        stats.secondsTransfer += detail::secondsSince(t);
        e.commitUpload(e.mask, e.upMask, kk * nxy);
        e.run(Pass{u32(nx), u32(ny * kk), u32(ny), u32(nx), u32(nxy), 1, 0, sx2});
        e.percent = int(66 * k0 / nz + 33 * kk / nz);
        e.run(Pass{u32(ny), u32(nx * kk), u32(nx), 1, u32(nxy), u32(nx), 1, sy2});
        ++stats.slabs;
        if (whole) continue;
        const float* src = e.downloadField(4 * kk * nxy);
        t = Clock::now();
        parallelCopy(g + k0 * nxy, src, 4 * kk * nxy);
        stats.secondsTransfer += detail::secondsSince(t);
    }
    // z pass, per slab of y-rows: [k][row][i], rows `jj` apart along z
    for (uint64_t j0 = 0; j0 < ny; j0 += dj) {
        const uint64_t jj = std::min(dj, ny - j0), row = jj * nx;
        e.percent = int(66 + 34 * j0 / ny);
        if (!whole) {
            const auto t = Clock::now();
            float* dst = static_cast<float*>(e.uploadTarget(e.field, e.upField));
            copyBlocks(dst, row, g + j0 * nx, nxy, row, nz);
            stats.secondsTransfer += detail::secondsSince(t);
            e.commitUpload(e.field, e.upField, 4 * nz * row);
        }
        e.run(Pass{u32(nz), u32(row), u32(nx), 1, u32(nx), u32(row), 2, sz2});
        ++stats.slabs;
        const float* src = e.downloadField(4 * nz * row);
        const auto t = Clock::now();
        if (whole) parallelCopy(g, src, 4 * voxels);
        else copyBlocks(g + j0 * nx, nxy, src, row, row, nz);
        stats.secondsTransfer += detail::secondsSince(t);
    }
    return out;
}

} // namespace levelforge::gpu_internal
