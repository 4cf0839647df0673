// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief VolPack / UNC .den density maps: readDen().
#include "io/VolumeIOInternal.h"

namespace levelforge {

namespace volumeio_internal {

// ------------------------------------------------------------------------------- VolPack .den

constexpr size_t kDenHeaderBytes = 62;

ScalarVolume readDenStream(InputFile& in, const ReadVolumeOptions& options, VolumeInfo& info)
{
    const std::string& path = in.path();
    unsigned char h[kDenHeaderBytes];
    const uint64_t got = in.read(h, sizeof(h));
    if (got < sizeof(h)) {
        throwInvalid(path, "not a .den file: " + std::to_string(got) + " bytes, shorter than the 62-byte header");
    }
    // Fields (int16 unless said): version, orig_min[3], orig_max[3], orig_len[3], extr_min[3],
    // extr_max[3], extr_len[3], map_min[3], map_max[3], map_len[3], map_warps, map_length (int32).
    bool big = false;
    if (getField<int16_t>(h, 0, false) == 1) big = false;
    else if (getField<int16_t>(h, 0, true) == 1) big = true;
    else {
        throwInvalid(path, "not a VolPack .den file: version field = " +
                               std::to_string(getField<int16_t>(h, 0, false)) + " (expected 1)");
    }
    info.format = "den";
    info.bigEndian = big;
    info.sourceType = VolumeValueType::UInt8;
    auto field3 = [&](size_t offset, int a) { return int64_t(getField<int16_t>(h, offset + 2 * size_t(a), big)); };
    int64_t dims[3];
    for (int a = 0; a < 3; ++a) dims[a] = field3(50, a); // map_len
    const char* dimNames[3] = {"map_len[0]", "map_len[1]", "map_len[2]"};
    for (int a = 0; a < 3; ++a) {
        if (dims[a] <= 0) {
            throwInvalid(path, std::string("bad dimension ") + dimNames[a] + " = " + std::to_string(dims[a]) +
                                   " (must be > 0)");
        }
    }
    const int64_t mapLength = getField<int32_t>(h, 58, big);
    if (mapLength != dims[0] * dims[1] * dims[2]) {
        throwInvalid(path, "map_length = " + std::to_string(mapLength) + " is not the product of map_len (" +
                               std::to_string(dims[0]) + "x" + std::to_string(dims[1]) + "x" +
                               std::to_string(dims[2]) + ")");
    }
    const uint64_t count = checkDims(path, dims, options.maxVoxels, dimNames);
    // The header's numbers against the file's size, before anything is allocated (a gzip
    // file: bounded by the deflate ratio, samples allocated as they arrive).
    const io_internal::FileCapacity capacity = io_internal::fileCapacity(path);
    const std::string problem = io_internal::declaredDataProblem(capacity, kDenHeaderBytes, "the header", dims, 1);
    if (!problem.empty()) throwInvalid(path, "truncated voxel data: " + problem);
    ScalarVolume vol;
    if (capacity.gzip) vol.dims = openvdb::Coord(int(dims[0]), int(dims[1]), int(dims[2]));
    else allocate(path, vol, dims, count);
    readSamples(in, VolumeValueType::UInt8, big, false, 1.0, 0.0, vol);
    info.compressed = in.compressed();
    if (const uint64_t extra = in.drain()) {
        throwInvalid(path, std::to_string(extra) + " bytes after the " + std::to_string(count) +
                               " samples the header announces (map_length)");
    }
    finish(path, vol, info, "");
    return vol;
}

} // namespace volumeio_internal

// ================================================================================== public API

ScalarVolume readDen(const std::string& path, const ReadVolumeOptions& options, VolumeInfo* info)
{
    VolumeInfo local;
    volumeio_internal::InputFile in(path);
    ScalarVolume vol = volumeio_internal::readDenStream(in, options, local);
    if (info) *info = std::move(local);
    return vol;
}

} // namespace levelforge
