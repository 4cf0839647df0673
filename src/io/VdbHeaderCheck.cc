// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief The pre-scan of a whole .vdb file: header, metadata, grid descriptors, transforms,
///        tree topologies and voxel buffers (see VdbHeaderCheck.h for what is checked).
#include "io/VdbHeaderCheck.h"

#include <levelforge/core/Exceptions.h>

#include "detail/MessageText.h"

#include <openvdb/openvdb.h>
#include <openvdb/io/Compression.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <exception>
#include <sstream>
#include <string_view>
#include <vector>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

namespace levelforge::vdbio_internal {

namespace {

using message_internal::cutDependencyMessage;
using message_internal::groupedCount;
using message_internal::quotedExcerpt;

constexpr int64_t kVdbMagic = 0x56444220;
constexpr uint32_t kOldestOpenVdbVersion = 221;    // OPENVDB_FILE_VERSION_FLOAT_FRUSTUM_BBOX
constexpr uint32_t kSelectiveCompression = 220;    // a compression char follows the flag
constexpr uint32_t kNodeMaskCompression = 222;     // per-grid compression, per-node metadata byte
constexpr uint64_t kUuidChars = 36;
constexpr uint32_t kCompressZip = 0x1, kCompressActiveMask = 0x2, kCompressBlosc = 0x4;
constexpr uint64_t kBloscHeaderBytes = 16;         // BLOSC_MAX_OVERHEAD
constexpr size_t kBufferBytes = size_t(1) << 20;   // read-ahead of each cursor

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

std::string plural(uint64_t n, const char* one, const char* many)
{
    return groupedCount(n) + " " + (n == 1 ? one : many);
}

/// The file, opened once; the cursors below read it with pread() (no shared file position).
class VdbFile
{
public:
    explicit VdbFile(const std::string& path) : mPath(path)
    {
        mFd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
        if (mFd < 0) throw IoError("cannot read '" + path + "': " + std::strerror(errno));
        struct stat st{};
        if (::fstat(mFd, &st) != 0) {
            const int err = errno;
            ::close(mFd);
            throw IoError("cannot read '" + path + "': " + std::strerror(err));
        }
        mSize = uint64_t(st.st_size);
    }
    ~VdbFile() { ::close(mFd); }
    VdbFile(const VdbFile&) = delete;
    VdbFile& operator=(const VdbFile&) = delete;

    const std::string& path() const { return mPath; }
    uint64_t size() const { return mSize; }
    int fd() const { return mFd; }

private:
    std::string mPath;
    int mFd = -1;
    uint64_t mSize = 0;
};

/// A bounds-checked, buffered reader of the file: every length is compared with the bytes left
/// in the current region ([pos, limit)) before anything is read or skipped; nothing is
/// allocated from a length read from the file. Several cursors may read one file at once (the
/// tree scan walks the topology and the voxel buffers side by side).
class Scanner
{
public:
    Scanner(const VdbFile& file, uint64_t pos, uint64_t limit, std::string region)
        : mFile(file), mPos(pos), mLimit(std::min(limit, file.size())), mRegion(std::move(region))
    {
    }

    uint64_t size() const { return mFile.size(); }
    uint64_t pos() const { return mPos; }
    uint64_t limit() const { return mLimit; }
    uint64_t left() const { return mLimit > mPos ? mLimit - mPos : 0; }
    const std::string& region() const { return mRegion; }

    /// Reads are confined to [pos, limit) from now on; @p region names it in messages.
    void setRegion(uint64_t limit, std::string region)
    {
        mLimit = std::min(limit, mFile.size());
        mRegion = std::move(region);
    }

    void seek(uint64_t pos)
    {
        if (pos > mFile.size()) fail("cannot seek to byte " + groupedCount(pos));
        mPos = pos;
    }

    [[noreturn]] void fail(const std::string& what) const
    {
        throw IoError("cannot read '" + mFile.path() + "': corrupt VDB file: " + what);
    }

    /// Throws unless @p bytes are left; @p what names the field that claims them.
    void need(uint64_t bytes, const std::string& what) const
    {
        if (bytes > left()) failNeed(bytes, what);
    }

    [[noreturn]] void failNeed(uint64_t bytes, const std::string& what) const
    {
        fail(what + " claims " + plural(bytes, "byte", "bytes") + " but only " + groupedCount(left()) +
             (left() == 1 ? " byte is" : " bytes are") + " left in " + mRegion + " (at byte " + groupedCount(mPos) +
             " of " + groupedCount(mFile.size()) + ")");
    }

    [[noreturn]] void failEnds(const std::string& what) const
    {
        fail((mLimit >= mFile.size() ? std::string("the file") : mRegion) + " ends inside " + what + " (at byte " +
             groupedCount(mPos) + " of " + groupedCount(mFile.size()) + ", " + plural(left(), "byte", "bytes") +
             " left)");
    }

    /// The next @p n bytes (n <= kBufferBytes), valid until the next read; @p what (a callable
    /// returning the field's name) is evaluated only on failure.
    template<typename What>
    const unsigned char* view(uint64_t n, const What& what)
    {
        if (n > left()) failEnds(what());
        if (mPos < mBufStart || mPos + n > mBufStart + mBufLen) fill(n);
        const unsigned char* p = mBuf.data() + (mPos - mBufStart);
        mPos += n;
        return p;
    }

    template<typename What>
    void readInto(void* dst, uint64_t n, const What& what)
    {
        if (n > left()) failEnds(what());
        if (n <= kBufferBytes) {
            std::memcpy(dst, view(n, what), size_t(n));
            return;
        }
        readDirect(static_cast<unsigned char*>(dst), n);
    }

    void readRaw(void* dst, uint64_t n, const std::string& what)
    {
        readInto(dst, n, [&] { return what; });
    }

    template<typename T, typename What>
    T get(const What& what)
    {
        T v;
        std::memcpy(&v, view(sizeof(T), what), sizeof(T));
        return v;
    }

    template<typename T>
    T read(const std::string& what)
    {
        return get<T>([&] { return what; });
    }

    template<typename What>
    void skipBytes(uint64_t n, const What& what)
    {
        if (n > left()) failNeed(n, what());
        mPos += n;
    }

    void skip(uint64_t n, const std::string& what)
    {
        skipBytes(n, [&] { return what; });
    }

    /// A string as OpenVDB stores it (uint32 length + characters); returns at most its first
    /// @p keep characters (for messages and type names), skips the rest.
    std::string readString(const std::string& what, uint64_t keep = 64)
    {
        const uint32_t n = read<uint32_t>("the length of " + what);
        need(n, what);
        std::string head(size_t(std::min<uint64_t>(n, keep)), '\0');
        if (!head.empty()) readRaw(head.data(), head.size(), what);
        mPos += n - head.size();
        return head;
    }

private:
    void fill(uint64_t n)
    {
        if (mBuf.empty()) mBuf.resize(kBufferBytes);
        const uint64_t want = std::min<uint64_t>(kBufferBytes, mFile.size() - mPos);
        uint64_t got = 0;
        while (got < want) {
            const ssize_t r = ::pread(mFile.fd(), mBuf.data() + got, size_t(want - got), off_t(mPos + got));
            if (r < 0 && errno == EINTR) continue;
            if (r <= 0) break;
            got += uint64_t(r);
        }
        mBufStart = mPos;
        mBufLen = got;
        if (got < n) fail("cannot read byte " + groupedCount(mPos + got) + " (the file shrank while it was read?)");
    }

    void readDirect(unsigned char* dst, uint64_t n)
    {
        uint64_t got = 0;
        while (got < n) {
            const ssize_t r = ::pread(mFile.fd(), dst + got, size_t(n - got), off_t(mPos + got));
            if (r < 0 && errno == EINTR) continue;
            if (r <= 0) fail("cannot read byte " + groupedCount(mPos + got) + " (the file shrank while it was read?)");
            got += uint64_t(r);
        }
        mPos += n;
    }

    const VdbFile& mFile;
    uint64_t mPos = 0;
    uint64_t mLimit = 0;
    std::string mRegion;
    std::vector<unsigned char> mBuf;
    uint64_t mBufStart = 0;
    uint64_t mBufLen = 0;
};

/// Checks the 16-byte Blosc header @p h of a @p bytes-byte compressed buffer that must
/// decompress to @p expected bytes (OpenVDB hands Blosc the buffer without its length: Blosc
/// trusts the header's compressed size, so it must be the buffer's).
void checkBloscHeaderBytes(const Scanner& s, const unsigned char* h, uint64_t bytes, uint64_t expected,
                           const std::string& what, bool padSmall = false)
{
    auto u32 = [&](int at) {
        return uint32_t(h[at]) | (uint32_t(h[at + 1]) << 8) | (uint32_t(h[at + 2]) << 16) | (uint32_t(h[at + 3]) << 24);
    };
    const uint32_t nbytes = u32(4), blocksize = u32(8), cbytes = u32(12);
    // OpenVDB's compression::bloscCompress() (delayed-load metadata) pads 48 to 127 bytes to 128.
    const bool padded = padSmall && expected >= 48 && expected < 128 && nbytes == 128;
    if (nbytes != expected && !padded) {
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
        if (kBloscHeaderBytes + 4 * blocks > cbytes) s.fail(what + ": the Blosc block table does not fit the buffer");
    }
}

/// Checks a Blosc buffer of @p bytes bytes at the cursor and skips it.
void checkBloscHeader(Scanner& s, uint32_t bytes, uint64_t expected, const std::string& what, bool padSmall)
{
    if (bytes < kBloscHeaderBytes) {
        s.fail(what + ": a " + groupedCount(bytes) + "-byte Blosc buffer is shorter than its header");
    }
    s.need(bytes, what);
    const unsigned char* h = s.view(kBloscHeaderBytes, [&] { return what; });
    checkBloscHeaderBytes(s, h, bytes, expected, what, padSmall);
    s.seek(s.pos() + (bytes - kBloscHeaderBytes));
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
        checkBloscHeader(s, maskBytes, count, what + ": its compressed mask", true);
    } else {
        s.skip(count, what + ": its mask of " + groupedCount(count) + " leaves");
    }
    const uint32_t sizeBytes = s.read<uint32_t>(what + ": the size of its leaf sizes");
    if (sizeBytes != UINT32_MAX) {
        if (sizeBytes > 0) {
            checkBloscHeader(s, sizeBytes, uint64_t(count) * 8, what + ": its compressed leaf sizes", true);
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

/// What a metadata map says that matters to the tree's layout.
struct MetaInfo
{
    bool halfFloat = false; ///< the last "is_saved_as_half_float" entry (GridBase::saveFloatAsHalf())
};

/// A metadata map (MetaMap::readMeta) within the scanner's region; @p owner names it.
MetaInfo checkMetaMap(Scanner& s, const std::string& owner)
{
    MetaInfo info;
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
        const bool halfFlag = (name == "is_saved_as_half_float");
        if (halfFlag && type != "bool") {
            s.fail(typed + ": the half-float flag must be a bool");
        }
        if (type == "bool") {
            // Loaded as a C++ bool: any byte but 0 and 1 is undefined behaviour.
            const unsigned char b = s.get<unsigned char>([&] { return "the value of " + typed; });
            if (b > 1) s.fail("the value of " + typed + " is " + std::to_string(b) + ", not 0 or 1");
            if (halfFlag) info.halfFloat = (b == 1);
            continue;
        }
        s.seek(s.pos() + numBytes);
    }
    return info;
}

/// A grid's transform (math::Transform::read): the map's type name and its fixed-size data; a
/// frustum map holds its bounding box, taper, depth and a second (linear) map.
void checkTransform(Scanner& s, const std::string& grid, uint64_t* typeEnd)
{
    struct MapEntry
    {
        const char* name;
        uint64_t bytes;
    };
    // The double values each map's read() takes (AffineMap and UnitaryMap: a Mat4d; ScaleMap:
    // five Vec3d; ScaleTranslateMap: six Vec3d; TranslationMap: one Vec3d).
    static const MapEntry kMaps[] = {{"AffineMap", 128},         {"UnitaryMap", 128},
                                     {"ScaleMap", 120},          {"UniformScaleMap", 120},
                                     {"TranslationMap", 24},     {"ScaleTranslateMap", 144},
                                     {"UniformScaleTranslateMap", 144}};
    auto linearBytes = [&](const std::string& type) -> uint64_t {
        for (const MapEntry& m : kMaps) {
            if (type == m.name) return m.bytes;
        }
        return 0;
    };
    const std::string type = s.readString("the transform type of " + grid);
    if (typeEnd) *typeEnd = s.pos();
    if (type == "NonlinearFrustumMap") {
        s.skip(48 + 8 + 8, "the frustum of " + grid);
        const std::string second = s.readString("the second map type of the frustum of " + grid);
        const uint64_t bytes = linearBytes(second);
        if (bytes == 0) {
            s.fail("the frustum transform of " + grid + " has a second map of type " + quotedExcerpt(second) +
                   ", not a linear map OpenVDB knows");
        }
        s.skip(bytes, "the second map of the frustum of " + grid);
        return;
    }
    const uint64_t bytes = linearBytes(type);
    if (bytes == 0) {
        s.fail("the transform of " + grid + " has type " + quotedExcerpt(type) + ", not a map type OpenVDB knows");
    }
    s.skip(bytes, "the " + type + " of " + grid);
}

// ------------------------------------------------------------------------- tree topology

/// How a tree of one value type is laid out (Tree_<type>_5_4_3).
struct ValueLayout
{
    enum Leaf { kValues, kBool, kMask };
    const char* name;   ///< OpenVDB's type name in the grid type
    uint32_t bytes;     ///< sizeof(ValueType) of the root and internal nodes (and value leaves)
    uint32_t halfBytes; ///< bytes of a value saved as half float; 0: never converted
    bool isBool;        ///< values are C++ bools: bytes other than 0 and 1 are undefined behaviour
    Leaf leaf;
};

const ValueLayout* findLayout(std::string_view treeType)
{
    static const ValueLayout kLayouts[] = {
        {"float", 4, 2, false, ValueLayout::kValues},  {"double", 8, 2, false, ValueLayout::kValues},
        {"int32", 4, 0, false, ValueLayout::kValues},  {"int64", 8, 0, false, ValueLayout::kValues},
        {"vec3s", 12, 6, false, ValueLayout::kValues}, {"vec3d", 24, 6, false, ValueLayout::kValues},
        {"vec3i", 12, 0, false, ValueLayout::kValues}, {"bool", 1, 0, true, ValueLayout::kBool},
        {"mask", 1, 0, true, ValueLayout::kMask}};
    for (const ValueLayout& l : kLayouts) {
        if (treeType == std::string("Tree_") + l.name + "_5_4_3") return &l;
    }
    return nullptr;
}

struct Coord3
{
    int32_t x, y, z;
    bool operator<(const Coord3& o) const
    {
        return x != o.x ? x < o.x : y != o.y ? y < o.y : z < o.z;
    }
    bool operator==(const Coord3& o) const { return x == o.x && y == o.y && z == o.z; }
};

std::string coordText(const Coord3& c)
{
    return "(" + std::to_string(c.x) + ", " + std::to_string(c.y) + ", " + std::to_string(c.z) + ")";
}

/// The state of one grid's tree scan: the topology cursor and, in the full pass, the buffer
/// cursor, which walks the voxel buffers in the order OpenVDB reads them (depth first, root
/// children in key order: the topology's order, since the keys must be ascending).
struct TreeScan
{
    const ValueLayout& v;
    bool half;            ///< internal and leaf values are stored as half floats
    uint32_t compression; ///< the grid's compression flags
    std::string grid;     ///< "grid 0 ('name')"
    Scanner& topo;
    Scanner* bufs;        ///< null: topology only
    uint64_t leaves = 0, internals = 0, tiles = 0;
    std::vector<uint64_t> childMask[2], valueMask[2];
    std::vector<unsigned char> chunk, values;
};

std::string nodeName(const char* kind, const Coord3& c) { return std::string(kind) + " at " + coordText(c); }

bool maskOverlaps(const uint64_t* a, const uint64_t* b, size_t words)
{
    uint64_t any = 0;
    for (size_t i = 0; i < words; ++i) any |= a[i] & b[i];
    return any != 0;
}

uint64_t countOn(const uint64_t* m, size_t words)
{
    uint64_t n = 0;
    for (size_t i = 0; i < words; ++i) n += uint64_t(__builtin_popcountll(m[i]));
    return n;
}

void checkBoolBytes(const TreeScan& t, const unsigned char* p, uint64_t n, const std::string& what)
{
    for (uint64_t i = 0; i < n; ++i) {
        if (p[i] > 1) {
            t.topo.fail(t.grid + ": " + what + " holds the byte " + std::to_string(p[i]) + " for a bool value");
        }
    }
}

/// One chunk of values as readData() reads it: raw, or an int64 size and a zip / Blosc stream
/// (size <= 0: -size stored bytes). @p bytes is what the chunk must decompress to. With
/// @p verify (internal nodes, read inside OpenVDB's readTopology, where an exception leaks the
/// node being read) the chunk is decompressed by OpenVDB's own routine, so that it cannot throw
/// there; bool values are checked to be 0 or 1.
template<typename NodeName>
void scanChunk(TreeScan& t, Scanner& s, uint64_t bytes, const NodeName& node, bool verify, bool boolValues)
{
    const bool blosc = (t.compression & kCompressBlosc) != 0;
    const bool zip = !blosc && (t.compression & kCompressZip) != 0;
    if (!blosc && !zip) {
        if (verify && boolValues) {
            t.values.resize(size_t(bytes) + 1);
            s.readInto(t.values.data(), bytes, [&] { return t.grid + ": the values of " + node(); });
            checkBoolBytes(t, t.values.data(), bytes, "the values of " + node());
        } else {
            s.skipBytes(bytes, [&] { return t.grid + ": the " + plural(bytes, "value byte", "value bytes") + " of " + node(); });
        }
        return;
    }
    const char* kind = blosc ? "Blosc" : "zip";
    const int64_t n = s.get<int64_t>([&] { return t.grid + ": the " + kind + " chunk size of " + node(); });
    if (n <= 0) {
        const uint64_t stored = n == INT64_MIN ? uint64_t(INT64_MAX) + 1 : uint64_t(-n);
        if (stored != bytes) {
            s.fail(t.grid + ": " + node() + " declares a stored (uncompressed) " + kind + " chunk of " +
                   plural(stored, "byte", "bytes") + ", its values take " + plural(bytes, "byte", "bytes"));
        }
        if (verify && boolValues) {
            t.values.resize(size_t(bytes) + 1);
            s.readInto(t.values.data(), bytes, [&] { return t.grid + ": the stored values of " + node(); });
            checkBoolBytes(t, t.values.data(), bytes, "the values of " + node());
        } else {
            s.skipBytes(bytes, [&] { return t.grid + ": the stored " + kind + " chunk of " + node(); });
        }
        return;
    }
    const uint64_t un = uint64_t(n);
    const uint64_t most = blosc ? bytes + kBloscHeaderBytes : bytes;
    if (un > most) {
        s.fail(t.grid + ": " + node() + " declares a " + kind + " chunk of " + plural(un, "byte", "bytes") +
               ", more than the " + groupedCount(most) + " its values can take" +
               (blosc ? " (" + groupedCount(bytes) + " + a 16-byte header)" : std::string()));
    }
    if (un > s.left()) {
        s.fail(t.grid + ": " + node() + " declares a " + kind + " chunk of " + plural(un, "byte", "bytes") +
               ", more than the " + groupedCount(s.left()) + " bytes left in " + s.region());
    }
    if (blosc && un < kBloscHeaderBytes) {
        s.fail(t.grid + ": " + node() + " declares a " + groupedCount(un) +
               "-byte Blosc chunk, shorter than its 16-byte header");
    }
    if (!verify) {
        if (blosc) {
            const unsigned char* h = s.view(kBloscHeaderBytes, [&] { return t.grid + ": the Blosc chunk of " + node(); });
            checkBloscHeaderBytes(s, h, un, bytes, t.grid + ": the Blosc chunk of " + node());
            s.skipBytes(un - kBloscHeaderBytes, [&] { return t.grid + ": the Blosc chunk of " + node(); });
        } else {
            s.skipBytes(un, [&] { return t.grid + ": the zip chunk of " + node(); });
        }
        return;
    }
    // Decompress it as OpenVDB will: its size field and its bytes, through the same routine.
    t.chunk.resize(size_t(un) + 8);
    std::memcpy(t.chunk.data(), &n, 8);
    s.readInto(t.chunk.data() + 8, un, [&] { return t.grid + ": the " + std::string(kind) + " chunk of " + node(); });
    if (blosc) checkBloscHeaderBytes(s, t.chunk.data() + 8, un, bytes, t.grid + ": the Blosc chunk of " + node());
    t.values.resize(size_t(bytes) + 1);
    try {
        std::istringstream in(std::string(reinterpret_cast<const char*>(t.chunk.data()), t.chunk.size()));
        if (blosc) {
            openvdb::io::bloscFromStream(in, reinterpret_cast<char*>(t.values.data()), size_t(bytes));
        } else {
            openvdb::io::unzipFromStream(in, reinterpret_cast<char*>(t.values.data()), size_t(bytes));
        }
    } catch (const std::exception& e) {
        s.fail(t.grid + ": the " + kind + " chunk of " + node() + " does not decompress to its " +
               plural(bytes, "byte", "bytes") + " (" + cutDependencyMessage(e.what(), 200) + ")");
    }
    if (boolValues) checkBoolBytes(t, t.values.data(), bytes, "the values of " + node());
}

/// A node's values as readCompressedValues() reads them: the metadata byte (0..6), up to two
/// inactive values, a selection mask, then the active values (or all of them), maybe as half
/// floats, in one chunk.
template<typename NodeName>
void scanValues(TreeScan& t, Scanner& s, uint32_t numValues, const uint64_t* valueMask, const NodeName& node,
                bool verify)
{
    const int8_t meta = s.get<int8_t>([&] { return t.grid + ": the compression byte of " + node(); });
    if (meta < 0 || meta > 6) {
        s.fail(t.grid + ": the compression byte of " + node() + " is " + std::to_string(int(meta)) +
               ", not one of 0 to 6");
    }
    if (meta == 2 || meta == 4 || meta == 5) {
        const int inactive = meta == 5 ? 2 : 1;
        for (int i = 0; i < inactive; ++i) {
            const unsigned char* p = s.view(t.v.bytes, [&] { return t.grid + ": the inactive values of " + node(); });
            if (t.v.isBool && *p > 1) checkBoolBytes(t, p, 1, "an inactive value of " + node());
        }
    }
    if (meta == 3 || meta == 4 || meta == 5) {
        s.skipBytes(numValues / 8, [&] { return t.grid + ": the selection mask of " + node(); });
    }
    const bool maskCompressed = (t.compression & kCompressActiveMask) != 0;
    const uint64_t count = (maskCompressed && meta != 6) ? countOn(valueMask, numValues / 64) : numValues;
    const bool half = t.half && t.v.halfBytes != 0;
    if (half && count == 0) return; // HalfReader reads nothing for no values
    const uint64_t bytes = count * (half ? t.v.halfBytes : t.v.bytes);
    scanChunk(t, s, bytes, node, verify, t.v.isBool);
}

template<typename NodeName>
void readMask(TreeScan& t, Scanner& s, std::vector<uint64_t>& words, uint32_t numValues, const NodeName& what)
{
    words.resize(numValues / 64);
    s.readInto(words.data(), numValues / 8, what);
}

void scanLeaf(TreeScan& t, const Coord3& origin)
{
    auto node = [&] { return nodeName("leaf node", origin); };
    uint64_t mask[8];
    t.topo.readInto(mask, 64, [&] { return t.grid + ": the mask of " + node(); });
    ++t.leaves;
    if (!t.bufs) return;
    Scanner& b = *t.bufs;
    const unsigned char* again = b.view(64, [&] { return t.grid + ": the buffer of " + node(); });
    if (std::memcmp(again, mask, 64) != 0) {
        b.fail(t.grid + ": the mask in the buffer of " + node() + " differs from the one in its topology");
    }
    if (t.v.leaf == ValueLayout::kValues) {
        scanValues(t, b, 512, mask, node, /*verify=*/false);
        return;
    }
    Coord3 stored;
    std::memcpy(&stored, b.view(12, [&] { return t.grid + ": the origin in the buffer of " + node(); }), 12);
    if (!(stored == origin)) {
        b.fail(t.grid + ": the buffer of " + node() + " gives its origin as " + coordText(stored));
    }
    if (t.v.leaf == ValueLayout::kBool) {
        b.skipBytes(64, [&] { return t.grid + ": the values of " + node(); });
    }
}

void scanInternal(TreeScan& t, int level, const Coord3& origin)
{
    const uint32_t log2 = level == 0 ? 5 : 4;
    const uint32_t numValues = 1u << (3 * log2);
    const uint32_t childTotal = level == 0 ? 7 : 3;
    auto node = [&] { return nodeName("internal node", origin); };
    std::vector<uint64_t>& children = t.childMask[level];
    std::vector<uint64_t>& active = t.valueMask[level];
    readMask(t, t.topo, children, numValues, [&] { return t.grid + ": the child mask of " + node(); });
    readMask(t, t.topo, active, numValues, [&] { return t.grid + ": the value mask of " + node(); });
    if (maskOverlaps(children.data(), active.data(), children.size())) {
        t.topo.fail(t.grid + ": " + node() + " has entries marked both as a child and as an active tile");
    }
    ++t.internals;
    scanValues(t, t.topo, numValues, active.data(), node, /*verify=*/true);
    // Each child takes bytes of the topology: the loop ends at the file's end at the latest.
    const uint32_t dimMask = (1u << log2) - 1;
    for (size_t w = 0; w < children.size(); ++w) {
        for (uint64_t bits = children[w]; bits != 0; bits &= bits - 1) {
            const uint32_t i = uint32_t(w * 64 + size_t(__builtin_ctzll(bits)));
            const Coord3 child{origin.x + int32_t((i >> (2 * log2)) << childTotal),
                               origin.y + int32_t(((i >> log2) & dimMask) << childTotal),
                               origin.z + int32_t((i & dimMask) << childTotal)};
            if (level == 0) {
                scanInternal(t, 1, child);
            } else {
                scanLeaf(t, child);
            }
        }
    }
}

/// Tree::readTopology: the buffer count, then RootNode::readTopology.
void scanTree(TreeScan& t)
{
    Scanner& s = t.topo;
    const int32_t bufferCount = s.read<int32_t>("the buffer count of " + t.grid);
    if (bufferCount != 1) s.fail("the tree of " + t.grid + " has " + std::to_string(bufferCount) + " buffers, not 1");
    const unsigned char* bg = s.view(t.v.bytes, [&] { return "the background value of " + t.grid; });
    if (t.v.isBool && *bg > 1) checkBoolBytes(t, bg, 1, "the background value");
    const uint32_t numTiles = s.read<uint32_t>("the root tile count of " + t.grid);
    const uint32_t numChildren = s.read<uint32_t>("the root child count of " + t.grid);
    const uint64_t tileBytes = 12 + uint64_t(t.v.bytes) + 1;
    const uint64_t childBytes = 12 + 2 * 4096 + 1; // origin, two masks, compression byte
    if (uint64_t(numTiles) * tileBytes + uint64_t(numChildren) * childBytes > s.left()) {
        s.fail("the root of " + t.grid + " claims " + plural(numTiles, "tile", "tiles") + " and " +
               plural(numChildren, "child", "children") + " (at least " +
               groupedCount(uint64_t(numTiles) * tileBytes + uint64_t(numChildren) * childBytes) +
               " bytes) but only " + groupedCount(s.left()) + " bytes are left in " + s.region());
    }
    // Root keys are multiples of the child size (4096), ascending (OpenVDB writes its std::map
    // in order; a repeated child key would leak the first child).
    auto aligned = [](const Coord3& c) { return ((c.x | c.y | c.z) & 4095) == 0; };
    std::vector<Coord3> tileKeys;
    tileKeys.reserve(numTiles);
    for (uint32_t i = 0; i < numTiles; ++i) {
        auto tile = [&] { return "root tile " + std::to_string(i) + " of " + t.grid; };
        Coord3 key;
        std::memcpy(&key, s.view(12, tile), 12);
        const unsigned char* value = s.view(t.v.bytes, tile);
        if (t.v.isBool && *value > 1) checkBoolBytes(t, value, 1, "root tile " + std::to_string(i) + "'s value");
        const unsigned char activeByte = s.get<unsigned char>(tile);
        if (activeByte > 1) {
            s.fail(t.grid + ": root tile " + std::to_string(i) + " at " + coordText(key) + " has the active flag " +
                   std::to_string(activeByte) + ", not 0 or 1");
        }
        if (!aligned(key)) s.fail(t.grid + ": root tile " + std::to_string(i) + " at " + coordText(key) + " is not at a multiple of 4096");
        if (i > 0 && !(tileKeys.back() < key)) {
            s.fail(t.grid + ": root tile " + std::to_string(i) + " at " + coordText(key) + " does not follow " +
                   coordText(tileKeys.back()) + " (the keys must ascend)");
        }
        tileKeys.push_back(key);
    }
    t.tiles += numTiles;
    size_t nextTile = 0;
    Coord3 previous{};
    for (uint32_t i = 0; i < numChildren; ++i) {
        Coord3 key;
        std::memcpy(&key, s.view(12, [&] { return "the origin of root child " + std::to_string(i) + " of " + t.grid; }), 12);
        if (!aligned(key)) s.fail(t.grid + ": root child " + std::to_string(i) + " at " + coordText(key) + " is not at a multiple of 4096");
        if (i > 0 && !(previous < key)) {
            s.fail(t.grid + ": root child " + std::to_string(i) + " at " + coordText(key) + " does not follow " +
                   coordText(previous) + " (the keys must ascend)");
        }
        while (nextTile < tileKeys.size() && tileKeys[nextTile] < key) ++nextTile;
        if (nextTile < tileKeys.size() && tileKeys[nextTile] == key) {
            s.fail(t.grid + ": root child " + std::to_string(i) + " at " + coordText(key) + " is also a root tile");
        }
        previous = key;
        scanInternal(t, 0, key);
    }
}

} // namespace

VdbHeaderSummary checkVdbHeader(const std::string& path)
{
    VdbHeaderSummary out;
    const VdbFile file(path);
    Scanner s(file, 0, file.size(), "the file");
    out.fileBytes = s.size();
    if (s.size() < 8) {
        throw IoError("cannot read '" + path + "': not a VDB file (" + groupedCount(s.size()) +
                      " bytes, too short for the VDB magic number)");
    }
    if (s.read<int64_t>("the magic number") != kVdbMagic) {
        throw IoError("cannot read '" + path + "': not a VDB file (no VDB magic number)");
    }
    out.fileVersion = s.read<uint32_t>("the file format version");
    if (out.fileVersion < kOldestOpenVdbVersion) {
        throw IoError("cannot read '" + path + "': VDB file format version " + std::to_string(out.fileVersion) +
                      " is older than 221, the oldest OpenVDB reads");
    }
    if (out.fileVersion < kNodeMaskCompression) {
        throw IoError("cannot read '" + path + "': VDB file format version " + std::to_string(out.fileVersion) +
                      " (OpenVDB 1.x) is not supported; levelforge reads versions 222 (OpenVDB 2.0) and later");
    }
    out.libraryMajor = s.read<uint32_t>("the library major version");
    out.libraryMinor = s.read<uint32_t>("the library minor version");
    out.hasGridOffsets = s.read<char>("the grid-offsets flag") != 0;
    if (out.fileVersion >= kSelectiveCompression && out.fileVersion < kNodeMaskCompression) {
        (void)s.read<char>("the compression flag");
    }
    s.skip(kUuidChars, "the UUID");
    checkMetaMap(s, "file metadata");

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
        std::string type = s.readString("the grid type of " + grid, 256);
        const std::string parent = s.readString("the instance parent of " + grid);
        const bool instance = !parent.empty();
        const int64_t gridPos = s.read<int64_t>("the data position of " + grid);
        const int64_t blockPos = s.read<int64_t>("the block position of " + grid);
        const int64_t endPos = s.read<int64_t>("the end position of " + grid);
        const std::string kHalfSuffix = "_HalfFloat";
        if (type.size() > kHalfSuffix.size() && type.compare(type.size() - kHalfSuffix.size(), kHalfSuffix.size(), kHalfSuffix) == 0) {
            type.resize(type.size() - kHalfSuffix.size());
        }
        const ValueLayout* layout = findLayout(type);
        if (!layout) {
            // OpenVDB refuses a type it does not know (GridDescriptor::read); a registered type
            // levelforge does not scan (point grids) would be read unchecked.
            openvdb::initialize();
            if (!openvdb::GridBase::isRegistered(type)) return out;
            s.fail(grid + " is of type " + quotedExcerpt(type) + ", which levelforge does not read (" +
                   "scalar, vector, bool and mask grids only)");
        }
        uint64_t dataEnd = s.size(); // where the grid's header, transform and topology must end
        uint64_t blocks = 0, end = 0;
        if (out.hasGridOffsets) {
            const bool ordered = gridPos >= int64_t(s.pos()) && endPos >= gridPos && uint64_t(endPos) <= s.size() &&
                                 (instance || (blockPos >= gridPos && endPos >= blockPos));
            if (!ordered) {
                s.fail("the positions of " + grid + " (data " + std::to_string(gridPos) + ", blocks " +
                       std::to_string(blockPos) + ", end " + std::to_string(endPos) + ") are not ordered within the " +
                       groupedCount(s.size()) + "-byte file after its descriptor (byte " + groupedCount(s.pos()) + ")");
            }
            s.seek(uint64_t(gridPos));
            blocks = instance ? uint64_t(endPos) : uint64_t(blockPos);
            end = uint64_t(endPos);
            dataEnd = blocks;
            s.setRegion(dataEnd, "the header of " + grid + " (bytes " + groupedCount(uint64_t(gridPos)) + " to " +
                                     groupedCount(dataEnd) + ")");
        } else {
            s.setRegion(s.size(), "the file (" + grid + ")");
        }
        // The grid's own header: compression flags, metadata, transform, all before its tree.
        const uint32_t compression = s.read<uint32_t>("the compression flags of " + grid);
        if (compression > (kCompressZip | kCompressActiveMask | kCompressBlosc)) {
            s.fail("the compression flags of " + grid + " are " + std::to_string(compression) +
                   ", not a combination of zip (1), active mask (2) and Blosc (4)");
        }
        const MetaInfo meta = checkMetaMap(s, "metadata of " + grid);
        uint64_t typeEnd = 0;
        checkTransform(s, grid, &typeEnd);
        if (g == 0) out.firstTreeOffset = typeEnd;
        if (instance) {
            // A grid that shares another grid's tree: no topology and no buffers.
            if (out.hasGridOffsets) s.seek(end);
            s.setRegion(s.size(), "the file");
            continue;
        }
        const uint64_t treeStart = s.pos();
        const std::string topoRegion = "the topology of " + grid;
        const std::string bufRegion = "the voxel buffers of " + grid;
        auto scan = [&](Scanner& topo, Scanner* bufs) {
            TreeScan t{*layout, meta.halfFloat, compression, grid, topo, bufs, 0, 0, 0, {}, {}, {}, {}};
            scanTree(t);
            out.leafCount += t.leaves;
            out.internalNodeCount += t.internals;
            out.rootTileCount += t.tiles;
        };
        if (!out.hasGridOffsets) {
            // The buffers follow the topology: find its end first, then walk both.
            Scanner topo(file, treeStart, s.size(), topoRegion);
            {
                TreeScan t{*layout, meta.halfFloat, compression, grid, topo, nullptr, 0, 0, 0, {}, {}, {}, {}};
                scanTree(t);
            }
            blocks = topo.pos();
            end = s.size();
        }
        Scanner topo(file, treeStart, blocks, topoRegion + " (bytes " + groupedCount(treeStart) + " to " + groupedCount(blocks) + ")");
        Scanner bufs(file, blocks, end, bufRegion + " (bytes " + groupedCount(blocks) + " to " + groupedCount(end) + ")");
        scan(topo, &bufs);
        if (topo.pos() != blocks) {
            topo.fail("the topology of " + grid + " ends at byte " + groupedCount(topo.pos()) +
                      ", its descriptor puts the voxel buffers at byte " + groupedCount(blocks));
        }
        if (out.hasGridOffsets) {
            if (bufs.pos() != end) {
                bufs.fail("the voxel buffers of " + grid + " end at byte " + groupedCount(bufs.pos()) +
                          ", its descriptor puts the grid's end at byte " + groupedCount(end));
            }
            s.seek(end);
        } else {
            s.seek(bufs.pos());
        }
        s.setRegion(s.size(), "the file");
    }
    return out;
}

} // namespace levelforge::vdbio_internal
