// SPDX-License-Identifier: Apache-2.0
// Private: the main road's band leaves on a Vulkan device (shaders/leaf_distance.comp), with two
// submission slots so that the CPU prepares and finishes batches while the device computes.
// Declared whether or not the Vulkan backend is built; without it, construction throws
// DeviceError (ComputeDevice.cc).
#pragma once

#include <levelforge/gpu/VulkanDevices.h>

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
    std::vector<double> d2;          ///< out: 512 per leaf, squared distance (cells) of the closest
    std::vector<uint32_t> tri;       ///< out: 512 per leaf, its triangle (~0u: none within the limit)
    std::vector<size_t> slots;       ///< caller's bookkeeping: which output leaf each entry fills
    size_t count() const { return leaves.size() / 8; }
    void clear() { leaves.clear(); cands.clear(); slots.clear(); }
};

/// Transfer and wait statistics of a LeafDistanceDevice.
struct LeafDeviceStats
{
    uint64_t batches = 0, leaves = 0, pairs = 0; ///< pairs: voxel–triangle evaluations on the device
    uint64_t bytesUp = 0, bytesDown = 0, peakDeviceBytes = 0;
    double secondsWait = 0.0;                    ///< the CPU waiting for the device
    double secondsCopy = 0.0;                    ///< the CPU copying into and out of staging memory
};

class LeafDistanceDevice
{
public:
    /// Opens the device (the process's Vulkan context) and uploads the triangles' corners
    /// (cell space, 9 doubles per triangle). Throws DeviceError.
    explicit LeafDistanceDevice(const std::vector<double>& corners);
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
    /// Waits for slot `slot` and reads its results into b.d2 and b.tri. `interrupted` is polled
    /// while waiting; returns false when it asked to stop (results then unusable). Throws
    /// DeviceError when the device is lost.
    bool finish(int slot, LeafBatch& b, const std::function<bool()>& interrupted);
    const LeafDeviceStats& stats() const { return mStats; }

private:
    struct Impl;
    std::unique_ptr<Impl> mImpl;
    LeafDeviceStats mStats;
};

} // namespace levelforge::gpu_internal
