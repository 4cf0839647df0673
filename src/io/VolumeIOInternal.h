// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Private to src/io/Volume*.cc: the gzip-aware input stream, header field access,
///        sample conversion and checks every volume format shares, the format choice and the
///        atomic writer of the NIfTI-1 and INRIMAGE-4 writers. See VolumeIO.h and
///        docs/volumes.md.
#pragma once

#include <levelforge/io/VolumeIO.h>

#include "detail/MessageText.h"
#include "detail/NumberFormat.h"
#include "io/IoCommon.h"

#include <openvdb/openvdb.h>

#include <zlib.h>

#include <algorithm>
#include <cerrno>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <functional>
#include <string>
#include <system_error>
#include <vector>

#include <fcntl.h>
#include <unistd.h>

namespace levelforge {

namespace volumeio_internal {

namespace fs = std::filesystem;

using detail::formatDouble;
using io_internal::byteSwapped;
using io_internal::endsWith;
using io_internal::kHostBigEndian;
using io_internal::lowerFileName;

// ------------------------------------------------------------------------------------ helpers

/// "NXxNYxNZ".
std::string formatCoord(const openvdb::Coord& c);

/// Throws InvalidVolumeError "<path>: <what>".
[[noreturn]] void throwInvalid(const std::string& path, const std::string& what);

/// Reads a T at @a offset of @a buf, stored with the given byte order.
template<typename T>
T getField(const unsigned char* buf, size_t offset, bool bigEndian)
{
    T v;
    std::memcpy(&v, buf + offset, sizeof(T));
    return bigEndian != kHostBigEndian ? byteSwapped(v) : v;
}

/// Stores a T at @a offset of @a buf, little endian.
template<typename T>
void putLE(unsigned char* buf, size_t offset, T v)
{
    if (kHostBigEndian) v = byteSwapped(v);
    std::memcpy(buf + offset, &v, sizeof(T));
}

// ------------------------------------------------------------------------------ input stream

/// A file read through zlib: gzip-compressed or plain (zlib reads plain files as they are).
/// Every error names the file.
class InputFile
{
public:
    explicit InputFile(const std::string& path) : mPath(path)
    {
        std::error_code ec;
        if (!fs::exists(path, ec)) throw IoError("cannot read '" + path + "': no such file");
        if (!fs::is_regular_file(path, ec)) throw IoError("cannot read '" + path + "': not a regular file");
        const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
        if (fd < 0) throw IoError("cannot read '" + path + "': " + std::strerror(errno));
        mFile = gzdopen(fd, "rb");
        if (!mFile) {
            ::close(fd);
            throw IoError("cannot read '" + path + "': out of memory opening the file");
        }
        gzbuffer(mFile, 1u << 17);
    }
    ~InputFile()
    {
        if (mFile) gzclose_r(mFile);
    }
    InputFile(const InputFile&) = delete;
    InputFile& operator=(const InputFile&) = delete;

    const std::string& path() const { return mPath; }

    /// Reads up to @a n bytes; fewer only at the end of the data. Throws IoError when the gzip
    /// stream is corrupt or truncated.
    uint64_t read(void* dst, uint64_t n)
    {
        unsigned char* out = static_cast<unsigned char*>(dst);
        uint64_t done = 0;
        while (done < n) {
            const unsigned chunk = unsigned(std::min<uint64_t>(n - done, uint64_t(1) << 30));
            const int got = gzread(mFile, out + done, chunk);
            if (got < 0) throwGzError();
            done += uint64_t(got);
            if (unsigned(got) < chunk) {
                int err = Z_OK;
                gzerror(mFile, &err);
                if (err != Z_OK) throwGzError();
                break;
            }
        }
        mPosition += done;
        if (!mCompressionKnown) {
            mCompressed = gzdirect(mFile) == 0;
            mCompressionKnown = true;
        }
        return done;
    }

    /// Skips @a n bytes; returns how many could be skipped.
    uint64_t skip(uint64_t n)
    {
        std::vector<unsigned char> scratch(std::min<uint64_t>(n, 1u << 16));
        uint64_t done = 0;
        while (done < n) {
            const uint64_t want = std::min<uint64_t>(n - done, scratch.size());
            const uint64_t got = read(scratch.data(), want);
            done += got;
            if (got < want) break;
        }
        return done;
    }

    /// Reads to the end (which checks the gzip CRC); returns the number of bytes that were left.
    uint64_t drain()
    {
        std::vector<unsigned char> scratch(1u << 16);
        uint64_t left = 0;
        for (;;) {
            const uint64_t got = read(scratch.data(), scratch.size());
            left += got;
            if (got < scratch.size()) return left;
        }
    }

    bool compressed() const { return mCompressed; }
    uint64_t position() const { return mPosition; }

private:
    [[noreturn]] void throwGzError()
    {
        int err = Z_OK;
        const char* msg = gzerror(mFile, &err);
        throw IoError("cannot read '" + mPath + "': corrupt or truncated gzip data near decompressed offset " +
                      std::to_string(mPosition) + " (zlib: " + (msg && *msg ? msg : "unknown error") + ")");
    }

    std::string mPath;
    gzFile mFile = nullptr;
    uint64_t mPosition = 0;
    bool mCompressed = false;
    bool mCompressionKnown = false;
};

// --------------------------------------------------------------------------- type handling

/// Bytes per sample of @a t (volumeValueTypeBytes()).
size_t typeBytes(VolumeValueType t);

/// Checks that @a dims are positive and their product is within @a maxVoxels; returns it.
uint64_t checkDims(const std::string& path, const int64_t dims[3], uint64_t maxVoxels, const char* names[3]);

/// Allocates @a vol for @a dims, turning allocation failure into ResourceLimitError.
void allocate(const std::string& path, ScalarVolume& vol, const int64_t dims[3], uint64_t count);

/// Reads vol.voxelCount() samples of @a type from @a in into vol.data (converted, optionally
/// scaled). Processes the file in chunks so no second full-size buffer is needed.
void readSamples(InputFile& in, VolumeValueType type, bool bigEndian, bool scale, double slope,
                 double inter, ScalarVolume& vol);

/// Checks every sample is finite and fills minValue / maxValue.
void finish(const std::string& path, const ScalarVolume& vol, VolumeInfo& info, const std::string& context);

// ------------------------------------------------------------------------------ the formats

/// Bytes of a NIfTI-1 header (also what formatFromContent() reads first).
constexpr size_t kNiftiHeaderBytes = 348;

/// First bytes of an INRIMAGE-4 header.
inline constexpr char kInrMagic[] = "#INRIMAGE-4#{";

enum class Format { Nifti, Inr, Den, Raw, Vdb, Unknown };

/// The format the extension names (an extra ".gz" allowed, except for .vdb); Unknown otherwise.
Format formatFromExtension(const std::string& path);

/// The format the content shows (NIfTI-1, INRIMAGE-4 or VDB magic); Unknown otherwise.
Format formatFromContent(const std::string& path);

// ---------------------------------------------------------------------------------- writing

/// Writes @a n bytes at @a data to the file being written (see writeAtomic()).
using WriteFn = std::function<void(const void* data, uint64_t n)>;

/// Writes the file that @a writeBody produces (through the WriteFn it is given) to @a path
/// atomically (detail::AtomicFile), gzip-compressed when the name ends with ".gz".
/// Throws IoError naming @a path.
void writeAtomic(const std::string& path, const std::function<void(WriteFn&)>& writeBody);

/// Throws InvalidArgumentError "cannot write <format> '<path>': ..." unless @a vol can be
/// written: dims > 0 and matching the data, finite spacing > 0, finite origin and samples.
void checkWritable(const std::string& path, const ScalarVolume& vol, const char* format);

/// Writes the samples as little-endian float32.
template<typename WriteT>
void writeFloatsLE(WriteT& write, const std::vector<float>& data)
{
    if (!kHostBigEndian) {
        write(data.data(), uint64_t(data.size()) * 4);
        return;
    }
    std::vector<float> chunk;
    for (size_t first = 0; first < data.size(); first += (1u << 20)) {
        const size_t n = std::min<size_t>(1u << 20, data.size() - first);
        chunk.assign(data.begin() + long(first), data.begin() + long(first + n));
        for (float& v : chunk) v = byteSwapped(v);
        write(chunk.data(), uint64_t(n) * 4);
    }
}

} // namespace volumeio_internal

} // namespace levelforge
