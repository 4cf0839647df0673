// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Exact dense Euclidean distance transform, a brute-force reference, and the accuracy
///        report of Satherley & Jones (Tables 1, 2, 4–6).
///
/// exactDistanceTransform(): P. F. Felzenszwalb and D. P. Huttenlocher, "Distance Transforms of
/// Sampled Functions", Theory of Computing 8 (2012): the squared Euclidean distance transform is
/// separable, D(p) = min_q |p - q|^2 = min over z of (sz^2 dz^2 + min over y of (sy^2 dy^2 +
/// min over x of (sx^2 dx^2 + f))), and each 1-D step is the lower envelope of parabolas, O(n)
/// per line. Anisotropic spacing enters as the parabola weight s^2 of each axis. Lines are
/// independent and run in parallel with TBB (results do not depend on the thread count).
/// The passes also run on a Vulkan device (ExactTransformOptions::device; the GPU twin is
/// src/gpu/shaders/edt_lines.comp, one invocation per line, the same double arithmetic without
/// fused multiply-add, the same float rounding between passes): bit-identical distances.
/// EXACT: the distance, in world units, from every voxel centre to the nearest feature voxel
/// centre, up to single-precision rounding (the envelope is evaluated in double precision, the
/// partial squared distances between axes are stored as float). This is the "true Euclidean
/// distance field" of the paper's tables for binary features; it is not the distance to a
/// sub-voxel surface.
///
/// bruteForceDistanceTransform(): the same quantity by testing every feature voxel (O(N·F),
/// double precision); for tests on small volumes.
///
/// compareDistanceFields() / distanceTransformReport(): the columns of the tables of
/// R. Satherley and M. W. Jones, "Vector-City Vector Distance Transform", Computer Vision and
/// Image Understanding 82 (2001): distance range of the computed field, error = computed - exact
/// per voxel (min, max), and the average error per voxel = sum |error| / number of voxels (all
/// voxels, as the paper divides by the dataset size). The report runs every chamfer and vector
/// transform on a signed inside mask (features = transverse voxels, Eq. 3; sign by Eq. 5–6,
/// VolumeFeatures.h) and times each one.
#pragma once

#include <levelforge/core/DenseVolume.h>
#include <levelforge/gpu/VulkanDevices.h>
#include <levelforge/volume/ChamferDistanceTransform.h>
#include <levelforge/volume/VectorDistanceTransform.h>
#include <levelforge/volume/VolumeFeatures.h>

#include <openvdb/util/NullInterrupter.h>

#include <cstdint>
#include <string>
#include <vector>

namespace levelforge {

/// Options of exactDistanceTransform().
struct ExactTransformOptions
{
    /// Optional interruption (checked between the three axis passes and per slab); not owned.
    openvdb::util::NullInterrupter* interrupter = nullptr;
    /// Where the transform runs (gpu/VulkanDevices.h). The distances are bit-identical on every
    /// device. Auto: a discrete Vulkan GPU (or the device LEVELFORGE_VULKAN_DEVICE picks) when
    /// the volume has at least deviceMinVoxels samples, else the CPU (stats.deviceNote says why);
    /// a device error under Auto falls back to the CPU.
    ComputeDevice device = ComputeDevice::Cpu;
    /// Device memory (bytes) the Vulkan transform may hold; 0: half the device's memory, at
    /// most 4 GiB. A volume larger than the budget is processed in slabs of z-slices (x and y
    /// passes) and of y-rows (z pass); at least one slice, row and line always go.
    uint64_t deviceMemoryBudget = 0;
    /// Auto: smaller volumes stay on the CPU (the transfers would cost more than they save).
    uint64_t deviceMinVoxels = uint64_t(1) << 24;
};

/// What exactDistanceTransform() did.
struct ExactTransformStats
{
    std::string device = "cpu";  ///< "cpu" or "vulkan: <name> (<type>)"
    std::string deviceNote;      ///< device auto: why the CPU was used (empty otherwise)
    uint64_t slabs = 0;          ///< device: slabs of z-slices plus slabs of y-rows
    uint64_t dispatches = 0;     ///< device: kernel dispatches (one per pass per batch of lines)
    uint64_t submissions = 0;    ///< device: command-buffer submissions (copies and kernels)
    uint64_t bytesUp = 0, bytesDown = 0; ///< device: host-to-device and device-to-host bytes
    uint64_t peakDeviceBytes = 0;        ///< device: device memory held at most
    double secondsTransfer = 0.0; ///< device: host copies into and out of device-visible memory and copy submissions
    double secondsCompute = 0.0;  ///< device: waiting for the kernels
};

/// @brief Exact Euclidean distance from every voxel centre to the nearest feature voxel centre,
///        in linear time, on the CPU or a Vulkan device.
/// @param[in]  features  feature voxels (mask != 0)
/// @param[in]  options   interrupter, device, device-memory budget
/// @param[out] stats     optional: the device used and its transfers and times
/// @return distances in world units (+inf everywhere when there is no feature); same dims,
///         spacing, origin. Bit-identical whichever device computed them.
/// @throws InvalidArgumentError (empty, spacing <= 0 or NaN, size mismatch);
/// @throws DeviceError (device Vulkan: no usable device, out of device memory, ...; Auto falls
///         back to the CPU instead);
/// @throws InterruptedError.
ScalarVolume exactDistanceTransform(const MaskVolume& features, const ExactTransformOptions& options = {},
                                    ExactTransformStats* stats = nullptr);

/// @brief The same distances by brute force over the feature voxels (O(N·F)); for small tests.
/// @param[in] features  feature voxels (mask != 0)
/// @return distances in world units (+inf everywhere when there is no feature); same dims,
///         spacing, origin.
/// @throws InvalidArgumentError (empty, bad spacing, size mismatch).
ScalarVolume bruteForceDistanceTransform(const MaskVolume& features);

/// One row of the paper's tables.
struct DistanceTransformComparison
{
    std::string method;
    double seconds = 0;                 ///< time of the transform (report only)
    float minDistance = 0, maxDistance = 0; ///< range of the computed field (world units)
    float minError = 0, maxError = 0;   ///< range of computed - exact (world units)
    double averageErrorPerVoxel = 0;    ///< sum |computed - exact| / voxel count
    uint64_t voxelsWithError = 0;       ///< voxels where computed != exact (|error| > 1e-5 · max(1,|exact|))
};

/// @brief Compares two fields voxel by voxel.
///
/// Voxels where both are the same infinity count as error 0; any other non-finite error makes
/// min/max/average infinite. Deterministic (fixed summation order).
/// @param[in] computed  the field under test
/// @param[in] exact     the reference, same dims
/// @return the table row (method empty, seconds 0).
/// @throws InvalidArgumentError if the dims or sizes differ or the volumes are empty.
DistanceTransformComparison compareDistanceFields(const ScalarVolume& computed, const ScalarVolume& exact);

/// Options of distanceTransformReport().
struct DistanceTransformReportOptions
{
    bool chamfer = true;       ///< the five chamfer metrics (Table 1)
    bool vector = true;        ///< EVDT, EVDT full grid, VCVDT4, VCVDT8 (Tables 2, 4–6)
    int repeats = 1;           ///< each transform is timed this many times; the fastest counts
    openvdb::util::NullInterrupter* interrupter = nullptr; ///< optional; not owned
};

/// @brief The accuracy report of the paper's tables for one object.
///
/// Signed fields of every transform for the object `inside` (features: transverseFeatures();
/// sign: classification(), Eq. 5–6), each compared with the signed exact EDT. The first row is
/// the exact EDT itself ("Euclidean", error 0). Methods are named as the paper's tables.
/// @param[in] inside   inside mask of the object
/// @param[in] options  which transforms, repeats, interrupter
/// @return one row per transform.
/// @throws InvalidArgumentError (invalid volume);
/// @throws InterruptedError.
std::vector<DistanceTransformComparison> distanceTransformReport(const MaskVolume& inside,
                                                                 const DistanceTransformReportOptions& options = {});

} // namespace levelforge
