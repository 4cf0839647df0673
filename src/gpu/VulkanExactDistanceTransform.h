// SPDX-License-Identifier: Apache-2.0
// Private: the dense exact EDT (exactDistanceTransform(), ExactDistanceTransform.h) on a Vulkan
// device, shaders/edt_lines.comp: the x and y passes on slabs of z-slices, the z pass on slabs of
// y-rows (or the whole volume resident on the device when it fits the budget). Declared whether
// or not the Vulkan backend is built; without it, the call throws DeviceError (ComputeDevice.cc).
#pragma once

#include <levelforge/core/DenseVolume.h>
#include <levelforge/gpu/VulkanDevices.h>
#include <levelforge/volume/ExactDistanceTransform.h>

#include <openvdb/util/NullInterrupter.h>

#include <cstdint>

namespace levelforge::gpu_internal {

/// @brief Device-memory budget of the device EDT (bytes): half the device-local heap, at most
///        4 GiB, or `override` when non-zero. Throws DeviceError when there is no device.
uint64_t edtDeviceBudget(uint64_t override);

/// @brief exactDistanceTransform() of `features` on the process's Vulkan device, bit-identical
///        to the CPU's.
///
/// Device memory (storage buffers: the feature bytes and float distances of a slab, and the
/// envelopes' scratch of the lines in flight) stays within `budget` bytes (edtDeviceBudget()),
/// except that at least one z-slice, one y-row and one line always go (a tiny budget means many
/// slabs, not an error). Fills stats.device, slabs, dispatches, bytes and seconds. The
/// interrupter is polled while waiting for the device (start()/end() are the caller's).
/// @throws DeviceError (no device, out of device memory, a slice larger than a storage buffer);
/// @throws InterruptedError.
ScalarVolume deviceExactDistanceTransform(const MaskVolume& features, uint64_t budget,
                                          openvdb::util::NullInterrupter* interrupter, ExactTransformStats& stats);

} // namespace levelforge::gpu_internal
