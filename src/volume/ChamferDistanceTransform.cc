// SPDX-License-Identifier: Apache-2.0
// Dense chamfer distance transforms; see include/levelforge/volume/ChamferDistanceTransform.h.
#include <levelforge/volume/ChamferDistanceTransform.h>

#include "detail/Lanes.h"
#include "volume/ChamferDistanceTransformInternal.h"
#include "volume/DenseVolumeHelpers.h"

#include <levelforge/core/Exceptions.h>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <limits>

namespace levelforge {

namespace {

using volume_internal::like;

constexpr float kInf = std::numeric_limits<float>::infinity();

/// One direction's half of a chamfer mask.
struct HalfMask
{
    std::vector<chamfer_internal::Step> steps;
    std::vector<int64_t> offsets; ///< linear index offsets
    std::vector<float> weights;   ///< world units
    int radius = 1;
};

HalfMask halfMask(ChamferMetric metric, const openvdb::Vec3d& spacing, const openvdb::Coord& dims, bool forward)
{
    HalfMask h;
    const int64_t nx = dims.x(), nxy = int64_t(dims.x()) * dims.y();
    for (const auto& s : chamfer_internal::neighbourhood(metric)) {
        const bool before = s.z < 0 || (s.z == 0 && (s.y < 0 || (s.y == 0 && s.x < 0)));
        if (before != forward) continue;
        h.steps.push_back(s);
        h.offsets.push_back(int64_t(s.z) * nxy + int64_t(s.y) * nx + s.x);
        h.weights.push_back(float(chamfer_internal::stepWeight(metric, s, spacing)));
        h.radius = std::max({h.radius, std::abs(int(s.x)), std::abs(int(s.y)), std::abs(int(s.z))});
    }
    return h;
}

/// One pass on pass-order x indices [i0, i1) of row y, slice z.
void chamferSpan(float* D, const openvdb::Coord& dims, const HalfMask& h, int z, int y, int i0, int i1, bool forward)
{
    const int nx = dims.x(), ny = dims.y(), nz = dims.z(), r = h.radius;
    const size_t nk = h.steps.size();
    const bool rowInterior = y >= r && y + r < ny && z >= r && z + r < nz;
    const size_t rowBase = (size_t(z) * size_t(ny) + size_t(y)) * size_t(nx);
    for (int i = i0; i < i1; ++i) {
        const int x = forward ? i : nx - 1 - i;
        const size_t idx = rowBase + size_t(x);
        float best = D[idx];
        if (best == 0.0f) continue;
        if (rowInterior && x >= r && x + r < nx) {
            for (size_t k = 0; k < nk; ++k) best = std::min(best, D[int64_t(idx) + h.offsets[k]] + h.weights[k]);
        } else {
            for (size_t k = 0; k < nk; ++k) {
                const auto& s = h.steps[k];
                const int qx = x + s.x, qy = y + s.y, qz = z + s.z;
                if (qx < 0 || qy < 0 || qz < 0 || qx >= nx || qy >= ny || qz >= nz) continue;
                best = std::min(best, D[int64_t(idx) + h.offsets[k]] + h.weights[k]);
            }
        }
        D[idx] = best;
    }
}

} // namespace

const char* chamferMetricName(ChamferMetric metric)
{
    switch (metric) {
    case ChamferMetric::CityBlock: return "City-block";
    case ChamferMetric::Chessboard: return "Chess board";
    case ChamferMetric::QuasiEuclidean3: return "Quasi-Euclidean 3^3";
    case ChamferMetric::Complete3: return "Complete 3^3";
    case ChamferMetric::QuasiEuclidean5: return "Quasi-Euclidean 5^3";
    }
    return "unknown";
}

namespace chamfer_internal {

std::vector<Step> neighbourhood(ChamferMetric metric)
{
    std::vector<Step> out;
    for (int z = -2; z <= 2; ++z)
        for (int y = -2; y <= 2; ++y)
            for (int x = -2; x <= 2; ++x) {
                if (x == 0 && y == 0 && z == 0) continue;
                int a[3] = {std::abs(x), std::abs(y), std::abs(z)};
                std::sort(a, a + 3); // a[0] <= a[1] <= a[2]
                const int nonzero = (a[0] > 0) + (a[1] > 0) + (a[2] > 0);
                bool use = false;
                switch (metric) {
                case ChamferMetric::CityBlock: use = a[2] == 1 && nonzero == 1; break;
                case ChamferMetric::Chessboard:
                case ChamferMetric::QuasiEuclidean3: use = a[2] == 1 && nonzero <= 2; break;
                case ChamferMetric::Complete3: use = a[2] == 1; break;
                case ChamferMetric::QuasiEuclidean5:
                    use = a[2] == 1 || (a[2] == 2 && a[1] == 1 && a[0] <= 1) || (a[2] == 2 && a[1] == 2 && a[0] == 1);
                    break;
                }
                if (use) out.push_back(Step{int8_t(x), int8_t(y), int8_t(z)});
            }
    return out;
}

double stepWeight(ChamferMetric metric, const Step& s, const openvdb::Vec3d& spacing)
{
    const double wx = s.x * spacing[0], wy = s.y * spacing[1], wz = s.z * spacing[2];
    if (metric == ChamferMetric::Chessboard) {
        double w = 0;
        if (s.x) w = std::max(w, spacing[0]);
        if (s.y) w = std::max(w, spacing[1]);
        if (s.z) w = std::max(w, spacing[2]);
        return w;
    }
    return std::sqrt(wx * wx + wy * wy + wz * wz);
}

} // namespace chamfer_internal

ScalarVolume chamferDistanceTransform(const MaskVolume& features, ChamferMetric metric, const ChamferOptions& options)
{
    requireValidVolume(features, "chamferDistanceTransform");
    ScalarVolume D = like<float>(features);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, D.data.size(), 1 << 16), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t i = r.begin(); i != r.end(); ++i) D.data[i] = features.data[i] ? 0.0f : kInf;
    });
    const openvdb::Coord dims = features.dims;
    const HalfMask fwd = halfMask(metric, features.spacing, dims, true);
    const HalfMask bwd = halfMask(metric, features.spacing, dims, false);
    const int nx = dims.x(), ny = dims.y(), nz = dims.z();
    const int lanes = detail::laneCountFor(nx, ny, options.threads);
    const int chunks = detail::wavefrontChunks(nx, lanes);
    float* d = D.data.data();
    auto work = [&](int s, int r, int c) {
        const bool forward = s < nz;
        const int z = forward ? s : 2 * nz - 1 - s;
        const int y = forward ? r : ny - 1 - r;
        const int i0 = int((int64_t(c) * nx) / chunks), i1 = int((int64_t(c + 1) * nx) / chunks);
        chamferSpan(d, dims, forward ? fwd : bwd, z, y, i0, i1, forward);
    };
    auto* interrupter = options.interrupter;
    if (interrupter) interrupter->start("chamfer distance transform");
    auto begin = [&](int s) { return !interrupter || !interrupter->wasInterrupted(int((50.0 * s) / nz)); };
    // lookahead 1 chunk: rows above read x + radius (radius <= 2 <= chunk width).
    if (!detail::runRowWavefront(2 * nz, ny, chunks, 1, lanes, work, begin)) {
        if (interrupter) interrupter->end();
        throw InterruptedError("chamfer distance transform interrupted");
    }
    if (interrupter) interrupter->end();
    return D;
}

} // namespace levelforge
