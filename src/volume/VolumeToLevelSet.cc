// SPDX-License-Identifier: Apache-2.0
// Scalar volume to a signed distance level set (see include/levelforge/volume/VolumeToLevelSet.h).
#include <levelforge/volume/VolumeToLevelSet.h>

#include "detail/NumberFormat.h"
#include "detail/Timer.h"
#include "detail/VoxelBudget.h"

#include <levelforge/core/Exceptions.h>
#include <levelforge/reference/ExactReference.h>
#include <levelforge/volume/ChamferDistanceTransform.h>
#include <levelforge/volume/ExactDistanceTransform.h>
#include <levelforge/volume/VectorDistanceTransform.h>
#include <levelforge/volume/VolumeFeatures.h>

#include <openvdb/tools/Prune.h>

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <atomic>
#include <cmath>
#include <limits>
#include <sstream>

namespace levelforge {
namespace {

using detail::Clock;
using detail::secondsSince;

struct MethodName { VolumeDistanceMethod m; const char* name; };
constexpr MethodName kNames[] = {
    {VolumeDistanceMethod::CityBlock, "city-block"},
    {VolumeDistanceMethod::Chessboard, "chessboard"},
    {VolumeDistanceMethod::QuasiEuclidean3, "quasi-euclidean-3"},
    {VolumeDistanceMethod::Complete3, "complete-3"},
    {VolumeDistanceMethod::QuasiEuclidean5, "quasi-euclidean-5"},
    {VolumeDistanceMethod::EVDT, "evdt"},
    {VolumeDistanceMethod::EVDTFullGrid, "evdt-grid"},
    {VolumeDistanceMethod::VCVDT4, "vcvdt4"},
    {VolumeDistanceMethod::VCVDT8, "vcvdt8"},
    {VolumeDistanceMethod::Exact, "exact"},
};

bool isChamfer(VolumeDistanceMethod m) { return int(m) <= int(VolumeDistanceMethod::QuasiEuclidean5); }
VectorTransformMethod vectorMethod(VolumeDistanceMethod m)
{
    switch (m) {
    case VolumeDistanceMethod::EVDT: return VectorTransformMethod::EVDT;
    case VolumeDistanceMethod::EVDTFullGrid: return VectorTransformMethod::EVDTFullGrid;
    case VolumeDistanceMethod::VCVDT4: return VectorTransformMethod::VCVDT4;
    default: return VectorTransformMethod::VCVDT8;
    }
}
ChamferMetric chamferMetric(VolumeDistanceMethod m)
{
    switch (m) {
    case VolumeDistanceMethod::CityBlock: return ChamferMetric::CityBlock;
    case VolumeDistanceMethod::Chessboard: return ChamferMetric::Chessboard;
    case VolumeDistanceMethod::QuasiEuclidean3: return ChamferMetric::QuasiEuclidean3;
    case VolumeDistanceMethod::Complete3: return ChamferMetric::Complete3;
    default: return ChamferMetric::QuasiEuclidean5;
    }
}

void checkOptions(const ScalarVolume& f, const VolumeToLevelSetOptions& o)
{
    if (o.voxelSize != 0.0 || o.voxelCount != 0)
        throw InvalidArgumentError("volume to level set: the volume's spacing sets the voxel size; voxelSize and "
                                   "voxelCount must be 0, got voxelSize " + detail::formatDouble(o.voxelSize) +
                                   ", voxelCount " + std::to_string(o.voxelCount));
    if (f.empty()) throw InvalidArgumentError("volume to level set: the volume is empty");
    requireValidVolume(f, "volume to level set");
    detail::checkVoxelBudget({"volume to level set", "the dense volume", "one voxel per sample",
                              double(f.voxelCount()), 0.0, o.maxVoxels, "crop or resample the volume"});
    if (!std::isfinite(o.iso)) throw InvalidArgumentError("volume to level set: the iso-value must be finite");
    for (size_t i = 0; i < f.data.size(); ++i) {
        if (std::isnan(f.data[i])) {
            const size_t nx = size_t(f.dims.x()), ny = size_t(f.dims.y());
            std::ostringstream os;
            os << "volume to level set: sample (" << i % nx << ", " << (i / nx) % ny << ", " << i / (nx * ny)
               << ") is NaN";
            throw InvalidArgumentError(os.str());
        }
    }
    auto width = [&o](double w, const char* name) {
        if (!(w > 0.0) || !std::isfinite(w)) {
            std::ostringstream os;
            os << "volume to level set: " << name << " must be finite and > 0 ("
               << (o.units == WidthUnits::World ? "world units" : "voxels") << "), got " << w;
            throw InvalidArgumentError(os.str());
        }
    };
    width(o.exteriorWidth, "the exterior band width");
    if (!o.fillInterior) width(o.interiorWidth, "the interior band width");
    if (o.subvoxel && isChamfer(o.method))
        throw InvalidArgumentError(std::string("volume to level set: the chamfer transform '") +
                                   volumeDistanceMethodName(o.method) +
                                   "' propagates scalar distances from binary feature voxels; the sub-voxel "
                                   "shell needs a vector method (evdt, evdt-grid, vcvdt4, vcvdt8) or exact");
}

} // namespace

const char* volumeDistanceMethodName(VolumeDistanceMethod method)
{
    for (const auto& n : kNames)
        if (n.m == method) return n.name;
    return "unknown";
}

VolumeDistanceMethod volumeDistanceMethodFromName(const std::string& name)
{
    for (const auto& n : kNames)
        if (name == n.name) return n.m;
    std::string all;
    for (const auto& n : kNames) all += std::string(all.empty() ? "" : ", ") + n.name;
    throw InvalidArgumentError("unknown distance transform '" + name + "' (one of: " + all + ")");
}

ScalarVolume volumeSignedDistance(const ScalarVolume& field, const VolumeToLevelSetOptions& o,
                                  VolumeToLevelSetStats* statsOut)
{
    checkOptions(field, o);
    VolumeToLevelSetStats stats;
    if (o.device == ComputeDevice::Vulkan && (o.subvoxel || o.method != VolumeDistanceMethod::Exact))
        stats.deviceNote = std::string("device vulkan: only the exact transform of binary features (method exact "
                                       "without the sub-voxel shell) runs on a device; ") +
                           volumeDistanceMethodName(o.method) + (o.subvoxel ? " (sub-voxel)" : "") +
                           " ran on the CPU";
    auto t0 = Clock::now();
    ScalarVolume result;
    SubvoxelShellOptions so;
    so.iso = o.iso;
    so.insideBelow = o.insideBelow;
    so.interrupter = o.interrupter;
    if (o.subvoxel) {
        const MaskVolume inside = insideFlags(field, so);
        if (o.method == VolumeDistanceMethod::Exact) {
            // the exact distance to the triangulated surface, for every voxel (BVH)
            const TriangleMesh surface = isoSurfaceTriangles(field, so);
            if (surface.triangles.empty())
                throw InvalidArgumentError("volume to level set: no surface at iso-value " + std::to_string(o.iso));
            stats.shell.triangles = surface.triangles.size();
            stats.secondsClassify = secondsSince(t0);
            t0 = Clock::now();
            auto* interrupter = o.interrupter;
            if (interrupter) interrupter->start("volume to level set (exact)");
            const ExactReference ref(surface);
            result = ScalarVolume(field.dims, 0.0f, field.spacing, field.origin);
            const int nx = field.dims.x(), ny = field.dims.y(), nz = field.dims.z();
            // one BVH query per voxel: the interrupter is polled after every row
            std::atomic<bool> stop{false};
            std::atomic<int64_t> rowsDone{0};
            const double rows = double(ny) * double(nz);
            tbb::parallel_for(tbb::blocked_range<int>(0, nz), [&](const tbb::blocked_range<int>& r) {
                for (int k = r.begin(); k != r.end(); ++k)
                    for (int j = 0; j < ny; ++j) {
                        if (stop.load(std::memory_order_relaxed)) return;
                        for (int i = 0; i < nx; ++i) {
                            const double d = std::abs(ref.query(field.worldPosition(i, j, k)).distance);
                            result(i, j, k) = float(inside(i, j, k) ? -d : d);
                        }
                        const double done = double(rowsDone.fetch_add(1, std::memory_order_relaxed) + 1);
                        if (interrupter && interrupter->wasInterrupted(int(100.0 * done / rows))) stop = true;
                    }
            });
            if (stop) throw InterruptedError("interrupted while computing exact distances to the iso-surface");
            if (interrupter) interrupter->end();
            stats.secondsTransform = secondsSince(t0);
        } else {
            VectorVolume v = subvoxelShell(field, so, &stats.shell);
            if (stats.shell.shellVoxels == 0)
                throw InvalidArgumentError("volume to level set: no surface at iso-value " + std::to_string(o.iso));
            stats.secondsClassify = secondsSince(t0);
            t0 = Clock::now();
            VectorTransformOptions vo;
            vo.method = vectorMethod(o.method);
            vo.interrupter = o.interrupter;
            vectorDistanceTransform(v, vo);
            result = vectorLength(v);
            for (size_t i = 0; i < result.data.size(); ++i)
                if (inside.data[i]) result.data[i] = -result.data[i];
            stats.secondsTransform = secondsSince(t0);
        }
    } else {
        MaskVolume inside = insideFlags(field, so);
        const MaskVolume features = transverseFeatures(inside);
        for (uint8_t f : features.data) stats.featureVoxels += f ? 1 : 0;
        if (stats.featureVoxels == 0)
            throw InvalidArgumentError("volume to level set: no feature voxels at iso-value " + std::to_string(o.iso));
        const DenseVolume<int8_t> sign = classification(inside, features);
        stats.secondsClassify = secondsSince(t0);
        t0 = Clock::now();
        ScalarVolume unsignedField;
        if (o.method == VolumeDistanceMethod::Exact) {
            ExactTransformOptions eo;
            eo.interrupter = o.interrupter;
            eo.device = o.device;
            eo.deviceMemoryBudget = o.deviceMemoryBudget;
            ExactTransformStats es;
            unsignedField = exactDistanceTransform(features, eo, &es);
            stats.device = es.device;
            stats.deviceNote = es.deviceNote;
            stats.secondsDeviceTransfer = es.secondsTransfer;
            stats.secondsDeviceCompute = es.secondsCompute;
            stats.devicePeakBytes = es.peakDeviceBytes;
        } else if (isChamfer(o.method)) {
            ChamferOptions co;
            co.interrupter = o.interrupter;
            unsignedField = chamferDistanceTransform(features, chamferMetric(o.method), co);
        } else {
            VectorTransformOptions vo;
            vo.method = vectorMethod(o.method);
            vo.interrupter = o.interrupter;
            unsignedField = vectorDistanceTransform(features, vo); // no 16-byte vector volume
        }
        result = applySign(unsignedField, sign);
        stats.secondsTransform = secondsSince(t0);
    }
    if (statsOut) *statsOut = stats;
    return result;
}

openvdb::FloatGrid::Ptr denseToLevelSet(const ScalarVolume& d, double extW, double intW, bool fillInterior,
                                        const std::string& name)
{
    const float background = float(extW);
    auto tree = std::make_shared<openvdb::FloatTree>(background);
    const int nx = d.dims.x(), ny = d.dims.y(), nz = d.dims.z();
    // leaf-aligned z-slabs in parallel, each into its own tree, merged in a fixed order
    const int slabs = (nz + 7) / 8;
    std::vector<openvdb::FloatTree::Ptr> parts(static_cast<size_t>(slabs));
    tbb::parallel_for(tbb::blocked_range<int>(0, slabs), [&](const tbb::blocked_range<int>& r) {
        for (int s = r.begin(); s != r.end(); ++s) {
            auto part = std::make_shared<openvdb::FloatTree>(background);
            openvdb::tree::ValueAccessor<openvdb::FloatTree> acc(*part);
            for (int k = s * 8; k < std::min(nz, s * 8 + 8); ++k)
                for (int j = 0; j < ny; ++j)
                    for (int i = 0; i < nx; ++i) {
                        const float v = d(i, j, k);
                        if (!std::isfinite(v)) continue;
                        const bool keep = v < 0 ? (fillInterior || v > -intW) : v < extW;
                        if (keep) acc.setValueOn(openvdb::Coord(i, j, k), v);
                        else if (v < 0) acc.setValueOff(openvdb::Coord(i, j, k), -background);
                    }
            parts[size_t(s)] = part;
        }
    });
    for (auto& p : parts) tree->merge(*p);
    // every inside voxel beyond the band already holds -background (no flood fill needed, and
    // none that could guess wrong at the volume's edge); uniform inactive leaves become tiles
    openvdb::tools::prune(*tree);
    auto grid = openvdb::FloatGrid::create(tree);
    openvdb::math::Mat4d m = openvdb::math::Mat4d::identity();
    m.setToScale(d.spacing);
    m.setTranslation(d.origin);
    grid->setTransform(openvdb::math::Transform::createLinearTransform(m));
    grid->setGridClass(openvdb::GRID_LEVEL_SET);
    grid->setName(name);
    return grid;
}

openvdb::FloatGrid::Ptr volumeToLevelSet(const ScalarVolume& field, const VolumeToLevelSetOptions& o,
                                         VolumeToLevelSetStats* statsOut)
{
    VolumeToLevelSetStats stats;
    const ScalarVolume d = volumeSignedDistance(field, o, &stats);
    const auto t0 = Clock::now();
    const double hmin = std::min({field.spacing[0], field.spacing[1], field.spacing[2]});
    // widths in voxels of the smallest spacing, to world units
    auto grid = denseToLevelSet(d, o.widthInVoxels(o.exteriorWidth, hmin) * hmin,
                                o.widthInVoxels(o.interiorWidth, hmin) * hmin, o.fillInterior, o.gridName);
    stats.activeVoxels = grid->activeVoxelCount();
    stats.secondsBuild = secondsSince(t0);
    if (statsOut) *statsOut = stats;
    return grid;
}

} // namespace levelforge
