// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Fuzz target raw: readRaw() with a fuzzed RawVolumeLayout on fuzzed data, and
///        readVolume() of a ".raw" path with that layout.
///
/// The first kLayoutBytes bytes of the input are the layout (all little endian), the rest is the
/// file:
///   byte  0      sample type, VolumeValueType index (mod 10)
///   byte  1      bit 0: big-endian samples; bit 1: read through readVolume() instead of readRaw()
///   bytes 2..7   dims x, y, z (int16 each: zero and negative dims must be refused)
///   bytes 8..11  headerBytes (uint32)
///   bytes 12..15 spacing along x (float; NaN, 0 and negative must be refused), y = z = 1
/// The sample limit is kMaxFuzzVoxels. Inputs shorter than the layout are ignored.
#include "FuzzCommon.h"

namespace {

constexpr size_t kLayoutBytes = 16;

} // namespace

LF_FUZZ_TARGET(raw)
{
    using namespace levelforge;
    if (size < kLayoutBytes) return 0;
    RawVolumeLayout layout;
    layout.type = VolumeValueType(data[0] % 10);
    layout.bigEndian = (data[1] & 1) != 0;
    const bool viaReadVolume = (data[1] & 2) != 0;
    layout.dims = openvdb::Coord(fuzz::takeLE<int16_t>(data, size, 2), fuzz::takeLE<int16_t>(data, size, 4),
                                 fuzz::takeLE<int16_t>(data, size, 6));
    layout.headerBytes = fuzz::takeLE<uint32_t>(data, size, 8);
    float sx;
    const uint32_t sxBits = fuzz::takeLE<uint32_t>(data, size, 12);
    std::memcpy(&sx, &sxBits, sizeof(sx));
    layout.spacing = openvdb::Vec3d(double(sx), 1.0, 1.0);
    fuzz::TempFile file(data + kLayoutBytes, size - kLayoutBytes, ".raw");
    return fuzz::runGuarded([&] {
        VolumeInfo info;
        ScalarVolume vol;
        if (viaReadVolume) {
            ReadVolumeOptions options = fuzz::fuzzVolumeOptions();
            options.raw = layout;
            vol = readVolume(file.path(), options, &info);
        } else {
            vol = readRaw(file.path(), layout, fuzz::kMaxFuzzVoxels, &info);
        }
        fuzz::checkVolumePromises(vol, viaReadVolume ? "readVolume(raw)" : "readRaw");
        if (vol.dims != layout.dims) fuzz::finding("readRaw returned dims that differ from the layout's");
    });
}
