// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief The pre-scan of a .vdb file's header, metadata and grid descriptors (see
///        VdbHeaderCheck.h).
#include "io/VdbHeaderCheck.h"

#include <levelforge/core/Exceptions.h>

#include "detail/MessageText.h"

#include <cstring>
#include <filesystem>
#include <fstream>
#include <string_view>

namespace levelforge::vdbio_internal {

namespace {

using message_internal::groupedCount;
using message_internal::quotedExcerpt;

constexpr int64_t kVdbMagic = 0x56444220;
constexpr uint32_t kOldestReadableVersion = 221;   // OPENVDB_FILE_VERSION_FLOAT_FRUSTUM_BBOX
constexpr uint32_t kSelectiveCompression = 220;    // a compression char follows the flag
constexpr uint32_t kNodeMaskCompression = 222;     // per-grid compression (uint32)
constexpr uint64_t kUuidChars = 36;

/// Size in bytes of the value of each fixed-size metadata type (TypedMetadata<T>: OpenVDB
/// reads sizeof(T) bytes whatever the file declares, so another declared size means the
/// file is corrupt).
uint64_t fixedMetadataSize(std::string_view type)
{
    struct Entry
    {
        const char* name;
        uint64_t bytes;
    };
    static const Entry kTypes[] = {
        {"bool", 1},    {"half", 2},    {"float", 4},   {"double", 8},  {"int8", 1},    {"uint8", 1},
        {"int16", 2},   {"uint16", 2},  {"int32", 4},   {"uint32", 4},  {"int64", 8},   {"vec2i", 8},
        {"vec2s", 8},   {"vec2d", 16},  {"vec3u8", 3},  {"vec3u16", 6}, {"vec3i", 12},  {"vec3s", 12},
        {"vec3d", 24},  {"vec4i", 16},  {"vec4s", 16},  {"vec4d", 32},  {"mat3s", 36},  {"mat3d", 72},
        {"mat4s", 64},  {"mat4d", 128}, {"quats", 16},  {"quatd", 32}};
    for (const Entry& e : kTypes) {
        if (type == e.name) return e.bytes;
    }
    return 0;
}

/// A bounds-checked reader of the file: every length is compared with the bytes left in the
/// current region before anything is read or skipped; nothing is allocated from a length.
class Scanner
{
public:
    explicit Scanner(const std::string& path) : mPath(path)
    {
        std::error_code ec;
        const auto size = std::filesystem::file_size(path, ec);
        if (ec) throw IoError("cannot read '" + path + "': " + ec.message());
        mSize = uint64_t(size);
        mLimit = mSize;
        mIn.open(path, std::ios::binary);
        if (!mIn) throw IoError("cannot read '" + path + "': cannot open the file");
    }

    uint64_t size() const { return mSize; }
    uint64_t pos() const { return mPos; }
    uint64_t left() const { return mLimit > mPos ? mLimit - mPos : 0; }

    /// Reads are confined to [pos, limit) from now on; @p region names it in messages.
    void setRegion(uint64_t limit, std::string region)
    {
        mLimit = limit;
        mRegion = std::move(region);
    }

    void seek(uint64_t pos)
    {
        mPos = pos;
        mIn.clear();
        mIn.seekg(std::streamoff(pos));
        if (!mIn) fail("cannot seek to byte " + groupedCount(pos));
    }

    [[noreturn]] void fail(const std::string& what) const
    {
        throw IoError("cannot read '" + mPath + "': corrupt VDB file: " + what);
    }

    /// Throws unless @p bytes are left; @p what names the field that claims them.
    void need(uint64_t bytes, const std::string& what) const
    {
        if (bytes <= left()) return;
        fail(what + " claims " + groupedCount(bytes) + (bytes == 1 ? " byte" : " bytes") + " but only " +
             groupedCount(left()) + (left() == 1 ? " byte is" : " bytes are") + " left in " + mRegion +
             " (at byte " + groupedCount(mPos) + " of " + groupedCount(mSize) + ")");
    }

    void readRaw(void* dst, uint64_t n, const std::string& what)
    {
        if (n > left()) {
            fail("the file ends inside " + what + " (at byte " + groupedCount(mPos) + " of " + groupedCount(mSize) +
                 ")");
        }
        mIn.read(static_cast<char*>(dst), std::streamsize(n));
        if (uint64_t(mIn.gcount()) != n) fail("cannot read " + what + " at byte " + groupedCount(mPos));
        mPos += n;
    }

    template<typename T>
    T read(const std::string& what)
    {
        T v;
        readRaw(&v, sizeof(T), what);
        return v;
    }

    void skip(uint64_t n, const std::string& what)
    {
        need(n, what);
        seek(mPos + n);
    }

    /// A string as OpenVDB stores it (uint32 length + characters); returns at most its first
    /// 64 characters (for messages and type names), skips the rest.
    std::string readString(const std::string& what)
    {
        const uint32_t n = read<uint32_t>("the length of " + what);
        need(n, what);
        std::string head(std::min<uint64_t>(n, 64), '\0');
        if (!head.empty()) readRaw(head.data(), head.size(), what);
        if (n > head.size()) seek(mPos + (n - head.size()));
        return head;
    }

private:
    std::string mPath;
    std::ifstream mIn;
    uint64_t mSize = 0;
    uint64_t mPos = 0;
    uint64_t mLimit = 0;
    std::string mRegion = "the file";
};

/// Checks a Blosc header at the start of a @p bytes-byte compressed buffer that must
/// decompress to @p expected bytes (OpenVDB reserves what the header says, then decompresses).
void checkBloscHeader(Scanner& s, uint32_t bytes, uint64_t expected, const std::string& what)
{
    if (bytes < 16) s.fail(what + ": a " + groupedCount(bytes) + "-byte Blosc buffer is shorter than its header");
    unsigned char h[16];
    s.readRaw(h, 16, what);
    auto u32 = [&](int at) {
        return uint32_t(h[at]) | (uint32_t(h[at + 1]) << 8) | (uint32_t(h[at + 2]) << 16) | (uint32_t(h[at + 3]) << 24);
    };
    const uint32_t nbytes = u32(4), blocksize = u32(8), cbytes = u32(12);
    if (nbytes != expected) {
        s.fail(what + ": the Blosc header claims " + groupedCount(nbytes) + " bytes once decompressed, " +
               groupedCount(expected) + " expected");
    }
    if (cbytes != bytes) {
        s.fail(what + ": the Blosc header claims " + groupedCount(cbytes) + " compressed bytes, the buffer holds " +
               groupedCount(bytes));
    }
    if (nbytes > 0 && (blocksize == 0 || blocksize > nbytes)) {
        s.fail(what + ": the Blosc block size " + groupedCount(blocksize) + " does not fit " + groupedCount(nbytes) +
               " bytes");
    }
    const bool memcpyed = (h[2] & 0x2) != 0;
    if (!memcpyed && nbytes > 0) {
        const uint64_t blocks = (uint64_t(nbytes) + blocksize - 1) / blocksize;
        if (16 + 4 * blocks > cbytes) s.fail(what + ": the Blosc block table does not fit the buffer");
    }
    s.seek(s.pos() + (bytes - 16));
}

/// The value of a "__delayedload" entry (DelayedLoadMetadata::readValue): leaf count, a mask
/// of one byte per leaf (raw or Blosc) and, unless its size is 0xffffffff, one int64 per leaf
/// (raw or Blosc), all within the @p numBytes the entry declares.
void checkDelayedLoad(Scanner& s, uint32_t numBytes, const std::string& what)
{
    if (numBytes == 0) return;
    const uint64_t end = s.pos() + numBytes;
    const uint32_t count = s.read<uint32_t>(what + ": its leaf count");
    // Every leaf costs the file more than one byte (its 64-byte value mask, at least).
    if (count > s.size()) {
        s.fail(what + " claims " + groupedCount(count) + " leaves in a file of " + groupedCount(s.size()) + " bytes");
    }
    const uint32_t maskBytes = s.read<uint32_t>(what + ": the size of its mask");
    if (maskBytes > 0) {
        s.need(maskBytes, what + ": its compressed mask");
        checkBloscHeader(s, maskBytes, count, what + ": its compressed mask");
    } else {
        s.skip(count, what + ": its mask of " + groupedCount(count) + " leaves");
    }
    const uint32_t sizeBytes = s.read<uint32_t>(what + ": the size of its leaf sizes");
    if (sizeBytes != UINT32_MAX) {
        if (sizeBytes > 0) {
            s.need(sizeBytes, what + ": its compressed leaf sizes");
            checkBloscHeader(s, sizeBytes, uint64_t(count) * 8, what + ": its compressed leaf sizes");
        } else {
            s.skip(uint64_t(count) * 8, what + ": its leaf sizes (" + groupedCount(count) + " int64)");
        }
    }
    if (s.pos() > end) {
        s.fail(what + " holds " + groupedCount(s.pos() - (end - numBytes)) + " bytes but declares " +
               groupedCount(numBytes));
    }
    s.seek(end);
}

/// A metadata map (MetaMap::readMeta) within the scanner's region; @p owner names it.
void checkMetaMap(Scanner& s, const std::string& owner)
{
    const uint32_t count = s.read<uint32_t>("the entry count of " + owner);
    // Each entry holds at least a name length, a type-name length and a value size.
    if (uint64_t(count) * 12 > s.left()) {
        s.fail("the " + owner + " claims " + groupedCount(count) + " entries (at least " +
               groupedCount(uint64_t(count) * 12) + " bytes) but only " + groupedCount(s.left()) + " bytes are left");
    }
    for (uint32_t i = 0; i < count; ++i) {
        const std::string entry = owner + " entry " + std::to_string(i);
        const std::string name = s.readString("the name of " + entry);
        const std::string named = entry + " (" + quotedExcerpt(name) + ")";
        const std::string type = s.readString("the type name of " + named);
        const std::string typed = named + " of type " + quotedExcerpt(type);
        const uint32_t numBytes = s.read<uint32_t>("the value size of " + typed);
        s.need(numBytes, "the value of " + typed);
        if (type == "__delayedload") {
            checkDelayedLoad(s, numBytes, "the value of " + typed);
            continue;
        }
        const uint64_t fixed = fixedMetadataSize(type);
        if (fixed != 0 && numBytes != fixed) {
            s.fail("the value of " + typed + " claims " + groupedCount(numBytes) + " bytes, a " + type + " has " +
                   groupedCount(fixed));
        }
        s.seek(s.pos() + numBytes);
    }
}

} // namespace

VdbHeaderSummary checkVdbHeader(const std::string& path)
{
    VdbHeaderSummary out;
    Scanner s(path);
    out.fileBytes = s.size();
    if (s.size() < 8) {
        throw IoError("cannot read '" + path + "': not a VDB file (" + groupedCount(s.size()) +
                      " bytes, too short for the VDB magic number)");
    }
    if (s.read<int64_t>("the magic number") != kVdbMagic) {
        throw IoError("cannot read '" + path + "': not a VDB file (no VDB magic number)");
    }
    out.fileVersion = s.read<uint32_t>("the file format version");
    if (out.fileVersion < kOldestReadableVersion) {
        throw IoError("cannot read '" + path + "': VDB file format version " + std::to_string(out.fileVersion) +
                      " is older than 221, the oldest OpenVDB reads");
    }
    out.libraryMajor = s.read<uint32_t>("the library major version");
    out.libraryMinor = s.read<uint32_t>("the library minor version");
    out.hasGridOffsets = s.read<char>("the grid-offsets flag") != 0;
    if (out.fileVersion >= kSelectiveCompression && out.fileVersion < kNodeMaskCompression) {
        (void)s.read<char>("the compression flag");
    }
    s.skip(kUuidChars, "the UUID");
    checkMetaMap(s, "file metadata");
    if (!out.hasGridOffsets) return out; // grids follow their descriptors in a stream: not scanned

    const int32_t grids = s.read<int32_t>("the grid count");
    // A descriptor holds three string lengths and three int64 positions at least.
    if (grids < 0 || uint64_t(grids) * 36 > s.left()) {
        s.fail("the grid count " + std::to_string(grids) + " does not fit the " + groupedCount(s.left()) +
               " bytes left");
    }
    out.gridCount = grids;
    for (int32_t g = 0; g < grids; ++g) {
        const std::string gd = "grid descriptor " + std::to_string(g);
        const std::string name = s.readString("the name in " + gd);
        const std::string grid = "grid " + std::to_string(g) + " (" + quotedExcerpt(name) + ")";
        (void)s.readString("the grid type of " + grid);
        (void)s.readString("the instance parent of " + grid);
        const int64_t gridPos = s.read<int64_t>("the data position of " + grid);
        const int64_t blockPos = s.read<int64_t>("the block position of " + grid);
        const int64_t endPos = s.read<int64_t>("the end position of " + grid);
        if (gridPos < int64_t(s.pos()) || blockPos < gridPos || endPos < blockPos || uint64_t(endPos) > s.size()) {
            s.fail("the positions of " + grid + " (data " + std::to_string(gridPos) + ", blocks " +
                   std::to_string(blockPos) + ", end " + std::to_string(endPos) + ") are not ordered within the " +
                   groupedCount(s.size()) + "-byte file after its descriptor (byte " + groupedCount(s.pos()) + ")");
        }
        // The grid's own header: compression flags, metadata, transform type, all before its
        // data blocks.
        s.seek(uint64_t(gridPos));
        s.setRegion(uint64_t(blockPos), "the header of " + grid + " (bytes " + groupedCount(uint64_t(gridPos)) +
                                            " to " + groupedCount(uint64_t(blockPos)) + ")");
        if (out.fileVersion >= kNodeMaskCompression) (void)s.read<uint32_t>("the compression flags of " + grid);
        checkMetaMap(s, "metadata of " + grid);
        (void)s.readString("the transform type of " + grid);
        if (g == 0) out.firstTreeOffset = s.pos();
        s.seek(uint64_t(endPos));
        s.setRegion(s.size(), "the file");
    }
    return out;
}

} // namespace levelforge::vdbio_internal
