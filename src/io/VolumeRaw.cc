// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Headerless (raw) volumes described by a RawVolumeLayout: readRaw().
#include "io/VolumeIOInternal.h"

#include <cmath>

namespace levelforge {

namespace volumeio_internal {

// ------------------------------------------------------------------------------------- raw

ScalarVolume readRawStream(InputFile& in, const RawVolumeLayout& layout, uint64_t maxVoxels, VolumeInfo& info)
{
    const std::string& path = in.path();
    for (int a = 0; a < 3; ++a) {
        if (layout.dims[a] <= 0) {
            throw InvalidArgumentError(path + ": raw layout dims " + formatCoord(layout.dims) + " must be > 0");
        }
        if (!(layout.spacing[a] > 0.0) || !std::isfinite(layout.spacing[a]) || !std::isfinite(layout.origin[a])) {
            throw InvalidArgumentError(path + ": raw layout spacing must be finite and > 0 and origin finite");
        }
    }
    info.format = "raw";
    info.sourceType = layout.type;
    info.bigEndian = layout.bigEndian;
    const int64_t dims[3] = {layout.dims.x(), layout.dims.y(), layout.dims.z()};
    const char* dimNames[3] = {"x", "y", "z"};
    const uint64_t count = checkDims(path, dims, maxVoxels, dimNames);
    // The layout against the file's size, before anything is allocated (a gzip file: bounded by
    // the deflate ratio, samples allocated as they arrive).
    const io_internal::FileCapacity capacity = io_internal::fileCapacity(path);
    const std::string problem = io_internal::declaredDataProblem(capacity, layout.headerBytes, "the raw layout",
                                                                 dims, typeBytes(layout.type));
    if (!problem.empty()) throwInvalid(path, "truncated voxel data: " + problem);
    ScalarVolume vol;
    if (capacity.gzip) vol.dims = layout.dims;
    else allocate(path, vol, dims, count);
    vol.spacing = layout.spacing;
    vol.origin = layout.origin;
    const uint64_t bytes = count * typeBytes(layout.type);
    if (in.skip(layout.headerBytes) < layout.headerBytes) {
        throwInvalid(path, "truncated: the file is shorter than the " + std::to_string(layout.headerBytes) +
                               "-byte header; expected " + std::to_string(layout.headerBytes + bytes) + " bytes");
    }
    readSamples(in, layout.type, layout.bigEndian, false, 1.0, 0.0, vol);
    info.compressed = in.compressed();
    if (const uint64_t extra = in.drain()) {
        throwInvalid(path, "size mismatch: expected " + std::to_string(layout.headerBytes + bytes) + " bytes (" +
                               std::to_string(layout.headerBytes) + "-byte header + " + formatCoord(layout.dims) +
                               " " + volumeValueTypeName(layout.type) + "), the " +
                               (in.compressed() ? "decompressed " : "") + "file has " +
                               std::to_string(layout.headerBytes + bytes + extra) + " (wrong dims or type?)");
    }
    finish(path, vol, info, "");
    return vol;
}

} // namespace volumeio_internal

// ================================================================================== public API

ScalarVolume readRaw(const std::string& path, const RawVolumeLayout& layout, uint64_t maxVoxels, VolumeInfo* info)
{
    VolumeInfo local;
    volumeio_internal::InputFile in(path);
    ScalarVolume vol = volumeio_internal::readRawStream(in, layout, maxVoxels, local);
    if (info) *info = std::move(local);
    return vol;
}

} // namespace levelforge
