// levelforge — scalar volume readers and writers (see VolumeIO.h and docs/volumes.md).
#include <levelforge/io/VolumeIO.h>

#include "detail/MessageText.h"

#include <levelforge/io/VdbIO.h>

#include <openvdb/openvdb.h>
#include <openvdb/tools/Dense.h>

#include <zlib.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cfloat>
#include <chrono>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <limits>
#include <random>
#include <sstream>
#include <string_view>
#include <system_error>
#include <type_traits>

#include <fcntl.h>
#include <unistd.h>

namespace fs = std::filesystem;

namespace levelforge {

namespace volumeio_internal {

constexpr bool kHostBigEndian = (__BYTE_ORDER__ == __ORDER_BIG_ENDIAN__);

// ------------------------------------------------------------------------------------ helpers

std::string lowerFileName(const std::string& path)
{
    std::string name = fs::path(path).filename().string();
    for (char& c : name) c = char(std::tolower(static_cast<unsigned char>(c)));
    return name;
}

bool endsWith(const std::string& s, const std::string& suffix)
{
    return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

std::string formatDouble(double v)
{
    if (std::isnan(v)) return "nan";
    if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
    char buf[64];
    auto r = std::to_chars(buf, buf + sizeof(buf), v);
    return std::string(buf, r.ptr);
}

std::string formatCoord(const openvdb::Coord& c)
{
    return std::to_string(c.x()) + "x" + std::to_string(c.y()) + "x" + std::to_string(c.z());
}


[[noreturn]] void throwInvalid(const std::string& path, const std::string& what)
{
    throw InvalidVolumeError(path + ": " + what);
}

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

/// double -> float without undefined behaviour: out-of-range values become +-inf.
inline float toFloat(double v)
{
    if (std::fabs(v) <= double(FLT_MAX)) return float(v);
    if (std::isnan(v)) return std::numeric_limits<float>::quiet_NaN();
    return v > 0 ? std::numeric_limits<float>::infinity() : -std::numeric_limits<float>::infinity();
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
    if (overflow) throw ResourceLimitError(path + ": volume " + shape + " has too many samples (overflow)");
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
void readSamples(InputFile& in, VolumeValueType type, bool bigEndian, bool scale, double slope,
                 double inter, ScalarVolume& vol)
{
    const size_t bytes = typeBytes(type);
    const uint64_t count = vol.voxelCount();
    const bool swap = bytes > 1 && bigEndian != kHostBigEndian;
    const uint64_t start = in.position();
    auto truncated = [&](uint64_t gotBytes) {
        throwInvalid(in.path(), "truncated voxel data: expected " + std::to_string(count * bytes) +
                                    " bytes (" + formatCoord(vol.dims) + " " + volumeValueTypeName(type) +
                                    ") after the " + std::to_string(start) + "-byte header, the " +
                                    (in.compressed() ? "decompressed " : "") + "file has " +
                                    std::to_string(gotBytes));
    };
    if (type == VolumeValueType::Float32 && !swap && !scale) {
        const uint64_t got = in.read(vol.data.data(), count * 4);
        if (got < count * 4) truncated(got);
        return;
    }
    constexpr uint64_t kChunkSamples = uint64_t(1) << 22;
    std::vector<unsigned char> buffer(size_t(std::min(count, kChunkSamples) * bytes));
    for (uint64_t first = 0; first < count; first += kChunkSamples) {
        const uint64_t n = std::min(kChunkSamples, count - first);
        const uint64_t got = in.read(buffer.data(), n * bytes);
        if (got < n * bytes) truncated(first * bytes + got);
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

/// Reverses the samples of @a vol along axis @a a.
void reverseAxis(ScalarVolume& vol, int a)
{
    const size_t nx = size_t(vol.dims.x()), ny = size_t(vol.dims.y()), nz = size_t(vol.dims.z());
    float* d = vol.data.data();
    if (a == 0) {
        for (size_t row = 0; row < ny * nz; ++row) std::reverse(d + row * nx, d + row * nx + nx);
    } else if (a == 1) {
        for (size_t z = 0; z < nz; ++z) {
            float* slice = d + z * nx * ny;
            for (size_t y = 0; y < ny / 2; ++y) {
                std::swap_ranges(slice + y * nx, slice + y * nx + nx, slice + (ny - 1 - y) * nx);
            }
        }
    } else {
        const size_t s = nx * ny;
        for (size_t z = 0; z < nz / 2; ++z) std::swap_ranges(d + z * s, d + z * s + s, d + (nz - 1 - z) * s);
    }
}

// ----------------------------------------------------------------------------------- NIfTI-1

constexpr size_t kNiftiHeaderBytes = 348;

struct NiftiType
{
    int code;
    VolumeValueType type;
};
constexpr NiftiType kNiftiTypes[] = {
    {2, VolumeValueType::UInt8},    {4, VolumeValueType::Int16},   {8, VolumeValueType::Int32},
    {16, VolumeValueType::Float32}, {64, VolumeValueType::Float64}, {256, VolumeValueType::Int8},
    {512, VolumeValueType::UInt16}, {768, VolumeValueType::UInt32}, {1024, VolumeValueType::Int64},
    {1280, VolumeValueType::UInt64}};

const char* niftiTypeDescription(int code)
{
    switch (code) {
    case 0: return "unknown";
    case 1: return "binary (1 bit)";
    case 32: return "complex64";
    case 128: return "rgb24";
    case 1536: return "float128";
    case 1792: return "complex128";
    case 2048: return "complex256";
    case 2304: return "rgba32";
    default: return "not a NIfTI-1 datatype";
    }
}

ScalarVolume readNiftiStream(InputFile& in, const ReadVolumeOptions& options, VolumeInfo& info)
{
    const std::string& path = in.path();
    unsigned char h[kNiftiHeaderBytes];
    const uint64_t got = in.read(h, sizeof(h));
    if (got < sizeof(h)) {
        throwInvalid(path, "not a NIfTI-1 file: " + std::to_string(got) +
                               " bytes, shorter than the 348-byte NIfTI-1 header");
    }
    bool big = false;
    const int32_t sizeLE = getField<int32_t>(h, 0, false);
    const int32_t sizeBE = getField<int32_t>(h, 0, true);
    if (sizeLE == 348) {
        big = false;
    } else if (sizeBE == 348) {
        big = true;
    } else if (sizeLE == 540 || sizeBE == 540) {
        throwInvalid(path, "NIfTI-2 files (sizeof_hdr = 540) are not supported; save as NIfTI-1");
    } else {
        throwInvalid(path, "not a NIfTI-1 file: sizeof_hdr = " + std::to_string(sizeLE) + " (expected 348)");
    }
    info.format = "nifti";
    info.bigEndian = big;
    const std::string magic(reinterpret_cast<const char*>(h + 344), 4);
    if (magic == std::string("ni1\0", 4)) {
        throwInvalid(path, "two-file NIfTI-1 (magic 'ni1', .hdr + .img) is not supported; "
                           "convert it to a single .nii file");
    }
    if (magic != std::string("n+1\0", 4)) {
        throwInvalid(path, "magic " + message_internal::quotedExcerpt(magic) + " is not the NIfTI-1 single-file magic 'n+1' "
                                                      "(an Analyze 7.5 header?)");
    }

    // dim[8] at 40.
    int64_t dim[8];
    for (int i = 0; i < 8; ++i) dim[i] = getField<int16_t>(h, 40 + 2 * size_t(i), big);
    if (dim[0] < 1 || dim[0] > 7) {
        throwInvalid(path, "dim[0] = " + std::to_string(dim[0]) + " (the number of dimensions must be 1..7)");
    }
    for (int i = 4; i <= dim[0]; ++i) {
        if (dim[i] != 1) {
            throwInvalid(path, "dim[0] = " + std::to_string(dim[0]) + " with dim[" + std::to_string(i) +
                                   "] = " + std::to_string(dim[i]) + ": only 3-D volumes are supported "
                                   "(a time series or vector image has dim[4..] > 1)");
        }
    }
    int64_t dims[3];
    for (int a = 0; a < 3; ++a) dims[a] = (a + 1 <= dim[0]) ? dim[a + 1] : 1;
    const char* dimNames[3] = {"dim[1]", "dim[2]", "dim[3]"};

    const int datatype = getField<int16_t>(h, 70, big);
    bool known = false;
    for (const NiftiType& t : kNiftiTypes) {
        if (t.code == datatype) {
            info.sourceType = t.type;
            known = true;
        }
    }
    if (!known) {
        throwInvalid(path, "unsupported datatype " + std::to_string(datatype) + " (" +
                               niftiTypeDescription(datatype) + "); supported: 2 uint8, 4 int16, 8 int32, "
                               "16 float32, 64 float64, 256 int8, 512 uint16, 768 uint32, 1024 int64, 1280 uint64");
    }

    float pixdim[8];
    for (int i = 0; i < 8; ++i) pixdim[i] = getField<float>(h, 76 + 4 * size_t(i), big);
    openvdb::Vec3d spacing;
    for (int a = 0; a < 3; ++a) {
        const double p = std::fabs(double(pixdim[a + 1]));
        if (!(p > 0.0) || !std::isfinite(p)) {
            if (a + 1 > dim[0]) { // an axis the file does not have
                spacing[a] = 1.0;
                continue;
            }
            throwInvalid(path, "pixdim[" + std::to_string(a + 1) + "] = " + formatDouble(pixdim[a + 1]) +
                                   " (the voxel spacing must be finite and non-zero)");
        }
        spacing[a] = p;
    }

    const float voxOffset = getField<float>(h, 108, big);
    if (!std::isfinite(voxOffset) || voxOffset < float(kNiftiHeaderBytes) || voxOffset != std::floor(voxOffset) ||
        voxOffset > 1e9f) {
        throwInvalid(path, "vox_offset = " + formatDouble(voxOffset) +
                               " (must be a whole number of bytes >= 348)");
    }
    const double slope = getField<float>(h, 112, big);
    double inter = getField<float>(h, 116, big);
    const bool scale = std::isfinite(slope) && slope != 0.0 && !(slope == 1.0 && (inter == 0.0 || !std::isfinite(inter)));
    if (!std::isfinite(inter)) inter = 0.0;

    // Geometry: sform if sform_code > 0, else qform if qform_code > 0, else pixdim only.
    const int qformCode = getField<int16_t>(h, 252, big);
    const int sformCode = getField<int16_t>(h, 254, big);
    double m[3][3] = {{spacing[0], 0, 0}, {0, spacing[1], 0}, {0, 0, spacing[2]}}; // column a = step of index a
    double t[3] = {0, 0, 0};
    std::string xform = "pixdim";
    if (sformCode > 0) {
        xform = "sform";
        for (int r = 0; r < 3; ++r) {
            for (int c = 0; c < 3; ++c) m[r][c] = getField<float>(h, 280 + 16 * size_t(r) + 4 * size_t(c), big);
            t[r] = getField<float>(h, 280 + 16 * size_t(r) + 12, big);
        }
    } else if (qformCode > 0) {
        xform = "qform";
        const double b = getField<float>(h, 256, big), c = getField<float>(h, 260, big),
                     d = getField<float>(h, 264, big);
        const double a = std::sqrt(std::max(0.0, 1.0 - (b * b + c * c + d * d)));
        const double r[3][3] = {{a * a + b * b - c * c - d * d, 2 * (b * c - a * d), 2 * (b * d + a * c)},
                                {2 * (b * c + a * d), a * a + c * c - b * b - d * d, 2 * (c * d - a * b)},
                                {2 * (b * d - a * c), 2 * (c * d + a * b), a * a + d * d - c * c - b * b}};
        const double qfac = pixdim[0] < 0 ? -1.0 : 1.0;
        const double s[3] = {spacing[0], spacing[1], qfac * spacing[2]};
        for (int row = 0; row < 3; ++row) {
            for (int col = 0; col < 3; ++col) m[row][col] = r[row][col] * s[col];
        }
        for (int row = 0; row < 3; ++row) t[row] = getField<float>(h, 268 + 4 * size_t(row), big);
    }
    for (int r = 0; r < 3; ++r) {
        bool ok = std::isfinite(t[r]);
        for (int c = 0; c < 3; ++c) ok &= std::isfinite(m[r][c]);
        if (!ok) throwInvalid(path, "the " + xform + " holds a NaN or infinite value");
    }

    const uint64_t count = checkDims(path, dims, options.maxVoxels, dimNames);
    ScalarVolume vol;
    allocate(path, vol, dims, count);

    // Skip header extensions up to vox_offset, then read.
    const uint64_t offset = uint64_t(voxOffset);
    if (in.skip(offset - kNiftiHeaderBytes) < offset - kNiftiHeaderBytes) {
        throwInvalid(path, "truncated: the file ends before vox_offset = " + std::to_string(offset));
    }
    readSamples(in, info.sourceType, big, scale, slope, inter, vol);
    info.compressed = in.compressed();
    in.drain(); // verifies the gzip checksum; trailing bytes are allowed by NIfTI-1

    // Axis-aligned part of the transform.
    double maxDiag = 0.0;
    for (int a = 0; a < 3; ++a) maxDiag = std::max(maxDiag, std::fabs(m[a][a]));
    bool diagonal = maxDiag > 0.0;
    for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) {
            if (r != c && std::fabs(m[r][c]) > 1e-6 * maxDiag) diagonal = false;
        }
        if (!(std::fabs(m[r][r]) > 0.0)) diagonal = false;
    }
    if (diagonal) {
        for (int a = 0; a < 3; ++a) {
            vol.spacing[a] = std::fabs(m[a][a]);
            vol.origin[a] = t[a];
            if (m[a][a] < 0.0) {
                reverseAxis(vol, a);
                vol.origin[a] = t[a] + double(dims[a] - 1) * m[a][a];
                info.reversedAxes[size_t(a)] = true;
            }
        }
    } else {
        for (int a = 0; a < 3; ++a) {
            const double len = std::sqrt(m[0][a] * m[0][a] + m[1][a] * m[1][a] + m[2][a] * m[2][a]);
            vol.spacing[a] = len > 0.0 ? len : spacing[a];
            vol.origin[a] = t[a];
        }
        info.warnings.push_back(path + ": the " + xform + " rotates or shears the voxel axes; only the "
                                       "voxel sizes and the offset are used (world positions are approximate)");
    }
    finish(path, vol, info, scale ? "after scl_slope/scl_inter" : std::string());
    return vol;
}

// ----------------------------------------------------------------------------- INRIMAGE-4

const char kInrMagic[] = "#INRIMAGE-4#{";

ScalarVolume readInrStream(InputFile& in, const ReadVolumeOptions& options, VolumeInfo& info)
{
    const std::string& path = in.path();
    std::string header;
    header.resize(256);
    const uint64_t first = in.read(header.data(), 256);
    header.resize(size_t(first));
    if (header.compare(0, sizeof(kInrMagic) - 1, kInrMagic) != 0) {
        throwInvalid(path, "not an INRIMAGE-4 file: it does not start with '#INRIMAGE-4#{'");
    }
    if (first < 256) throwInvalid(path, "truncated INRIMAGE-4 header: " + std::to_string(first) + " of 256 bytes");
    // The header is padded to a multiple of 256 bytes and ends with "##}\n".
    size_t end = header.find("##}");
    while (end == std::string::npos || header.size() < ((end + 4 + 255) / 256) * 256) {
        if (header.size() >= (1u << 16)) throwInvalid(path, "no '##}' ending the INRIMAGE-4 header in its first 64 KiB");
        const size_t old = header.size();
        header.resize(old + 256);
        const uint64_t got = in.read(header.data() + old, 256);
        if (got < 256) throwInvalid(path, "truncated INRIMAGE-4 header: no '##}' before the end of the file");
        if (end == std::string::npos) end = header.find("##}");
    }
    const size_t headerBytes = ((end + 4 + 255) / 256) * 256;
    info.format = "inr";

    int64_t dims[3] = {-1, -1, 1};
    int64_t vdim = 1;
    std::string typeText;
    int64_t bits = -1;
    std::string cpu;
    openvdb::Vec3d spacing(1.0), origin(0.0);
    std::istringstream lines(header.substr(sizeof(kInrMagic) - 1, end - (sizeof(kInrMagic) - 1)));
    std::string line;
    auto parseInt = [&](const std::string& key, const std::string& value) {
        int64_t v = 0;
        const char* b = value.data();
        const char* e = b + value.size();
        const auto r = std::from_chars(b, e, v);
        if (r.ec != std::errc() || b == e) throwInvalid(path, key + " = " + message_internal::quotedExcerpt(value) + " is not an integer");
        return v;
    };
    auto parseReal = [&](const std::string& key, const std::string& value) {
        char* e = nullptr;
        const double v = std::strtod(value.c_str(), &e);
        if (e == value.c_str() || !std::isfinite(v)) {
            throwInvalid(path, key + " = " + message_internal::quotedExcerpt(value) + " is not a finite number");
        }
        return v;
    };
    while (std::getline(lines, line)) {
        while (!line.empty() && (line.back() == '\r' || line.back() == ' ')) line.pop_back();
        if (line.empty() || line[0] == '#') continue;
        const size_t eq = line.find('=');
        if (eq == std::string::npos) continue;
        std::string key = line.substr(0, eq);
        std::string value = line.substr(eq + 1);
        while (!key.empty() && key.back() == ' ') key.pop_back();
        while (!value.empty() && value.front() == ' ') value.erase(0, 1);
        if (key == "XDIM") dims[0] = parseInt(key, value);
        else if (key == "YDIM") dims[1] = parseInt(key, value);
        else if (key == "ZDIM") dims[2] = parseInt(key, value);
        else if (key == "VDIM") vdim = parseInt(key, value);
        else if (key == "TYPE") typeText = value;
        else if (key == "PIXSIZE") {
            bits = parseInt(key, value.substr(0, value.find(' ')));
        } else if (key == "CPU") cpu = value;
        else if (key == "VX") spacing[0] = parseReal(key, value);
        else if (key == "VY") spacing[1] = parseReal(key, value);
        else if (key == "VZ") spacing[2] = parseReal(key, value);
        else if (key == "XO") origin[0] = parseReal(key, value);
        else if (key == "YO") origin[1] = parseReal(key, value);
        else if (key == "ZO") origin[2] = parseReal(key, value);
    }
    if (dims[0] < 0) throwInvalid(path, "the INRIMAGE-4 header has no XDIM");
    if (dims[1] < 0) throwInvalid(path, "the INRIMAGE-4 header has no YDIM");
    if (vdim != 1) {
        throwInvalid(path, "VDIM = " + std::to_string(vdim) + ": only scalar images (VDIM=1) are supported");
    }
    for (int a = 0; a < 3; ++a) {
        if (!(spacing[a] > 0.0)) {
            throwInvalid(path, std::string(a == 0 ? "VX" : a == 1 ? "VY" : "VZ") + " = " + formatDouble(spacing[a]) +
                                   " (the voxel spacing must be > 0)");
        }
    }
    if (typeText.empty()) throwInvalid(path, "the INRIMAGE-4 header has no TYPE");
    if (bits < 0) throwInvalid(path, "the INRIMAGE-4 header has no PIXSIZE");
    const std::string bitsText = std::to_string(bits);
    if (typeText == "float") {
        if (bits == 32) info.sourceType = VolumeValueType::Float32;
        else if (bits == 64) info.sourceType = VolumeValueType::Float64;
        else throwInvalid(path, "TYPE=float with PIXSIZE=" + bitsText + " bits is not supported (32 or 64)");
    } else if (typeText == "unsigned fixed" || typeText == "signed fixed") {
        const bool s = typeText[0] == 's';
        switch (bits) {
        case 8: info.sourceType = s ? VolumeValueType::Int8 : VolumeValueType::UInt8; break;
        case 16: info.sourceType = s ? VolumeValueType::Int16 : VolumeValueType::UInt16; break;
        case 32: info.sourceType = s ? VolumeValueType::Int32 : VolumeValueType::UInt32; break;
        case 64: info.sourceType = s ? VolumeValueType::Int64 : VolumeValueType::UInt64; break;
        default:
            throwInvalid(path, "TYPE=" + typeText + " with PIXSIZE=" + bitsText +
                                   " bits is not supported (8, 16, 32 or 64)");
        }
    } else {
        throwInvalid(path, "unsupported TYPE " + message_internal::quotedExcerpt(typeText) +
                               " (supported: 'unsigned fixed', 'signed fixed', 'float')");
    }
    bool big = false;
    if (cpu.empty() || cpu == "decm" || cpu == "pc" || cpu == "alpha") {
        big = false;
        if (cpu.empty() && typeBytes(info.sourceType) > 1) {
            info.warnings.push_back(path + ": no CPU in the INRIMAGE-4 header; little endian assumed");
        }
    } else if (cpu == "sun" || cpu == "sgi") {
        big = true;
    } else {
        throwInvalid(path, "unknown CPU " + message_internal::quotedExcerpt(cpu) + " (expected decm, pc, alpha, sun or sgi)");
    }
    info.bigEndian = big;

    const char* dimNames[3] = {"XDIM", "YDIM", "ZDIM"};
    const uint64_t count = checkDims(path, dims, options.maxVoxels, dimNames);
    ScalarVolume vol;
    allocate(path, vol, dims, count);
    vol.spacing = spacing;
    vol.origin = origin;
    if (in.skip(headerBytes - header.size()) < headerBytes - header.size()) {
        throwInvalid(path, "truncated INRIMAGE-4 header");
    }
    readSamples(in, info.sourceType, big, false, 1.0, 0.0, vol);
    info.compressed = in.compressed();
    in.drain(); // verifies the gzip checksum
    finish(path, vol, info, "");
    return vol;
}

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
    ScalarVolume vol;
    allocate(path, vol, dims, count);
    readSamples(in, VolumeValueType::UInt8, big, false, 1.0, 0.0, vol);
    info.compressed = in.compressed();
    if (const uint64_t extra = in.drain()) {
        throwInvalid(path, std::to_string(extra) + " bytes after the " + std::to_string(count) +
                               " samples the header announces (map_length)");
    }
    finish(path, vol, info, "");
    return vol;
}

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
    ScalarVolume vol;
    allocate(path, vol, dims, count);
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

// -------------------------------------------------------------------------------------- vdb

template<typename GridT>
ScalarVolume denseFromGrid(const std::string& path, const GridT& grid, uint64_t maxVoxels, int padding)
{
    openvdb::CoordBBox bbox = grid.evalActiveVoxelBoundingBox();
    if (bbox.empty() || grid.activeVoxelCount() == 0) {
        throwInvalid(path, "grid '" + grid.getName() + "' has no active voxels");
    }
    bbox.expand(std::max(0, padding));
    const openvdb::Coord d = bbox.dim();
    const int64_t dims[3] = {d.x(), d.y(), d.z()};
    const char* dimNames[3] = {"x", "y", "z"};
    const uint64_t count = checkDims(path, dims, maxVoxels, dimNames);
    ScalarVolume vol;
    allocate(path, vol, dims, count);
    openvdb::tools::Dense<float, openvdb::tools::LayoutXYZ> dense(bbox, vol.data.data());
    openvdb::tools::copyToDense(grid, dense);
    return vol;
}

/// The scalar grid readVdb() converts (checked: scalar type, axis-aligned positive scale).
openvdb::GridBase::Ptr chooseScalarGrid(const std::string& path, const ReadVolumeOptions& options, VolumeInfo& info)
{
    {
        // Existence and type checks with this module's messages; readGrids() does the rest.
        InputFile probe(path);
    }
    openvdb::GridPtrVecPtr grids = readGrids(path);
    info.format = "vdb";
    auto scalarType = [](const openvdb::GridBase& g, VolumeValueType& t) {
        if (g.isType<openvdb::FloatGrid>()) t = VolumeValueType::Float32;
        else if (g.isType<openvdb::DoubleGrid>()) t = VolumeValueType::Float64;
        else if (g.isType<openvdb::Int32Grid>()) t = VolumeValueType::Int32;
        else if (g.isType<openvdb::Int64Grid>()) t = VolumeValueType::Int64;
        else return false;
        return true;
    };
    openvdb::GridBase::Ptr chosen;
    std::string available;
    for (const auto& g : *grids) {
        if (!g) continue;
        available += (available.empty() ? "" : ", ") + ("'" + g->getName() + "' (" + g->valueType() + ")");
        VolumeValueType t;
        const bool scalar = scalarType(*g, t);
        if (options.vdbGridName.empty() ? (scalar && !chosen) : (g->getName() == options.vdbGridName && !chosen)) {
            if (!scalar) {
                throwInvalid(path, "grid '" + g->getName() + "' holds " + g->valueType() +
                                       " values; only float, double, int32 and int64 grids can be read as volumes");
            }
            chosen = g;
            info.sourceType = t;
        }
    }
    if (!chosen) {
        if (options.vdbGridName.empty()) {
            throwInvalid(path, "no float, double, int32 or int64 grid (grids: " +
                                   (available.empty() ? std::string("none") : available) + ")");
        }
        throwInvalid(path, "no grid named '" + options.vdbGridName + "' (grids: " +
                               (available.empty() ? std::string("none") : available) + ")");
    }
    info.gridName = chosen->getName();

    const openvdb::math::Transform& xf = chosen->transform();
    const std::string gridText = "grid '" + chosen->getName() + "': ";
    if (!xf.isLinear()) {
        throwInvalid(path, gridText + "the transform (" + xf.mapType() +
                               ") is not linear; only axis-aligned scale + translation can be read as a volume");
    }
    const openvdb::Mat4d m = xf.baseMap()->getAffineMap()->getMat4();
    double maxDiag = 0.0;
    for (int a = 0; a < 3; ++a) maxDiag = std::max(maxDiag, std::fabs(m[a][a]));
    for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) {
            if (r != c && std::fabs(m[r][c]) > 1e-9 * maxDiag) {
                throwInvalid(path, gridText + "the transform rotates or shears the voxel axes; only axis-aligned "
                                              "scale + translation can be read as a volume");
            }
        }
        if (!(m[r][r] > 0.0)) {
            throwInvalid(path, gridText + "the transform's scale along axis " + std::to_string(r) + " is " +
                                   formatDouble(m[r][r]) + "; it must be > 0 (no mirroring)");
        }
    }

    return chosen;
}

ScalarVolume readVdb(const std::string& path, const ReadVolumeOptions& options, VolumeInfo& info)
{
    const openvdb::GridBase::Ptr chosen = chooseScalarGrid(path, options, info);
    const openvdb::math::Transform& xf = chosen->transform();
    const std::string gridText = "grid '" + chosen->getName() + "': ";
    const openvdb::Mat4d m = xf.baseMap()->getAffineMap()->getMat4();
    ScalarVolume vol;
    switch (info.sourceType) {
    case VolumeValueType::Float32:
        vol = denseFromGrid(path, static_cast<const openvdb::FloatGrid&>(*chosen), options.maxVoxels, options.vdbPadding); break;
    case VolumeValueType::Float64:
        vol = denseFromGrid(path, static_cast<const openvdb::DoubleGrid&>(*chosen), options.maxVoxels, options.vdbPadding); break;
    case VolumeValueType::Int32:
        vol = denseFromGrid(path, static_cast<const openvdb::Int32Grid&>(*chosen), options.maxVoxels, options.vdbPadding); break;
    default:
        vol = denseFromGrid(path, static_cast<const openvdb::Int64Grid&>(*chosen), options.maxVoxels, options.vdbPadding); break;
    }
    openvdb::CoordBBox bbox = chosen->evalActiveVoxelBoundingBox();
    bbox.expand(std::max(0, options.vdbPadding));
    vol.spacing = openvdb::Vec3d(m[0][0], m[1][1], m[2][2]);
    vol.origin = xf.indexToWorld(bbox.min());
    finish(path, vol, info, gridText.substr(0, gridText.size() - 2));
    return vol;
}

// ----------------------------------------------------------------------------- format choice

enum class Format { Nifti, Inr, Den, Raw, Vdb, Unknown };

Format formatFromExtension(const std::string& path)
{
    std::string name = lowerFileName(path);
    const bool gz = endsWith(name, ".gz");
    if (gz) name.resize(name.size() - 3);
    if (endsWith(name, ".vdb")) return gz ? Format::Unknown : Format::Vdb;
    if (endsWith(name, ".nii")) return Format::Nifti;
    if (endsWith(name, ".inr")) return Format::Inr;
    if (endsWith(name, ".den")) return Format::Den;
    if (endsWith(name, ".raw")) return Format::Raw;
    return Format::Unknown;
}

Format formatFromContent(const std::string& path)
{
    InputFile in(path);
    unsigned char h[kNiftiHeaderBytes] = {};
    const uint64_t got = in.read(h, sizeof(h));
    if (got >= sizeof(kInrMagic) - 1 && std::memcmp(h, kInrMagic, sizeof(kInrMagic) - 1) == 0) return Format::Inr;
    if (got >= 8 && !in.compressed() && getField<int64_t>(h, 0, false) == int64_t(0x56444220)) return Format::Vdb;
    if (got == sizeof(h) && (getField<int32_t>(h, 0, false) == 348 || getField<int32_t>(h, 0, true) == 348) &&
        std::memcmp(h + 344, "n+1", 4) == 0) {
        return Format::Nifti;
    }
    return Format::Unknown;
}

/// Writes the file that @a writeBody produces to @a path atomically, gzip-compressed when the
/// name ends with ".gz".
template<typename BodyFn>
void writeAtomic(const std::string& path, BodyFn writeBody)
{
    if (path.empty()) throw IoError("cannot write a volume: empty output path");
    const fs::path target(path);
    const fs::path dir = target.parent_path().empty() ? fs::path(".") : target.parent_path();
    std::error_code ec;
    if (!fs::is_directory(dir, ec)) {
        throw IoError("cannot write '" + path + "': directory '" + dir.string() + "' does not exist");
    }
    if (fs::is_directory(target, ec)) throw IoError("cannot write '" + path + "': it is a directory");
    const bool gz = endsWith(lowerFileName(path), ".gz");

    std::random_device rd;
    std::mt19937_64 rng((uint64_t(rd()) << 32) ^ uint64_t(rd()) ^
                        uint64_t(std::chrono::steady_clock::now().time_since_epoch().count()));
    std::string tmp;
    int fd = -1;
    for (int attempt = 0; attempt < 100 && fd < 0; ++attempt) {
        char suffix[48];
        std::snprintf(suffix, sizeof(suffix), ".%ld-%08llx.tmp", long(::getpid()),
                      static_cast<unsigned long long>(rng() & 0xffffffffull));
        tmp = (dir / ("." + target.filename().string() + suffix)).string();
        fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
        if (fd < 0 && errno != EEXIST) {
            throw IoError("cannot write '" + path + "': cannot create a file in '" + dir.string() +
                          "': " + std::strerror(errno));
        }
    }
    if (fd < 0) throw IoError("cannot write '" + path + "': no free temporary file name");
    auto fail = [&](const std::string& cause) {
        std::error_code ignored;
        fs::remove(tmp, ignored);
        throw IoError("cannot write '" + path + "': " + cause);
    };
    const int fdSync = ::dup(fd);
    gzFile f = gzdopen(fd, gz ? "wb6" : "wbT");
    if (!f) {
        ::close(fd);
        if (fdSync >= 0) ::close(fdSync);
        fail("out of memory");
    }
    bool ok = true;
    auto write = [&](const void* data, uint64_t n) {
        const unsigned char* p = static_cast<const unsigned char*>(data);
        while (ok && n > 0) {
            const unsigned chunk = unsigned(std::min<uint64_t>(n, uint64_t(1) << 30));
            if (gzwrite(f, p, chunk) != int(chunk)) ok = false;
            p += chunk;
            n -= chunk;
        }
    };
    writeBody(write);
    int err = Z_OK;
    std::string cause = ok ? std::string() : std::string(gzerror(f, &err));
    const int closed = gzclose_w(f);
    if (ok && closed != Z_OK) {
        ok = false;
        cause = "error closing the file (disk full?)";
    }
    if (ok && fdSync >= 0 && ::fsync(fdSync) != 0) {
        ok = false;
        cause = std::strerror(errno);
    }
    if (fdSync >= 0) ::close(fdSync);
    if (!ok) fail(cause.empty() ? "write error (disk full?)" : cause);
    if (std::rename(tmp.c_str(), path.c_str()) != 0) fail(std::strerror(errno));
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

/// Writes the samples as little-endian float32.
template<typename WriteFn>
void writeFloatsLE(WriteFn& write, const std::vector<float>& data)
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

// ================================================================================== public API

std::string volumeValueTypeName(VolumeValueType type)
{
    switch (type) {
    case VolumeValueType::UInt8: return "uint8";
    case VolumeValueType::Int8: return "int8";
    case VolumeValueType::UInt16: return "uint16";
    case VolumeValueType::Int16: return "int16";
    case VolumeValueType::UInt32: return "uint32";
    case VolumeValueType::Int32: return "int32";
    case VolumeValueType::UInt64: return "uint64";
    case VolumeValueType::Int64: return "int64";
    case VolumeValueType::Float32: return "float32";
    case VolumeValueType::Float64: return "float64";
    }
    return "unknown";
}

size_t volumeValueTypeBytes(VolumeValueType type) { return volumeio_internal::typeBytes(type); }

ScalarVolume readNifti(const std::string& path, const ReadVolumeOptions& options, VolumeInfo* info)
{
    VolumeInfo local;
    volumeio_internal::InputFile in(path);
    ScalarVolume vol = volumeio_internal::readNiftiStream(in, options, local);
    if (info) *info = std::move(local);
    return vol;
}

ScalarVolume readInr(const std::string& path, const ReadVolumeOptions& options, VolumeInfo* info)
{
    VolumeInfo local;
    volumeio_internal::InputFile in(path);
    ScalarVolume vol = volumeio_internal::readInrStream(in, options, local);
    if (info) *info = std::move(local);
    return vol;
}

ScalarVolume readDen(const std::string& path, const ReadVolumeOptions& options, VolumeInfo* info)
{
    VolumeInfo local;
    volumeio_internal::InputFile in(path);
    ScalarVolume vol = volumeio_internal::readDenStream(in, options, local);
    if (info) *info = std::move(local);
    return vol;
}

ScalarVolume readRaw(const std::string& path, const RawVolumeLayout& layout, uint64_t maxVoxels, VolumeInfo* info)
{
    VolumeInfo local;
    volumeio_internal::InputFile in(path);
    ScalarVolume vol = volumeio_internal::readRawStream(in, layout, maxVoxels, local);
    if (info) *info = std::move(local);
    return vol;
}

openvdb::FloatGrid::Ptr readVdbScalarGrid(const std::string& path, const ReadVolumeOptions& options, VolumeInfo* info)
{
    if (volumeio_internal::formatFromExtension(path) != volumeio_internal::Format::Vdb)
        volumeio_internal::throwInvalid(path, "not a .vdb file (only OpenVDB grids can be read without densifying)");
    VolumeInfo local;
    const openvdb::GridBase::Ptr chosen = volumeio_internal::chooseScalarGrid(path, options, local);
    openvdb::FloatGrid::Ptr out;
    switch (local.sourceType) {
    case VolumeValueType::Float32:
        out = openvdb::gridPtrCast<openvdb::FloatGrid>(chosen); // read for us: nothing to share
        break;
    case VolumeValueType::Float64:
        out = openvdb::FloatGrid::create(std::make_shared<openvdb::FloatTree>(
            openvdb::gridConstPtrCast<openvdb::DoubleGrid>(chosen)->tree()));
        break;
    case VolumeValueType::Int32:
        out = openvdb::FloatGrid::create(std::make_shared<openvdb::FloatTree>(
            openvdb::gridConstPtrCast<openvdb::Int32Grid>(chosen)->tree()));
        break;
    default:
        out = openvdb::FloatGrid::create(std::make_shared<openvdb::FloatTree>(
            openvdb::gridConstPtrCast<openvdb::Int64Grid>(chosen)->tree()));
        break;
    }
    out->setTransform(chosen->transform().copy());
    out->setName(chosen->getName());
    if (info) *info = std::move(local);
    return out;
}

ScalarVolume readVdbVolume(const std::string& path, const ReadVolumeOptions& options, VolumeInfo* info)
{
    VolumeInfo local;
    ScalarVolume vol = volumeio_internal::readVdb(path, options, local);
    if (info) *info = std::move(local);
    return vol;
}

ScalarVolume readVolume(const std::string& path, const ReadVolumeOptions& options, VolumeInfo* info)
{
    using namespace volumeio_internal;
    Format format = formatFromExtension(path);
    if (format == Format::Raw && !options.raw) {
        throw InvalidArgumentError(path + ": a .raw volume needs a RawVolumeLayout (dims, value type, "
                                          "byte order, spacing, header bytes)");
    }
    if (format == Format::Unknown) {
        format = options.raw ? Format::Raw : formatFromContent(path);
    }
    switch (format) {
    case Format::Nifti: return readNifti(path, options, info);
    case Format::Inr: return readInr(path, options, info);
    case Format::Den: return readDen(path, options, info);
    case Format::Raw: return readRaw(path, *options.raw, options.maxVoxels, info);
    case Format::Vdb: return readVdbVolume(path, options, info);
    case Format::Unknown: break;
    }
    throw IoError("cannot read '" + path + "': unrecognised volume format (extension is not one of .nii, "
                  ".nii.gz, .inr, .inr.gz, .den, .raw, .vdb and the content is not NIfTI-1, INRIMAGE-4 "
                  "or VDB); for headerless data pass a RawVolumeLayout");
}

void writeNifti(const std::string& path, const ScalarVolume& volume)
{
    using namespace volumeio_internal;
    checkWritable(path, volume, "NIfTI-1");
    for (int a = 0; a < 3; ++a) {
        if (volume.dims[a] > 32767) {
            throw InvalidArgumentError("cannot write NIfTI-1 '" + path + "': dims " + formatCoord(volume.dims) +
                                       " exceed the format's 32767 samples per axis");
        }
    }
    unsigned char h[352] = {};
    putLE<int32_t>(h, 0, 348);
    h[38] = 'r'; // regular
    putLE<int16_t>(h, 40, 3);
    for (int a = 0; a < 3; ++a) putLE<int16_t>(h, 42 + 2 * size_t(a), int16_t(volume.dims[a]));
    for (int i = 4; i < 8; ++i) putLE<int16_t>(h, 40 + 2 * size_t(i), 1);
    putLE<int16_t>(h, 70, 16);  // float32
    putLE<int16_t>(h, 72, 32);  // bitpix
    putLE<float>(h, 76, 1.0f);  // qfac
    for (int a = 0; a < 3; ++a) putLE<float>(h, 80 + 4 * size_t(a), float(volume.spacing[a]));
    putLE<float>(h, 108, 352.0f); // vox_offset
    putLE<float>(h, 112, 1.0f);   // scl_slope
    std::snprintf(reinterpret_cast<char*>(h + 148), 80, "levelforge");
    putLE<int16_t>(h, 252, 1); // qform_code: scanner
    putLE<int16_t>(h, 254, 1); // sform_code: scanner
    for (int a = 0; a < 3; ++a) putLE<float>(h, 268 + 4 * size_t(a), float(volume.origin[a]));
    for (int r = 0; r < 3; ++r) {
        putLE<float>(h, 280 + 16 * size_t(r) + 4 * size_t(r), float(volume.spacing[r]));
        putLE<float>(h, 280 + 16 * size_t(r) + 12, float(volume.origin[r]));
    }
    std::memcpy(h + 344, "n+1", 4);
    writeAtomic(path, [&](auto& write) {
        write(h, sizeof(h)); // 348 bytes of header + 4 bytes of (empty) extension flag
        writeFloatsLE(write, volume.data);
    });
}

void writeInr(const std::string& path, const ScalarVolume& volume)
{
    using namespace volumeio_internal;
    checkWritable(path, volume, "INRIMAGE-4");
    auto real = [](double v) {
        char buf[64];
        auto r = std::to_chars(buf, buf + sizeof(buf), v);
        return std::string(buf, r.ptr);
    };
    std::string header = std::string(kInrMagic) + "\n";
    header += "XDIM=" + std::to_string(volume.dims.x()) + "\n";
    header += "YDIM=" + std::to_string(volume.dims.y()) + "\n";
    header += "ZDIM=" + std::to_string(volume.dims.z()) + "\n";
    header += "VDIM=1\nTYPE=float\nPIXSIZE=32 bits\nCPU=decm\n";
    header += "VX=" + real(volume.spacing[0]) + "\nVY=" + real(volume.spacing[1]) + "\nVZ=" +
              real(volume.spacing[2]) + "\n";
    header += "XO=" + real(volume.origin[0]) + "\nYO=" + real(volume.origin[1]) + "\nZO=" +
              real(volume.origin[2]) + "\n";
    const size_t total = ((header.size() + 4 + 255) / 256) * 256;
    header.append(total - 4 - header.size(), '\n');
    header += "##}\n";
    writeAtomic(path, [&](auto& write) {
        write(header.data(), header.size());
        writeFloatsLE(write, volume.data);
    });
}

bool isReadableVolumeFile(const std::string& path)
{
    const auto f = volumeio_internal::formatFromExtension(path);
    return f != volumeio_internal::Format::Unknown && f != volumeio_internal::Format::Raw;
}

std::vector<std::string> readableVolumeExtensions()
{
    return {".nii", ".nii.gz", ".inr", ".inr.gz", ".den", ".vdb"};
}

} // namespace levelforge
