// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Helpers shared by the mesh and the volume readers and writers: host byte order,
///        byte swapping, lower-cased file names and extensions, and the check of a header's
///        declared data size against what the file can hold (before anything is allocated).
#pragma once

#include "detail/MessageText.h"

#include <algorithm>
#include <cctype>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <system_error>
#include <type_traits>

namespace levelforge::io_internal {

/// True on a big-endian host (file formats state their own byte order).
constexpr bool kHostBigEndian = (__BYTE_ORDER__ == __ORDER_BIG_ENDIAN__);

/// @p v with its bytes in reverse order.
template<typename T>
T byteSwapped(T v)
{
    static_assert(std::is_trivially_copyable<T>::value, "");
    unsigned char b[sizeof(T)];
    std::memcpy(b, &v, sizeof(T));
    std::reverse(b, b + sizeof(T));
    std::memcpy(&v, b, sizeof(T));
    return v;
}

/// @p s with ASCII letters in lower case.
inline std::string asciiLower(std::string s)
{
    for (char& c : s) c = char(std::tolower(static_cast<unsigned char>(c)));
    return s;
}

/// File name of @p path (no directory), lower case: "Brain.NII.GZ" -> "brain.nii.gz".
inline std::string lowerFileName(const std::string& path)
{
    return asciiLower(std::filesystem::path(path).filename().string());
}

/// Last extension of @p path with its dot, lower case: "a/Box.OBJ" -> ".obj"; "" when none.
inline std::string lowerExtension(const std::string& path)
{
    return asciiLower(std::filesystem::path(path).extension().string());
}

/// True when @p s ends with @p suffix.
inline bool endsWith(const std::string& s, const std::string& suffix)
{
    return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

/// Largest ratio of decompressed to compressed size that deflate (gzip) can reach: a 258-byte
/// match costs at least 2 bits (RFC 1951), so no gzip file of N bytes decompresses to more
/// than about 1032 * N bytes (concatenated members only add headers).
constexpr uint64_t kMaxDeflateRatio = 1032;

/// What a file can deliver, found without reading it: its size on disk and whether it starts
/// with the gzip magic bytes (zlib then decompresses it as it is read).
struct FileCapacity
{
    uint64_t fileBytes = 0; ///< size on disk
    bool gzip = false;      ///< starts with 0x1f 0x8b
    /// Most bytes the (decompressed) stream can hold: the file size for a plain file, the
    /// deflate bound (kMaxDeflateRatio times the size, plus a little) for gzip.
    uint64_t maxStreamBytes() const
    {
        if (!gzip) return fileBytes;
        uint64_t bound = 0;
        if (__builtin_mul_overflow(fileBytes, kMaxDeflateRatio, &bound) ||
            __builtin_add_overflow(bound, uint64_t(4096), &bound)) {
            return UINT64_MAX;
        }
        return bound;
    }
};

/// Size and gzip-ness of @p path; a file that cannot be measured gives {0, false} (the reader
/// that opens it reports the error).
inline FileCapacity fileCapacity(const std::string& path)
{
    FileCapacity cap;
    std::error_code ec;
    const auto size = std::filesystem::file_size(path, ec);
    if (ec) return cap;
    cap.fileBytes = uint64_t(size);
    std::ifstream in(path, std::ios::binary);
    unsigned char magic[2] = {0, 0};
    if (in.read(reinterpret_cast<char*>(magic), 2)) cap.gzip = magic[0] == 0x1f && magic[1] == 0x8b;
    return cap;
}

/// Checks, before anything is allocated, that a file can hold the samples a header (or a raw
/// layout: @p source names which) declares: @p dims samples of @p sampleBytes bytes each,
/// starting @p offset bytes into the (decompressed) stream. A plain file must hold them all;
/// a gzip file must be large enough to decompress to them (kMaxDeflateRatio). The product of
/// the dimensions and bytes is computed without overflow (an overflow is reported too).
/// @return "" when the data can be there; else the reason, without the file name:
///   "the header claims 181x217x181 voxels of 1 byte (7.1 MB) after a 352-byte header, but the
///    file holds only 2,634 bytes of data"
inline std::string declaredDataProblem(const FileCapacity& cap, uint64_t offset, const char* source,
                                       const int64_t dims[3], uint64_t sampleBytes)
{
    using message_internal::byteSize;
    using message_internal::groupedCount;
    const std::string shape = std::to_string(dims[0]) + "x" + std::to_string(dims[1]) + "x" + std::to_string(dims[2]);
    const std::string claim = std::string(source) + " claims " + shape + " voxels of " +
                              (sampleBytes == 1 ? std::string("1 byte") : std::to_string(sampleBytes) + " bytes");
    uint64_t bytes = 0;
    if (dims[0] < 0 || dims[1] < 0 || dims[2] < 0 ||
        __builtin_mul_overflow(uint64_t(dims[0]), uint64_t(dims[1]), &bytes) ||
        __builtin_mul_overflow(bytes, uint64_t(dims[2]), &bytes) ||
        __builtin_mul_overflow(bytes, sampleBytes, &bytes)) {
        return claim + ": more bytes than 64 bits can count";
    }
    const std::string after = offset ? " after a " + groupedCount(offset) + "-byte header" : std::string();
    const uint64_t capacity = cap.maxStreamBytes();
    const uint64_t left = capacity > offset ? capacity - offset : 0;
    if (bytes <= left) return {};
    if (cap.gzip) {
        return claim + " (" + byteSize(bytes) + ")" + after + ", but a gzip file of " + groupedCount(cap.fileBytes) +
               " bytes decompresses to at most " + byteSize(capacity);
    }
    return claim + " (" + byteSize(bytes) + ")" + after + ", but the file holds only " + groupedCount(left) +
           (left == 1 ? " byte" : " bytes") + " of data";
}

} // namespace levelforge::io_internal
