// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief The parallel fast path of readMesh() (see MeshParseFast.h): mapped file, chunks split
///        at line boundaries, TBB over chunks, results concatenated in chunk order.
#include "io/MeshParseFast.h"
#include "io/MeshIOInternal.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <array>
#include <atomic>

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

namespace levelforge {

namespace meshio_internal {

namespace {

/// Bytes per chunk. Fixed (not derived from the thread count), so chunk boundaries and hence the
/// results are the same for any number of threads.
constexpr size_t kChunkBytes = size_t(1) << 20;

/// A read-only memory map of a whole file (empty for an empty file).
class MappedFile
{
public:
    explicit MappedFile(const std::string& path)
    {
        const int fd = ::open(path.c_str(), O_RDONLY);
        if (fd < 0) throw IoError("cannot open mesh file '" + path + "': " + std::strerror(errno));
        struct stat st;
        if (::fstat(fd, &st) != 0) {
            const int err = errno;
            ::close(fd);
            throw IoError("cannot read mesh file '" + path + "': " + std::strerror(err));
        }
        mSize = size_t(st.st_size);
        if (mSize > 0) {
            void* p = ::mmap(nullptr, mSize, PROT_READ, MAP_PRIVATE | MAP_POPULATE, fd, 0);
            if (p == MAP_FAILED) {
                const int err = errno;
                ::close(fd);
                throw IoError("cannot map mesh file '" + path + "': " + std::strerror(err));
            }
            mData = static_cast<const char*>(p);
        }
        ::close(fd);
    }
    ~MappedFile()
    {
        if (mData) ::munmap(const_cast<char*>(mData), mSize);
    }
    MappedFile(const MappedFile&) = delete;
    MappedFile& operator=(const MappedFile&) = delete;

    const char* data() const { return mData; }
    size_t size() const { return mSize; }

private:
    const char* mData = nullptr;
    size_t mSize = 0;
};

using Range = std::pair<size_t, size_t>;

/// [begin, end) cut into pieces of about kChunkBytes, each ending just after a '\n' (the last
/// one at @a end).
std::vector<Range> splitAtLines(const char* d, size_t begin, size_t end)
{
    std::vector<Range> chunks;
    size_t b = begin;
    while (b < end) {
        size_t e = b + kChunkBytes;
        if (e >= end) {
            e = end;
        } else {
            const void* nl = std::memchr(d + e, '\n', end - e);
            e = nl ? size_t(static_cast<const char*>(nl) - d) + 1 : end;
        }
        chunks.emplace_back(b, e);
        b = e;
    }
    return chunks;
}

/// Next line of [p, end) without its '\n'; advances @a p past it.
inline std::string_view nextLine(const char*& p, const char* end)
{
    const char* nl = static_cast<const char*>(std::memchr(p, '\n', size_t(end - p)));
    const char* e = nl ? nl : end;
    std::string_view line(p, size_t(e - p));
    p = nl ? nl + 1 : end;
    return line;
}

/// True when the first non-blank character of @a line is '\v' or '\f' (OpenMesh's trimming and
/// our tokenizer disagree on such lines).
inline bool oddLineStart(std::string_view line)
{
    for (char c : line) {
        if (c == ' ' || c == '\t' || c == '\r') continue;
        return c == '\v' || c == '\f';
    }
    return false;
}

/// A coordinate exactly as the pre-scan parses it, accepted only when it is finite, within the
/// float range and zero or of at least FLT_MIN magnitude (OpenMesh's stream reading may fail on
/// values that underflow a float).
inline bool plainCoordinate(std::string_view tok, double& v)
{
    if (parseCoordinate(tok, v) != NumberStatus::Ok) return false;
    return v == 0.0 || std::abs(v) >= double(FLT_MIN);
}

/// A whole token as a non-negative decimal integer (digits only).
template<typename IntT>
inline bool plainUnsigned(std::string_view tok, IntT& v)
{
    if (tok.empty() || tok[0] < '0' || tok[0] > '9') return false;
    const auto r = std::from_chars(tok.data(), tok.data() + tok.size(), v);
    return r.ec == std::errc() && r.ptr == tok.data() + tok.size();
}

/// Concatenates per-chunk vectors in chunk order.
template<typename T, typename GetFn>
void concatenate(size_t chunks, GetFn get, std::vector<T>& out)
{
    std::vector<size_t> offset(chunks + 1, 0);
    for (size_t c = 0; c < chunks; ++c) offset[c + 1] = offset[c] + get(c).size();
    out.resize(offset[chunks]);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, chunks, 1), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t c = r.begin(); c < r.end(); ++c) {
            const std::vector<T>& v = get(c);
            if (!v.empty()) std::memcpy(static_cast<void*>(out.data() + offset[c]), v.data(), v.size() * sizeof(T));
        }
    });
}

// ------------------------------------------------------------------------------------- OBJ

struct ObjChunk
{
    std::vector<Vec3d> points;
    std::vector<int32_t> faces;
    uint64_t faceCount = 0, fileFaces = 0;
    int64_t maxIndex = 0;
    bool bail = false;
};

/// One chunk of an OBJ file. Faces: 1-based positive indices only (relative ones depend on the
/// vertices of earlier chunks: the sequential path reads such files); repeated corners removed
/// keeping the first occurrence, as OpenMesh's OBJ reader does.
void parseObjChunk(const char* p, const char* end, ObjChunk& c)
{
    std::string_view line, rest, tok;
    int32_t corners[64];
    while (p < end) {
        line = nextLine(p, end);
        if (oddLineStart(line)) { c.bail = true; return; }
        rest = line;
        if (!nextToken(rest, tok) || tok[0] == '#') continue;
        if (tok.size() != 1) continue; // vn, vt, usemtl, ...: nothing for the geometry
        if (tok[0] == 'v') {
            Vec3d q;
            for (int k = 0; k < 3; ++k) {
                if (!nextToken(rest, tok) || !plainCoordinate(tok, q[k])) { c.bail = true; return; }
            }
            c.points.push_back(q);
        } else if (tok[0] == 'f') {
            ++c.fileFaces;
            int n = 0;
            while (nextToken(rest, tok)) {
                if (n == 64) { c.bail = true; return; }
                const size_t slash = tok.find('/');
                int64_t idx = 0;
                if (!plainUnsigned(tok.substr(0, slash), idx) || idx < 1 || idx > INT32_MAX) {
                    c.bail = true; // '#', relative, zero, junk: the sequential path decides
                    return;
                }
                c.maxIndex = std::max(c.maxIndex, idx);
                const int32_t v = int32_t(idx - 1);
                bool repeated = false;
                for (int j = 0; j < n; ++j) repeated = repeated || corners[j] == v;
                if (!repeated) corners[n++] = v;
            }
            if (n >= 3) {
                c.faces.push_back(n);
                c.faces.insert(c.faces.end(), corners, corners + n);
                ++c.faceCount;
            }
        }
    }
}

bool fastObj(const MappedFile& file, FastMesh& out)
{
    const std::vector<Range> ranges = splitAtLines(file.data(), 0, file.size());
    std::vector<ObjChunk> chunks(ranges.size());
    std::atomic<bool> bail{false};
    tbb::parallel_for(tbb::blocked_range<size_t>(0, ranges.size(), 1), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t i = r.begin(); i < r.end() && !bail.load(std::memory_order_relaxed); ++i) {
            parseObjChunk(file.data() + ranges[i].first, file.data() + ranges[i].second, chunks[i]);
            if (chunks[i].bail) bail = true;
        }
    });
    if (bail) return false;
    int64_t maxIndex = 0;
    for (const ObjChunk& c : chunks) {
        maxIndex = std::max(maxIndex, c.maxIndex);
        out.faceCount += c.faceCount;
        out.fileFaces += c.fileFaces;
    }
    concatenate<Vec3d>(chunks.size(), [&](size_t i) -> const std::vector<Vec3d>& { return chunks[i].points; }, out.points);
    if (maxIndex > int64_t(out.points.size())) return false; // the sequential path names the face
    concatenate<int32_t>(chunks.size(), [&](size_t i) -> const std::vector<int32_t>& { return chunks[i].faces; }, out.faceStream);
    out.exactPoints = true;
    return true;
}

// ----------------------------------------------------------------------------- STL merging

/// Merges STL corners as OpenMesh's STL reader does (a map with a FLT_MIN tolerance, which for
/// the values accepted here, zero or at least 2^-100 in magnitude, means equal coordinates with
/// 0 == -0): vertices in order of first use, each with the coordinates of its first use; facets
/// with two equal corners are dropped. @a corners holds 9 floats per facet.
void mergeStlCorners(const std::vector<float>& corners, FastMesh& out)
{
    const size_t n = corners.size() / 3; // corners
    auto keyOf = [&](size_t i, uint32_t k[3]) {
        for (int j = 0; j < 3; ++j) {
            uint32_t b;
            std::memcpy(&b, &corners[3 * i + size_t(j)], 4);
            k[j] = b == 0x80000000u ? 0u : b;
        }
    };
    std::vector<uint32_t> hash(n);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 1 << 16), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t i = r.begin(); i < r.end(); ++i) {
            uint32_t k[3];
            keyOf(i, k);
            uint64_t h = (uint64_t(k[0]) * 0x9E3779B97F4A7C15ull) ^ (uint64_t(k[1]) * 0xC2B2AE3D27D4EB4Full) ^
                         (uint64_t(k[2]) * 0x165667B19E3779F9ull);
            h ^= h >> 29;
            h *= 0xBF58476D1CE4E5B9ull;
            h ^= h >> 32;
            hash[i] = uint32_t(h);
        }
    });
    // Stable bucketing of the corner numbers by the top bits of their hash.
    constexpr int kBits = 6;
    constexpr size_t kParts = size_t(1) << kBits;
    constexpr size_t kBlock = size_t(1) << 16;
    const size_t blocks = (n + kBlock - 1) / kBlock;
    std::vector<uint32_t> count(blocks * kParts, 0);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, blocks, 1), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t b = r.begin(); b < r.end(); ++b) {
            for (size_t i = b * kBlock; i < std::min(n, (b + 1) * kBlock); ++i) ++count[b * kParts + (hash[i] >> (32 - kBits))];
        }
    });
    std::vector<size_t> start(blocks * kParts + 1, 0), partBegin(kParts + 1, 0);
    size_t acc = 0;
    for (size_t p = 0; p < kParts; ++p) {
        partBegin[p] = acc;
        for (size_t b = 0; b < blocks; ++b) {
            start[b * kParts + p] = acc;
            acc += count[b * kParts + p];
        }
    }
    partBegin[kParts] = acc;
    std::vector<uint32_t> order(n);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, blocks, 1), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t b = r.begin(); b < r.end(); ++b) {
            size_t* s = &start[b * kParts];
            for (size_t i = b * kBlock; i < std::min(n, (b + 1) * kBlock); ++i) order[s[hash[i] >> (32 - kBits)]++] = uint32_t(i);
        }
    });
    // Per part: the first corner with the same key (corners come in increasing order).
    std::vector<uint32_t> first(n);
    struct Entry { uint32_t k[3]; uint32_t corner; }; // corner + 1; 0 = empty
    tbb::parallel_for(tbb::blocked_range<size_t>(0, kParts, 1), [&](const tbb::blocked_range<size_t>& r) {
        std::vector<Entry> table;
        for (size_t p = r.begin(); p < r.end(); ++p) {
            const size_t m = partBegin[p + 1] - partBegin[p];
            size_t cap = 16;
            while (cap < 2 * m) cap *= 2;
            table.assign(cap, Entry{{0, 0, 0}, 0});
            const size_t mask = cap - 1;
            for (size_t j = partBegin[p]; j < partBegin[p + 1]; ++j) {
                const uint32_t i = order[j];
                uint32_t k[3];
                keyOf(i, k);
                size_t slot = hash[i] & mask;
                for (;;) {
                    Entry& e = table[slot];
                    if (e.corner == 0) {
                        e = Entry{{k[0], k[1], k[2]}, i + 1};
                        first[i] = i;
                        break;
                    }
                    if (e.k[0] == k[0] && e.k[1] == k[1] && e.k[2] == k[2]) {
                        first[i] = e.corner - 1;
                        break;
                    }
                    slot = (slot + 1) & mask;
                }
            }
        }
    });
    // Vertex numbers in order of first use.
    std::vector<uint32_t>& id = hash; // reused
    out.points.clear();
    size_t distinct = 0;
    for (size_t i = 0; i < n; ++i) distinct += first[i] == i;
    out.points.reserve(distinct);
    for (size_t i = 0; i < n; ++i) {
        if (first[i] == i) {
            id[i] = uint32_t(out.points.size());
            out.points.emplace_back(corners[3 * i], corners[3 * i + 1], corners[3 * i + 2]);
        } else {
            id[i] = id[first[i]];
        }
    }
    const size_t facets = n / 3;
    out.faceStream.clear();
    out.faceStream.reserve(4 * facets);
    out.faceCount = 0;
    for (size_t f = 0; f < facets; ++f) {
        const uint32_t a = id[3 * f], b = id[3 * f + 1], c = id[3 * f + 2];
        if (a == b || a == c || b == c) continue;
        out.faceStream.insert(out.faceStream.end(), {3, int32_t(a), int32_t(b), int32_t(c)});
        ++out.faceCount;
    }
    out.fileFaces = facets;
    out.exactPoints = false;
}

/// A float STL coordinate the merge above handles exactly: finite, and zero or >= 2^-100.
inline bool plainStlFloat(float v)
{
    return std::isfinite(v) && (v == 0.0f || std::abs(v) >= 0x1p-100f);
}

bool fastBinaryStl(const MappedFile& file, FastMesh& out)
{
    if (file.size() < 84) return false;
    uint32_t nT = 0;
    std::memcpy(&nT, file.data() + 80, 4);
    if (kHostBigEndian) nT = __builtin_bswap32(nT);
    if (file.size() != 84 + 50 * uint64_t(nT) || nT > uint32_t(INT32_MAX) / 3) return false;
    std::vector<float> corners(size_t(nT) * 9);
    std::atomic<bool> bail{false};
    tbb::parallel_for(tbb::blocked_range<size_t>(0, nT, 1 << 15), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t f = r.begin(); f < r.end(); ++f) {
            const char* rec = file.data() + 84 + 50 * f + 12;
            float* dst = &corners[9 * f];
            std::memcpy(dst, rec, 36);
            for (int k = 0; k < 9; ++k) {
                if (kHostBigEndian) dst[k] = io_internal::byteSwapped(dst[k]);
                if (!plainStlFloat(dst[k])) bail = true;
            }
        }
    });
    if (bail) return false;
    out.binary = true;
    mergeStlCorners(corners, out);
    return true;
}

inline bool containsOuter(std::string_view line)
{
    return line.find("outer") != std::string_view::npos || line.find("OUTER") != std::string_view::npos;
}

struct StlChunk
{
    std::vector<float> corners;
    bool bail = false;
};

/// One chunk of an ASCII STL file: the facets whose "outer" line starts in the chunk (their
/// corner lines may run into the next chunk). A corner line that itself contains "outer" makes
/// the facet starts depend on earlier chunks: such files take the sequential path.
void parseStlChunk(const char* p, const char* chunkEnd, const char* fileEnd, StlChunk& c)
{
    std::string_view line, rest, tok;
    while (p < chunkEnd) {
        line = nextLine(p, fileEnd);
        if (!containsOuter(line)) continue;
        for (int k = 0; k < 3; ++k) {
            if (p >= fileEnd) { c.bail = true; return; }
            line = nextLine(p, fileEnd);
            if (containsOuter(line) || oddLineStart(line)) { c.bail = true; return; }
            rest = line;
            if (!nextToken(rest, tok)) { c.bail = true; return; } // "vertex"
            for (int j = 0; j < 3; ++j) {
                float v = 0;
                if (!nextToken(rest, tok)) { c.bail = true; return; }
                const char* b = tok.data();
                const char* e = b + tok.size();
                if (*b == '+') ++b;
                const auto r = std::from_chars(b, e, v, std::chars_format::general);
                if (r.ec != std::errc() || r.ptr != e || !plainStlFloat(v)) { c.bail = true; return; }
                c.corners.push_back(v);
            }
        }
    }
}

bool fastAsciiStl(const MappedFile& file, FastMesh& out)
{
    const std::vector<Range> ranges = splitAtLines(file.data(), 0, file.size());
    std::vector<StlChunk> chunks(ranges.size());
    std::atomic<bool> bail{false};
    const char* d = file.data();
    tbb::parallel_for(tbb::blocked_range<size_t>(0, ranges.size(), 1), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t i = r.begin(); i < r.end() && !bail.load(std::memory_order_relaxed); ++i) {
            parseStlChunk(d + ranges[i].first, d + ranges[i].second, d + file.size(), chunks[i]);
            if (chunks[i].bail) bail = true;
        }
    });
    if (bail) return false;
    std::vector<float> corners;
    concatenate<float>(chunks.size(), [&](size_t i) -> const std::vector<float>& { return chunks[i].corners; }, corners);
    chunks.clear();
    // No facet: not ASCII STL after all; the sequential path says what the file is.
    if (corners.empty() || corners.size() / 9 > size_t(INT32_MAX) / 3) return false;
    out.binary = false;
    mergeStlCorners(corners, out);
    return true;
}

// ------------------------------------------------------------------------------------- PLY

// PLY property types: PlyType, plyType() and plySize() of MeshScanPly.cc (MeshIOInternal.h).

/// Little-endian integer of type @a t at @a p (integer types only).
inline int64_t readInt(const char* p, PlyType t)
{
    switch (t) {
    case PlyType::Int8: { int8_t v; std::memcpy(&v, p, 1); return v; }
    case PlyType::UInt8: { uint8_t v; std::memcpy(&v, p, 1); return v; }
    case PlyType::Int16: { int16_t v; std::memcpy(&v, p, 2); return v; }
    case PlyType::UInt16: { uint16_t v; std::memcpy(&v, p, 2); return v; }
    case PlyType::Int32: { int32_t v; std::memcpy(&v, p, 4); return v; }
    case PlyType::UInt32: { uint32_t v; std::memcpy(&v, p, 4); return v; }
    default: break;
    }
    return -1;
}

/// The one PLY layout the fast path reads: "vertex" (scalar properties including float/double
/// x, y, z) then "face" (one list vertex_indices / vertex_index of integers).
struct PlyLayout
{
    bool ascii = true;
    uint64_t nV = 0, nF = 0;
    std::vector<PlyType> vprops;
    int xyz[3] = {-1, -1, -1};
    size_t xyzOffset[3] = {0, 0, 0};
    size_t stride = 0;
    PlyType countType = PlyType::Invalid, itemType = PlyType::Invalid;
    size_t body = 0; ///< offset of the first byte after the header
};

bool parsePlyHeader(const MappedFile& file, PlyLayout& L)
{
    const char* p = file.data();
    const char* end = p + file.size();
    std::string_view line = nextLine(p, end), rest, t[6];
    if (line != "ply") return false;
    int element = -1; // 0 vertex, 1 face
    bool haveFormat = false, faceList = false;
    for (;;) {
        if (p >= end) return false;
        line = nextLine(p, end);
        if (line.find('\r') != std::string_view::npos) return false;
        rest = line;
        int n = 0;
        while (n < 6 && nextToken(rest, t[n])) ++n;
        if (n == 0 || n == 6) return false;
        if (t[0] == "comment" || t[0] == "obj_info") continue;
        if (t[0] == "end_header" && n == 1) break;
        if (t[0] == "format" && n == 3 && !haveFormat && element < 0) {
            double version = 0;
            if (parseCoordinate(t[2], version) != NumberStatus::Ok) return false;
            if (t[1] == "ascii") L.ascii = true;
            else if (t[1] == "binary_little_endian" && !kHostBigEndian) L.ascii = false;
            else return false;
            haveFormat = true;
        } else if (t[0] == "element" && n == 3) {
            uint64_t count = 0;
            if (!plainUnsigned(t[2], count) || count > uint64_t(INT32_MAX)) return false;
            if (element == -1 && t[1] == "vertex") { element = 0; L.nV = count; }
            else if (element == 0 && t[1] == "face") { element = 1; L.nF = count; }
            else return false;
        } else if (t[0] == "property" && element == 0 && n == 3) {
            const PlyType ty = plyType(t[1]);
            if (ty == PlyType::Invalid) return false;
            for (int k = 0; k < 3; ++k) {
                if (t[2] == std::string_view(k == 0 ? "x" : (k == 1 ? "y" : "z"))) {
                    if (L.xyz[k] >= 0 || (ty != PlyType::Float32 && ty != PlyType::Float64)) return false;
                    L.xyz[k] = int(L.vprops.size());
                    L.xyzOffset[k] = L.stride;
                }
            }
            L.vprops.push_back(ty);
            L.stride += plySize(ty);
        } else if (t[0] == "property" && element == 1 && n == 5 && t[1] == "list" && !faceList &&
                   (t[4] == "vertex_indices" || t[4] == "vertex_index")) {
            L.countType = plyType(t[2]);
            L.itemType = plyType(t[3]);
            if (L.countType == PlyType::Invalid || L.countType == PlyType::Float32 || L.countType == PlyType::Float64) return false;
            if (L.itemType != PlyType::Int32 && L.itemType != PlyType::UInt32) return false;
            faceList = true;
        } else {
            return false;
        }
    }
    if (!haveFormat || element != 1 || !faceList || L.xyz[0] < 0 || L.xyz[1] < 0 || L.xyz[2] < 0) return false;
    L.body = size_t(p - file.data());
    return true;
}

bool fastBinaryPly(const MappedFile& file, const PlyLayout& L, FastMesh& out)
{
    const char* d = file.data() + L.body;
    const size_t avail = file.size() - L.body;
    const size_t cs = plySize(L.countType), is = plySize(L.itemType);
    if (uint64_t(L.nV) * L.stride + uint64_t(L.nF) * (cs + 3 * is) > avail) return false;
    out.points.resize(L.nV);
    std::atomic<bool> bail{false};
    tbb::parallel_for(tbb::blocked_range<size_t>(0, L.nV, 1 << 15), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t v = r.begin(); v < r.end(); ++v) {
            const char* rec = d + v * L.stride;
            for (int k = 0; k < 3; ++k) {
                double x;
                if (L.vprops[size_t(L.xyz[k])] == PlyType::Float32) {
                    float f;
                    std::memcpy(&f, rec + L.xyzOffset[k], 4);
                    x = f;
                } else {
                    std::memcpy(&x, rec + L.xyzOffset[k], 8);
                }
                if (!std::isfinite(x) || std::abs(x) > double(FLT_MAX)) bail = true;
                out.points[v][k] = x;
            }
        }
    });
    if (bail) return false;
    const char* p = d + uint64_t(L.nV) * L.stride;
    const char* end = file.data() + file.size();
    out.faceStream.resize(size_t(L.nF) * 4);
    size_t pos = 0;
    const int64_t nV = int64_t(L.nV);
    for (uint64_t f = 0; f < L.nF; ++f) {
        if (size_t(end - p) < cs) return false;
        const int64_t k = readInt(p, L.countType);
        p += cs;
        if (k < 3 || k > 64 || size_t(end - p) < size_t(k) * is) return false;
        if (pos + 1 + size_t(k) > out.faceStream.size()) out.faceStream.resize(2 * out.faceStream.size() + 8);
        out.faceStream[pos++] = int32_t(k);
        const size_t corner0 = pos;
        for (int64_t j = 0; j < k; ++j, p += is) {
            const int64_t idx = readInt(p, L.itemType);
            if (idx < 0 || idx >= nV) return false;
            for (size_t q = corner0; q < pos; ++q) {
                if (out.faceStream[q] == int32_t(idx)) return false; // repeated corner
            }
            out.faceStream[pos++] = int32_t(idx);
        }
    }
    out.faceStream.resize(pos);
    out.faceCount = out.fileFaces = L.nF;
    out.binary = true;
    out.exactPoints = true;
    return true;
}

struct PlyChunk
{
    uint64_t lines = 0;
    std::vector<int32_t> faces;
    uint64_t faceCount = 0;
    bool bail = false;
};

/// Lines of [p, end): '\n' count, plus one for a last line without '\n'.
uint64_t countLines(const char* p, const char* end)
{
    uint64_t n = 0;
    while (p < end) {
        const char* nl = static_cast<const char*>(std::memchr(p, '\n', size_t(end - p)));
        ++n;
        if (!nl) break;
        p = nl + 1;
    }
    return n;
}

/// One chunk of an ASCII PLY body whose first line is body line @a first: one vertex or one
/// face per line, exactly its tokens (the pre-scan reads tokens across lines; such files take
/// the sequential path, as do faces that repeat a corner, which OpenMesh may treat its own way).
void parsePlyChunk(const char* p, const char* end, uint64_t first, const PlyLayout& L,
                   std::vector<Vec3d>& points, PlyChunk& c)
{
    std::string_view line, rest, tok;
    const uint64_t nV = L.nV, total = L.nV + L.nF;
    for (uint64_t ln = first; p < end && ln < total; ++ln) {
        line = nextLine(p, end);
        rest = line;
        if (ln < nV) {
            Vec3d& q = points[ln];
            for (size_t i = 0; i < L.vprops.size(); ++i) {
                double v = 0;
                if (!nextToken(rest, tok) || !plainCoordinate(tok, v)) { c.bail = true; return; }
                if (int(i) == L.xyz[0]) q[0] = v;
                else if (int(i) == L.xyz[1]) q[1] = v;
                else if (int(i) == L.xyz[2]) q[2] = v;
            }
        } else {
            uint32_t k = 0;
            if (!nextToken(rest, tok) || !plainUnsigned(tok, k) || k < 3 || k > 64) { c.bail = true; return; }
            c.faces.push_back(int32_t(k));
            const size_t corner0 = c.faces.size();
            for (uint32_t j = 0; j < k; ++j) {
                uint32_t idx = 0;
                if (!nextToken(rest, tok) || !plainUnsigned(tok, idx) || idx >= nV) { c.bail = true; return; }
                for (size_t q = corner0; q < c.faces.size(); ++q) {
                    if (c.faces[q] == int32_t(idx)) { c.bail = true; return; } // repeated corner
                }
                c.faces.push_back(int32_t(idx));
            }
            ++c.faceCount;
        }
        if (nextToken(rest, tok)) { c.bail = true; return; }
    }
}

bool fastAsciiPly(const MappedFile& file, const PlyLayout& L, FastMesh& out)
{
    const char* d = file.data();
    // At least two bytes per number: a short file is the sequential path's to report.
    if (L.nV * L.vprops.size() * 2 + L.nF * 8 > file.size() - L.body + 1) return false;
    const std::vector<Range> ranges = splitAtLines(d, L.body, file.size());
    std::vector<PlyChunk> chunks(ranges.size());
    tbb::parallel_for(tbb::blocked_range<size_t>(0, ranges.size(), 1), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t i = r.begin(); i < r.end(); ++i) chunks[i].lines = countLines(d + ranges[i].first, d + ranges[i].second);
    });
    std::vector<uint64_t> firstLine(ranges.size() + 1, 0);
    for (size_t i = 0; i < ranges.size(); ++i) firstLine[i + 1] = firstLine[i] + chunks[i].lines;
    if (firstLine.back() < L.nV + L.nF) return false;
    out.points.resize(L.nV);
    std::atomic<bool> bail{false};
    tbb::parallel_for(tbb::blocked_range<size_t>(0, ranges.size(), 1), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t i = r.begin(); i < r.end() && !bail.load(std::memory_order_relaxed); ++i) {
            parsePlyChunk(d + ranges[i].first, d + ranges[i].second, firstLine[i], L, out.points, chunks[i]);
            if (chunks[i].bail) bail = true;
        }
    });
    if (bail) return false;
    concatenate<int32_t>(chunks.size(), [&](size_t i) -> const std::vector<int32_t>& { return chunks[i].faces; }, out.faceStream);
    for (const PlyChunk& c : chunks) out.faceCount += c.faceCount;
    out.fileFaces = out.faceCount;
    out.binary = false;
    out.exactPoints = true;
    return true;
}

} // namespace

bool fastReadMesh(const std::string& path, const std::string& ext, const std::string& format,
                  FastMesh& out)
{
    out = FastMesh();
    const MappedFile file(path);
    if (file.size() == 0) return false;
    if (format == "obj") return fastObj(file, out);
    if (format == "ply") {
        PlyLayout layout;
        if (!parsePlyHeader(file, layout)) return false;
        return layout.ascii ? fastAsciiPly(file, layout, out) : fastBinaryPly(file, layout, out);
    }
    if (format == "stl") {
        bool binary = ext == ".stlb";
        if (ext == ".stl" && file.size() >= 84) {
            uint32_t n = 0;
            std::memcpy(&n, file.data() + 80, 4);
            if (kHostBigEndian) n = __builtin_bswap32(n);
            binary = file.size() == 84 + 50 * uint64_t(n);
        }
        return binary ? fastBinaryStl(file, out) : fastAsciiStl(file, out);
    }
    return false;
}

} // namespace meshio_internal

} // namespace levelforge
