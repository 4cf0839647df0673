// SPDX-License-Identifier: Apache-2.0
// Private: the main road's band leaves on a Vulkan device (shaders/leaf_distance.comp), with two
// submission slots so that the CPU prepares and finishes batches while the device computes.
// Declared whether or not the Vulkan backend is built; without it, construction throws
// DeviceError (ComputeDevice.cc).
#pragma once

#include <levelforge/gpu/VulkanDevices.h>

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace levelforge::gpu_internal {

/// One batch of leaves, prepared on the CPU.
struct LeafBatch
{
    std::vector<int32_t> leaves;     ///< 8 per leaf: origin x y z, first candidate, count, 0 0 0
    std::vector<uint32_t> cands;     ///< candidate triangles, ascending within each leaf
    std::vector<size_t> slots;       ///< caller's bookkeeping: which output leaf each entry fills
    size_t count() const { return leaves.size() / 8; }
    void clear() { leaves.clear(); cands.clear(); slots.clear(); }
};

/// What the device keeps for the whole conversion: the triangles' corners (cell space) and,
/// for pseudonormal signs, their normals. The fill functions write straight into the memory
/// that is uploaded (they may run in parallel inside).
struct LeafDeviceInput
{
    size_t triangles = 0, vertices = 0;
    /// corners: 9 doubles per triangle
    std::function<void(double* corners)> fillCorners;
    /// Optional (empty: no signs on the device): per triangle 12 doubles (face normal, then the
    /// edge normals of 01, 12, 20), per vertex 3 doubles, per triangle its 3 vertex indices.
    std::function<void(double* triangleNormals, double* vertexNormals, uint32_t* triangleVertices)> fillNormals;
};

/// Transfer and wait statistics of a LeafDistanceDevice.
struct LeafDeviceStats
{
    uint64_t batches = 0, leaves = 0, pairs = 0; ///< pairs: voxel–triangle evaluations on the device
    uint64_t bytesUp = 0, bytesDown = 0, peakDeviceBytes = 0;
    double secondsWait = 0.0;                    ///< the CPU waiting for the device
    double secondsCopy = 0.0;                    ///< the CPU writing staging memory (uploads)
};

class LeafDistanceDevice
{
public:
    /// Opens the device (the process's Vulkan context) and uploads `input`. Throws DeviceError.
    explicit LeafDistanceDevice(const LeafDeviceInput& input);
    ~LeafDistanceDevice();
    LeafDistanceDevice(const LeafDistanceDevice&) = delete;
    LeafDistanceDevice& operator=(const LeafDistanceDevice&) = delete;

    /// The device's name and type, e.g. "NVIDIA H200 (discrete)".
    std::string deviceName() const;
    /// Device-memory budget for one batch slot (bytes): a quarter of the device-local heap at
    /// most 512 MiB, or `override` when non-zero.
    uint64_t slotBudget(uint64_t override) const;
    /// Uploads batch `b` into slot `slot` (0 or 1) and starts it. The slot must be idle.
    void start(int slot, const LeafBatch& b, double limit2);
    /// Waits for slot `slot`. `interrupted` is polled while waiting; returns false when it asked
    /// to stop (results then unusable). Throws DeviceError when the device is lost.
    bool finish(int slot, const std::function<bool()>& interrupted);
    /// The finished slot's results, 512 per leaf, valid until the slot is started again: the
    /// closest triangle (~0u: none within the limit) and its squared distance (cells), negated
    /// where the pseudonormal says inside when the input had normals.
    const uint32_t* triangles(int slot) const;
    const double* distances(int slot) const;
    const LeafDeviceStats& stats() const { return mStats; }

private:
    struct Impl;
    std::unique_ptr<Impl> mImpl;
    LeafDeviceStats mStats;
};

} // namespace levelforge::gpu_internal
