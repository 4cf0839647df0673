// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief The T4 scan conversion's dense slabs on a Vulkan device: the GPU twin of
///        CpuSlabBackend (scan/DenseSlab.h).
///
/// Erleben & Dohlmann's scan conversion (TetScanConversion.h) bins the cross-sections of the
/// tetrahedral shells into dense slabs; this backend fills a batch of slabs in one dispatch
/// (src/gpu/shaders/slab_fill.comp): one invocation per voxel, over the slab's items on the
/// voxel's plane (sorted by plane on the CPU). Coverage (the exact scanline span of the convex
/// polygon with the contract's 1e-7 voxel tolerance), the closest point, its feature and the
/// pseudonormal sign are computed in double precision, term for term as CpuSlabBackend, every
/// result `precise` (no fused multiply-add); ties go to the smaller triangle index; the square
/// root is taken on the CPU. So the slabs, and the grid, are bit-identical to the CPU backend's on
/// a device with IEEE double arithmetic (tested on lavapipe and an NVIDIA H200).
///
/// Use: `TetScanOptions::backend = &backend` (the pipeline does it for `--device vulkan`). The
/// constructor opens the device (DeviceError when there is none); batches are sized to the
/// device-memory budget, two in flight.
#pragma once

#include <levelforge/gpu/VulkanDevices.h>
#include <levelforge/scan/DenseSlab.h>

#include <memory>
#include <string>

namespace levelforge {

/// @brief Statistics of a VulkanSlabBackend (all calls so far).
struct VulkanSlabStats
{
    uint64_t batches = 0, slabs = 0, items = 0;
    uint64_t bytesUp = 0, bytesDown = 0, peakDeviceBytes = 0;
    double secondsWait = 0.0; ///< the CPU waiting for the device
};

/// @brief Fills dense slabs on the chosen Vulkan device (see the file comment).
class VulkanSlabBackend : public SlabBackend
{
public:
    /// @brief Opens the process's Vulkan device.
    /// @param[in] memoryBudget  device bytes per batch (0: a quarter of the device memory, at
    ///                          most 512 MiB); a slab larger than it is a batch of its own
    /// @throws DeviceError no Vulkan loader or usable device (64-bit floats)
    explicit VulkanSlabBackend(uint64_t memoryBudget = 0);
    ~VulkanSlabBackend() override;
    /// @brief "vulkan".
    const char* name() const override { return "vulkan"; }
    /// @brief One slab (a batch of one). Thread-safe (calls are serialised).
    void fill(DenseSlab& slab, const CrossSection* items, size_t count, const SlabTriangles& tris) const override;
    /// @brief A batch of slabs in as few dispatches as the budget allows. Thread-safe.
    void fillBatch(const SlabJob* jobs, size_t n, const SlabTriangles& tris) const override;
    /// @brief 1024: the scan conversion hands over a whole z-layer of slabs at a time.
    size_t preferredBatch() const override { return 1024; }
    /// @brief The device's name and type, e.g. "NVIDIA H200 (discrete)".
    std::string deviceName() const;
    /// @brief Counters so far.
    VulkanSlabStats stats() const;

private:
    struct Impl;
    std::unique_ptr<Impl> mImpl;
};

} // namespace levelforge
