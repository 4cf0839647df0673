// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief What every volume format shares: the gzip-aware input stream, sample conversion,
///        dimension checks, the finite-value check, and the atomic writer.
#include "io/VolumeIOInternal.h"

#include "detail/AtomicFile.h"

#include <cfloat>
#include <cmath>
#include <limits>
#include <type_traits>

namespace levelforge {

namespace volumeio_internal {

std::string formatCoord(const openvdb::Coord& c)
{
    return std::to_string(c.x()) + "x" + std::to_string(c.y()) + "x" + std::to_string(c.z());
}

[[noreturn]] void throwInvalid(const std::string& path, const std::string& what)
{
    throw InvalidVolumeError(path + ": " + what);
}

/// double -> float without undefined behaviour: out-of-range values become +-inf.
inline float toFloat(double v)
{
    if (std::fabs(v) <= double(FLT_MAX)) return float(v);
    if (std::isnan(v)) return std::numeric_limits<float>::quiet_NaN();
    return v > 0 ? std::numeric_limits<float>::infinity() : -std::numeric_limits<float>::infinity();
}

// --------------------------------------------------------------------------- type handling

size_t typeBytes(VolumeValueType t)
{
    switch (t) {
    case VolumeValueType::UInt8:
    case VolumeValueType::Int8: return 1;
    case VolumeValueType::UInt16:
    case VolumeValueType::Int16: return 2;
    case VolumeValueType::UInt32:
    case VolumeValueType::Int32:
    case VolumeValueType::Float32: return 4;
    case VolumeValueType::UInt64:
    case VolumeValueType::Int64:
    case VolumeValueType::Float64: return 8;
    }
    return 0;
}

/// Converts @a n samples of type T at @a src (byte order: swap when @a swap) to float,
/// applying v * slope + inter when Scale.
template<typename T, bool Scale>
void convertSamples(const unsigned char* src, size_t n, bool swap, double slope, double inter, float* dst)
{
    using U = std::conditional_t<sizeof(T) == 1, uint8_t,
              std::conditional_t<sizeof(T) == 2, uint16_t,
              std::conditional_t<sizeof(T) == 4, uint32_t, uint64_t>>>;
    for (size_t i = 0; i < n; ++i) {
        U u;
        std::memcpy(&u, src + i * sizeof(T), sizeof(T));
        if constexpr (sizeof(T) == 2) { if (swap) u = __builtin_bswap16(u); }
        if constexpr (sizeof(T) == 4) { if (swap) u = __builtin_bswap32(u); }
        if constexpr (sizeof(T) == 8) { if (swap) u = __builtin_bswap64(u); }
        T v;
        std::memcpy(&v, &u, sizeof(T));
        if constexpr (Scale) {
            dst[i] = toFloat(double(v) * slope + inter);
        } else if constexpr (std::is_same<T, double>::value) {
            dst[i] = toFloat(v);
        } else {
            dst[i] = float(v);
        }
    }
}

template<bool Scale>
void convertAny(VolumeValueType t, const unsigned char* src, size_t n, bool swap, double slope,
                double inter, float* dst)
{
    switch (t) {
    case VolumeValueType::UInt8: return convertSamples<uint8_t, Scale>(src, n, swap, slope, inter, dst);
    case VolumeValueType::Int8: return convertSamples<int8_t, Scale>(src, n, swap, slope, inter, dst);
    case VolumeValueType::UInt16: return convertSamples<uint16_t, Scale>(src, n, swap, slope, inter, dst);
    case VolumeValueType::Int16: return convertSamples<int16_t, Scale>(src, n, swap, slope, inter, dst);
    case VolumeValueType::UInt32: return convertSamples<uint32_t, Scale>(src, n, swap, slope, inter, dst);
    case VolumeValueType::Int32: return convertSamples<int32_t, Scale>(src, n, swap, slope, inter, dst);
    case VolumeValueType::UInt64: return convertSamples<uint64_t, Scale>(src, n, swap, slope, inter, dst);
    case VolumeValueType::Int64: return convertSamples<int64_t, Scale>(src, n, swap, slope, inter, dst);
    case VolumeValueType::Float32: return convertSamples<float, Scale>(src, n, swap, slope, inter, dst);
    case VolumeValueType::Float64: return convertSamples<double, Scale>(src, n, swap, slope, inter, dst);
    }
}

/// Checks that @a dims are positive and their product is within @a maxVoxels; returns it.
uint64_t checkDims(const std::string& path, const int64_t dims[3], uint64_t maxVoxels, const char* names[3])
{
    for (int a = 0; a < 3; ++a) {
        if (dims[a] <= 0) {
            throwInvalid(path, std::string("bad dimension ") + names[a] + " = " + std::to_string(dims[a]) +
                                   " (must be > 0)");
        }
        if (dims[a] > int64_t(std::numeric_limits<int32_t>::max())) {
            throw ResourceLimitError(path + ": dimension " + names[a] + " = " + std::to_string(dims[a]) +
                                     " is beyond the 2^31-1 samples a volume axis can hold");
        }
    }
    uint64_t n = 0;
    const bool overflow = __builtin_mul_overflow(uint64_t(dims[0]), uint64_t(dims[1]), &n) ||
                          __builtin_mul_overflow(n, uint64_t(dims[2]), &n) ||
                          n > std::numeric_limits<uint64_t>::max() / 8;
    const std::string shape = std::to_string(dims[0]) + "x" + std::to_string(dims[1]) + "x" +
                              std::to_string(dims[2]);
    if (overflow) {
        throw ResourceLimitError(path + ": volume " + shape + " has too many samples (its byte count overflows "
                                        "64 bits)");
    }
    if (n > maxVoxels) {
        throw ResourceLimitError(path + ": volume " + shape + " has " + std::to_string(n) +
                                 " samples, more than the limit of " + std::to_string(maxVoxels));
    }
    return n;
}

/// Allocates @a vol for @a dims, turning allocation failure into ResourceLimitError.
void allocate(const std::string& path, ScalarVolume& vol, const int64_t dims[3], uint64_t count)
{
    vol.dims = openvdb::Coord(int(dims[0]), int(dims[1]), int(dims[2]));
    try {
        vol.data.assign(size_t(count), 0.0f);
    } catch (const std::bad_alloc&) {
        throw ResourceLimitError(path + ": cannot allocate " + std::to_string(count) + " float samples");
    }
}

/// Reads vol.voxelCount() samples of @a type from @a in into vol.data (converted, optionally
/// scaled). Processes the file in chunks so no second full-size buffer is needed.
///
/// When vol.data already holds vol.voxelCount() samples (allocate(): a plain file whose size
/// was checked against the header) they are overwritten. When it is empty (a gzip stream,
/// whose decompressed size is only bounded by the deflate ratio) it grows as the data
/// arrives, doubling up to vol.voxelCount(), so a header that claims more data than the
/// stream holds costs at most twice the memory of the data actually there before the
/// "truncated" error.
void readSamples(InputFile& in, VolumeValueType type, bool bigEndian, bool scale, double slope,
                 double inter, ScalarVolume& vol)
{
    const size_t bytes = typeBytes(type);
    const uint64_t count = vol.voxelCount();
    const bool swap = bytes > 1 && bigEndian != kHostBigEndian;
    const uint64_t start = in.position();
    const bool preallocated = vol.data.size() == count;
    auto truncated = [&](uint64_t gotBytes) {
        throwInvalid(in.path(), "truncated voxel data: expected " + std::to_string(count * bytes) +
                                    " bytes (" + formatCoord(vol.dims) + " " + volumeValueTypeName(type) +
                                    ") after the " + std::to_string(start) + "-byte header, the " +
                                    (in.compressed() ? "decompressed " : "") + "file has " +
                                    std::to_string(gotBytes));
    };
    auto growTo = [&](uint64_t need) {
        if (vol.data.size() >= need) return;
        try {
            if (vol.data.capacity() < need) {
                const uint64_t doubled = 2 * uint64_t(vol.data.capacity());
                vol.data.reserve(size_t(std::min(count, std::max(need, doubled))));
            }
            vol.data.resize(size_t(need));
        } catch (const std::bad_alloc&) {
            throw ResourceLimitError(in.path() + ": cannot allocate " + std::to_string(need) + " float samples");
        }
    };
    if (preallocated && type == VolumeValueType::Float32 && !swap && !scale) {
        const uint64_t got = in.read(vol.data.data(), count * 4);
        if (got < count * 4) truncated(got);
        return;
    }
    if (!preallocated) vol.data.clear();
    constexpr uint64_t kChunkSamples = uint64_t(1) << 22;
    std::vector<unsigned char> buffer(size_t(std::min(count, kChunkSamples) * bytes));
    for (uint64_t first = 0; first < count; first += kChunkSamples) {
        const uint64_t n = std::min(kChunkSamples, count - first);
        const uint64_t got = in.read(buffer.data(), n * bytes);
        if (got < n * bytes) truncated(first * bytes + got);
        if (!preallocated) growTo(first + n);
        if (scale) {
            convertAny<true>(type, buffer.data(), size_t(n), swap, slope, inter, vol.data.data() + first);
        } else {
            convertAny<false>(type, buffer.data(), size_t(n), swap, slope, inter, vol.data.data() + first);
        }
    }
}

/// Checks every sample is finite and fills minValue / maxValue.
void finish(const std::string& path, const ScalarVolume& vol, VolumeInfo& info, const std::string& context)
{
    float lo = std::numeric_limits<float>::infinity();
    float hi = -std::numeric_limits<float>::infinity();
    const float* d = vol.data.data();
    const size_t n = vol.data.size();
    bool finite = true;
    for (size_t i = 0; i < n; ++i) {
        const float v = d[i];
        finite &= std::isfinite(v);
        lo = std::min(lo, v);
        hi = std::max(hi, v);
    }
    if (!finite) {
        for (size_t i = 0; i < n; ++i) {
            if (std::isfinite(d[i])) continue;
            const size_t nx = size_t(vol.dims.x()), ny = size_t(vol.dims.y());
            const size_t x = i % nx, y = (i / nx) % ny, z = i / (nx * ny);
            std::string what = path + ": voxel (" + std::to_string(x) + ", " + std::to_string(y) + ", " +
                               std::to_string(z) + ") is " + formatDouble(d[i]);
            if (!context.empty()) what += " (" + context + ")";
            throw InvalidVolumeError(what + "; volumes must hold finite values");
        }
    }
    info.minValue = n ? lo : 0.0;
    info.maxValue = n ? hi : 0.0;
}

// ---------------------------------------------------------------------------------- writing

void writeAtomic(const std::string& path, const std::function<void(WriteFn&)>& writeBody)
{
    if (path.empty()) throw IoError("cannot write a volume: empty output path");
    const fs::path target(path);
    const fs::path dir = detail::parentDirectory(path);
    std::error_code ec;
    if (!fs::is_directory(dir, ec)) {
        throw IoError("cannot write '" + path + "': directory '" + dir.string() + "' does not exist");
    }
    if (fs::is_directory(target, ec)) throw IoError("cannot write '" + path + "': it is a directory");
    const bool gz = endsWith(lowerFileName(path), ".gz");

    detail::AtomicFile file(path, "cannot write '" + path + "'");
    gzFile f = gzdopen(file.descriptor(), gz ? "wb6" : "wbT");
    if (!f) file.fail("out of memory");
    file.releaseDescriptor(); // now owned by f
    bool ok = true;
    WriteFn write = [&](const void* data, uint64_t n) {
        const unsigned char* p = static_cast<const unsigned char*>(data);
        while (ok && n > 0) {
            const unsigned chunk = unsigned(std::min<uint64_t>(n, uint64_t(1) << 30));
            if (gzwrite(f, p, chunk) != int(chunk)) ok = false;
            p += chunk;
            n -= chunk;
        }
    };
    try {
        writeBody(write);
    } catch (...) {
        gzclose_w(f); // the AtomicFile removes the temporary file
        throw;
    }
    int err = Z_OK;
    std::string cause = ok ? std::string() : std::string(gzerror(f, &err));
    const int closed = gzclose_w(f);
    if (ok && closed != Z_OK) {
        ok = false;
        cause = "error closing the file (disk full?)";
    }
    if (!ok) file.fail(cause.empty() ? "write error (disk full?)" : cause);
    file.sync();
    file.commit();
}

void checkWritable(const std::string& path, const ScalarVolume& vol, const char* format)
{
    const std::string prefix = std::string("cannot write ") + format + " '" + path + "': ";
    if (vol.dims.x() <= 0 || vol.dims.y() <= 0 || vol.dims.z() <= 0) {
        throw InvalidArgumentError(prefix + "dims " + formatCoord(vol.dims) + " must be > 0");
    }
    if (vol.data.size() != vol.voxelCount()) {
        throw InvalidArgumentError(prefix + "the volume holds " + std::to_string(vol.data.size()) +
                                   " samples, its dims say " + std::to_string(vol.voxelCount()));
    }
    for (int a = 0; a < 3; ++a) {
        if (!(vol.spacing[a] > 0.0) || !std::isfinite(vol.spacing[a]) || !std::isfinite(vol.origin[a])) {
            throw InvalidArgumentError(prefix + "spacing must be finite and > 0, origin finite");
        }
    }
    for (size_t i = 0; i < vol.data.size(); ++i) {
        if (!std::isfinite(vol.data[i])) {
            throw InvalidArgumentError(prefix + "sample " + std::to_string(i) + " is " +
                                       formatDouble(vol.data[i]) + " (volumes must hold finite values)");
        }
    }
}

} // namespace volumeio_internal

} // namespace levelforge
