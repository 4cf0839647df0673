// SPDX-License-Identifier: Apache-2.0
// levelforge — exact dense EDT (Felzenszwalb–Huttenlocher), brute force, and accuracy report.
// See include/levelforge/volume/ExactDistanceTransform.h.
#include "detail/Timer.h"
#include "volume/DenseVolumeHelpers.h"

#include <levelforge/volume/ExactDistanceTransform.h>

#include <levelforge/core/Exceptions.h>

#include "detail/LowerEnvelope.h"
#include "gpu/VulkanExactDistanceTransform.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <mutex>
#include <sstream>
#include <string>

namespace levelforge {

namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();
constexpr double kInfD = std::numeric_limits<double>::infinity();


/// Scratch for one 1-D lower envelope of n parabolas (detail::LowerEnvelope with the paper's
/// double-precision breakpoints at integer sites weighted by the squared spacing).
struct Envelope
{
    std::vector<double> f;
    detail::LowerEnvelope<double, double> env{-kInfD, kInfD};
    explicit Envelope(int n) : f(size_t(n)) { env.reset(size_t(n)); }

    /// out[p] = min_q s2 (p - q)^2 + f[q] for the n values in `f` (+inf = no sample).
    /// Returns false (out untouched) when every f is +inf.
    template<typename Out>
    bool run(int n, double s2, Out out)
    {
        env.reset(size_t(n));
        for (int q = 0; q < n; ++q) {
            const double fq = f[size_t(q)];
            if (!(fq < kInfD)) continue;
            const double hq = fq + s2 * double(q) * double(q);
            env.add(
                q, fq, [&](int a, double fa) { return (hq - (fa + s2 * double(a) * a)) / (2.0 * s2 * (q - a)); },
                [](double s, double z) { return s <= z; });
        }
        if (env.empty()) return false;
        env.evaluate(
            n, [](int p) { return double(p); }, [](double z, double t) { return z < t; },
            [&](int p, double, int a, double fa) {
                const double d = double(p - a);
                out(p, s2 * d * d + fa);
            });
        return true;
    }
};

/// Device Auto: a discrete Vulkan GPU (or the device LEVELFORGE_VULKAN_DEVICE picks) for a volume
/// of at least minVoxels samples; `note` says why not when a large volume stays on the CPU.
bool autoUsesDevice(uint64_t voxels, uint64_t minVoxels, std::string& note)
{
    if (voxels < minVoxels) return false; // small work: the CPU, no note
    std::string why;
    if (autoUsesVulkan(why)) return true;
    note = "device auto: " + why + "; the CPU was used";
    return false;
}

ScalarVolume cpuTransform(const MaskVolume& features, const ExactTransformOptions& options);

} // namespace

ScalarVolume exactDistanceTransform(const MaskVolume& features, const ExactTransformOptions& options,
                                    ExactTransformStats* statsOut)
{
    requireValidVolume(features, "exactDistanceTransform");
    ExactTransformStats stats;
    const bool device = options.device == ComputeDevice::Vulkan ||
                        (options.device == ComputeDevice::Auto &&
                         autoUsesDevice(features.voxelCount(), options.deviceMinVoxels, stats.deviceNote));
    if (device) {
        auto* interrupter = options.interrupter;
        if (interrupter) interrupter->start("exact distance transform");
        try {
            const uint64_t budget = gpu_internal::edtDeviceBudget(options.deviceMemoryBudget);
            ScalarVolume out = gpu_internal::deviceExactDistanceTransform(features, budget, interrupter, stats);
            if (interrupter) interrupter->end();
            if (statsOut) *statsOut = stats;
            return out;
        } catch (const DeviceError& e) {
            if (interrupter) interrupter->end();
            if (options.device == ComputeDevice::Vulkan) throw;
            stats = ExactTransformStats();
            stats.deviceNote = std::string("device auto: ") + e.what() + "; the CPU was used";
        } catch (...) {
            if (interrupter) interrupter->end();
            throw;
        }
    }
    ScalarVolume out = cpuTransform(features, options);
    if (statsOut) *statsOut = stats;
    return out;
}

namespace {

ScalarVolume cpuTransform(const MaskVolume& features, const ExactTransformOptions& options)
{
    const int nx = features.dims.x(), ny = features.dims.y(), nz = features.dims.z();
    const size_t nxy = size_t(nx) * size_t(ny);
    const double sx2 = features.spacing[0] * features.spacing[0];
    const double sy2 = features.spacing[1] * features.spacing[1];
    const double sz2 = features.spacing[2] * features.spacing[2];
    ScalarVolume out = volume_internal::like<float>(features, kInf);
    float* g = out.data.data();
    auto* interrupter = options.interrupter;
    std::atomic<bool> stop{false};
    auto interrupted = [&](int percent) {
        if (stop.load(std::memory_order_relaxed)) return true;
        if (interrupter && interrupter->wasInterrupted(percent)) stop = true;
        return stop.load(std::memory_order_relaxed);
    };
    auto finishPass = [&]() {
        if (stop) {
            if (interrupter) interrupter->end();
            throw InterruptedError("exact distance transform interrupted");
        }
    };
    if (interrupter) interrupter->start("exact distance transform");

    // x: squared distance along each row to the nearest feature of that row.
    tbb::parallel_for(tbb::blocked_range<int>(0, nz), [&](const tbb::blocked_range<int>& r) {
        Envelope e(nx);
        for (int k = r.begin(); k != r.end(); ++k) {
            if (interrupted(0)) return;
            for (int j = 0; j < ny; ++j) {
                const size_t base = size_t(k) * nxy + size_t(j) * size_t(nx);
                for (int i = 0; i < nx; ++i) e.f[size_t(i)] = features.data[base + size_t(i)] ? 0.0 : kInfD;
                e.run(nx, sx2, [&](int p, double d) { g[base + size_t(p)] = float(d); });
            }
        }
    });
    finishPass();
    // y: per slice, columns of stride nx.
    tbb::parallel_for(tbb::blocked_range<int>(0, nz), [&](const tbb::blocked_range<int>& r) {
        Envelope e(ny);
        for (int k = r.begin(); k != r.end(); ++k) {
            if (interrupted(33)) return;
            float* slice = g + size_t(k) * nxy;
            for (int i = 0; i < nx; ++i) {
                for (int j = 0; j < ny; ++j) e.f[size_t(j)] = slice[size_t(j) * size_t(nx) + size_t(i)];
                e.run(ny, sy2, [&](int p, double d) { slice[size_t(p) * size_t(nx) + size_t(i)] = float(d); });
            }
        }
    });
    finishPass();
    // z: per y, the nz x nx plane gathered row by row (cache friendly), then sqrt.
    tbb::parallel_for(tbb::blocked_range<int>(0, ny), [&](const tbb::blocked_range<int>& r) {
        Envelope e(nz);
        std::vector<float> plane(size_t(nz) * size_t(nx));
        for (int j = r.begin(); j != r.end(); ++j) {
            if (interrupted(66)) return;
            for (int k = 0; k < nz; ++k)
                std::copy_n(g + size_t(k) * nxy + size_t(j) * size_t(nx), nx, plane.data() + size_t(k) * size_t(nx));
            for (int i = 0; i < nx; ++i) {
                for (int k = 0; k < nz; ++k) e.f[size_t(k)] = plane[size_t(k) * size_t(nx) + size_t(i)];
                if (!e.run(nz, sz2, [&](int p, double d) { plane[size_t(p) * size_t(nx) + size_t(i)] = float(std::sqrt(d)); })) {
                    for (int k = 0; k < nz; ++k) plane[size_t(k) * size_t(nx) + size_t(i)] = kInf;
                }
            }
            for (int k = 0; k < nz; ++k)
                std::copy_n(plane.data() + size_t(k) * size_t(nx), nx, g + size_t(k) * nxy + size_t(j) * size_t(nx));
        }
    });
    finishPass();
    if (interrupter) interrupter->end();
    return out;
}

} // namespace

ScalarVolume bruteForceDistanceTransform(const MaskVolume& features)
{
    requireValidVolume(features, "bruteForceDistanceTransform");
    std::vector<openvdb::Vec3d> pts;
    for (int k = 0; k < features.dims.z(); ++k)
        for (int j = 0; j < features.dims.y(); ++j)
            for (int i = 0; i < features.dims.x(); ++i)
                if (features(i, j, k))
                    pts.emplace_back(i * features.spacing[0], j * features.spacing[1], k * features.spacing[2]);
    ScalarVolume out = volume_internal::like<float>(features, kInf);
    tbb::parallel_for(tbb::blocked_range<int>(0, features.dims.z()), [&](const tbb::blocked_range<int>& r) {
        for (int k = r.begin(); k != r.end(); ++k)
            for (int j = 0; j < features.dims.y(); ++j)
                for (int i = 0; i < features.dims.x(); ++i) {
                    const openvdb::Vec3d p(i * features.spacing[0], j * features.spacing[1], k * features.spacing[2]);
                    double best = kInfD;
                    for (const auto& q : pts) best = std::min(best, (p - q).lengthSqr());
                    out(i, j, k) = float(std::sqrt(best));
                }
    });
    return out;
}

DistanceTransformComparison compareDistanceFields(const ScalarVolume& computed, const ScalarVolume& exact)
{
    if (computed.dims != exact.dims || computed.data.size() != exact.data.size() || computed.data.empty()) {
        std::ostringstream ss;
        ss << "compareDistanceFields: volumes differ or are empty (" << computed.dims.x() << " x "
           << computed.dims.y() << " x " << computed.dims.z() << " vs " << exact.dims.x() << " x "
           << exact.dims.y() << " x " << exact.dims.z() << ")";
        throw InvalidArgumentError(ss.str());
    }
    const int nz = computed.dims.z();
    const size_t nxy = size_t(computed.dims.x()) * size_t(computed.dims.y());
    struct Partial
    {
        float minD = kInf, maxD = -kInf, minE = kInf, maxE = -kInf;
        double sum = 0;
        uint64_t wrong = 0;
    };
    std::vector<Partial> parts(static_cast<size_t>(nz));
    tbb::parallel_for(tbb::blocked_range<int>(0, nz), [&](const tbb::blocked_range<int>& r) {
        for (int k = r.begin(); k != r.end(); ++k) {
            Partial p;
            for (size_t i = size_t(k) * nxy, e = i + nxy; i != e; ++i) {
                const float c = computed.data[i], x = exact.data[i];
                p.minD = std::min(p.minD, c);
                p.maxD = std::max(p.maxD, c);
                double err = 0.0;
                if (!(c == x)) err = double(c) - double(x); // inf == inf gives 0
                if (std::isnan(err)) err = std::numeric_limits<double>::infinity();
                p.minE = std::min(p.minE, float(err));
                p.maxE = std::max(p.maxE, float(err));
                p.sum += std::abs(err);
                if (std::abs(err) > 1e-5 * std::max(1.0, std::abs(double(x)))) ++p.wrong;
            }
            parts[size_t(k)] = p;
        }
    });
    Partial t;
    for (const auto& p : parts) {
        t.minD = std::min(t.minD, p.minD);
        t.maxD = std::max(t.maxD, p.maxD);
        t.minE = std::min(t.minE, p.minE);
        t.maxE = std::max(t.maxE, p.maxE);
        t.sum += p.sum;
        t.wrong += p.wrong;
    }
    DistanceTransformComparison c;
    c.minDistance = t.minD;
    c.maxDistance = t.maxD;
    c.minError = t.minE;
    c.maxError = t.maxE;
    c.averageErrorPerVoxel = t.sum / double(computed.data.size());
    c.voxelsWithError = t.wrong;
    return c;
}

std::vector<DistanceTransformComparison> distanceTransformReport(const MaskVolume& inside,
                                                                 const DistanceTransformReportOptions& options)
{
    requireValidVolume(inside, "distanceTransformReport");
    const int repeats = std::max(1, options.repeats);
    const MaskVolume features = transverseFeatures(inside);
    const DenseVolume<int8_t> sign = classification(inside, features);

    auto timed = [&](const auto& f) {
        double best = std::numeric_limits<double>::infinity();
        ScalarVolume result;
        for (int r = 0; r < repeats; ++r) {
            const auto t0 = detail::Clock::now();
            result = f();
            best = std::min(best, detail::secondsSince(t0));
        }
        return std::make_pair(std::move(result), best);
    };

    ExactTransformOptions eo;
    eo.interrupter = options.interrupter;
    auto [exactU, exactSeconds] = timed([&] { return exactDistanceTransform(features, eo); });
    const ScalarVolume exact = applySign(exactU, sign);

    std::vector<DistanceTransformComparison> rows;
    auto add = [&](const std::string& name, const ScalarVolume& unsignedField, double seconds) {
        DistanceTransformComparison c = compareDistanceFields(applySign(unsignedField, sign), exact);
        c.method = name;
        c.seconds = seconds;
        rows.push_back(c);
    };
    add("Euclidean (exact EDT)", exactU, exactSeconds);
    if (options.chamfer) {
        ChamferOptions co;
        co.interrupter = options.interrupter;
        for (ChamferMetric m : {ChamferMetric::CityBlock, ChamferMetric::Chessboard, ChamferMetric::QuasiEuclidean3,
                                ChamferMetric::Complete3, ChamferMetric::QuasiEuclidean5}) {
            auto [d, s] = timed([&] { return chamferDistanceTransform(features, m, co); });
            add(chamferMetricName(m), d, s);
        }
    }
    if (options.vector) {
        for (VectorTransformMethod m : {VectorTransformMethod::EVDT, VectorTransformMethod::EVDTFullGrid,
                                        VectorTransformMethod::VCVDT4, VectorTransformMethod::VCVDT8}) {
            VectorTransformOptions vo;
            vo.method = m;
            vo.interrupter = options.interrupter;
            auto [d, s] = timed([&] { return vectorDistanceTransform(features, vo); });
            add(vectorTransformMethodName(m), d, s);
        }
    }
    return rows;
}

} // namespace levelforge
