// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Private to src/io/Mesh*.cc: the shared parsing helpers, the buffered FileReader and
///        the pre-scan of OBJ / OFF / PLY / STL files. See MeshIO.h for what reading
///        guarantees; the OpenMesh importer is in MeshImporter.h.
#pragma once

#include <levelforge/io/MeshIO.h>

#include <levelforge/core/Exceptions.h>

#include "detail/MessageText.h"
#include "detail/NumberFormat.h"
#include "io/IoCommon.h"

#include <algorithm>
#include <cerrno>
#include <cfloat>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <string>
#include <string_view>
#include <system_error>
#include <vector>

namespace levelforge {

namespace meshio_internal {

namespace fs = std::filesystem;

using detail::formatDouble;
using io_internal::kHostBigEndian;
using io_internal::lowerExtension;

// ------------------------------------------------------------------------------------ helpers

/// "(x, y, z)" in shortest round-trip form.
std::string formatPoint(const Vec3d& p);

/// Throws InvalidMeshError "<path>: line <line>: <what>" (no line part when line == 0).
[[noreturn]] void throwInvalid(const std::string& path, uint64_t line, const std::string& what);

inline bool isSpace(char c)
{
    return c == ' ' || c == '\t' || c == '\r' || c == '\n' || c == '\v' || c == '\f';
}

/// Next whitespace-separated token of @a s (consumed from the front). False when none is left.
inline bool nextToken(std::string_view& s, std::string_view& tok)
{
    size_t i = 0;
    while (i < s.size() && isSpace(s[i])) ++i;
    if (i == s.size()) {
        s = {};
        return false;
    }
    size_t j = i;
    while (j < s.size() && !isSpace(s[j])) ++j;
    tok = s.substr(i, j - i);
    s.remove_prefix(j);
    return true;
}

inline std::string_view trimmed(std::string_view s)
{
    while (!s.empty() && isSpace(s.front())) s.remove_prefix(1);
    while (!s.empty() && isSpace(s.back())) s.remove_suffix(1);
    return s;
}

enum class NumberStatus { Ok, NotANumber, NonFinite, OutOfFloatRange };

/// Parses a whole token as a coordinate. OpenMesh hands coordinates over as float, so values
/// beyond the float range are as bad as Inf.
inline NumberStatus parseCoordinate(std::string_view tok, double& v)
{
    const char* b = tok.data();
    const char* e = b + tok.size();
    if (b != e && *b == '+') ++b;
    const auto r = std::from_chars(b, e, v, std::chars_format::general);
    if (r.ec == std::errc::result_out_of_range && r.ptr == e) {
        // Underflow reads as zero (as strtod does); overflow is out of range.
        const bool underflow = tok.find("e-") != std::string_view::npos ||
                               tok.find("E-") != std::string_view::npos;
        if (!underflow) return NumberStatus::OutOfFloatRange;
        v = 0.0;
        return NumberStatus::Ok;
    }
    if (r.ec != std::errc() || r.ptr != e) return NumberStatus::NotANumber;
    if (!std::isfinite(v)) return NumberStatus::NonFinite;
    if (std::abs(v) > double(FLT_MAX)) return NumberStatus::OutOfFloatRange;
    return NumberStatus::Ok;
}

/// Text of a coordinate problem: "cannot parse coordinate 'x'", "non-finite coordinate ...".
std::string describeCoordinateProblem(NumberStatus st, std::string_view tok);

/// Parses a whole token as an integer.
template<typename IntT>
bool parseInteger(std::string_view tok, IntT& v)
{
    const char* b = tok.data();
    const char* e = b + tok.size();
    if (b != e && *b == '+') ++b;
    const auto r = std::from_chars(b, e, v);
    return r.ec == std::errc() && r.ptr == e;
}

// ------------------------------------------------------------------------------- FileReader

/// Buffered reading of lines and raw bytes from a file, without per-line allocation.
class FileReader
{
public:
    /// Opens @a path. Throws IoError when it cannot be opened.
    explicit FileReader(const std::string& path);
    ~FileReader();
    FileReader(const FileReader&) = delete;
    FileReader& operator=(const FileReader&) = delete;

    /// Next line without its '\n' (a '\r' before it is kept; callers treat it as space).
    /// The view is valid until the next call. False at the end of the file.
    bool nextLine(std::string_view& line)
    {
        for (;;) {
            const char* begin = mBuf.data() + mBegin;
            const size_t avail = mEnd - mBegin;
            if (const void* nl = std::memchr(begin, '\n', avail)) {
                const size_t len = size_t(static_cast<const char*>(nl) - begin);
                line = std::string_view(begin, len);
                mBegin += len + 1;
                ++mLine;
                return true;
            }
            if (mEof) {
                if (avail == 0) return false;
                line = std::string_view(begin, avail);
                mBegin = mEnd;
                ++mLine;
                return true;
            }
            refill();
        }
    }

    /// Copies @a n bytes; false if the file ends first.
    bool readBytes(void* dst, size_t n)
    {
        char* out = static_cast<char*>(dst);
        while (n > 0) {
            if (mBegin == mEnd) {
                if (mEof) return false;
                refill();
                continue;
            }
            const size_t k = std::min(n, mEnd - mBegin);
            std::memcpy(out, mBuf.data() + mBegin, k);
            mBegin += k;
            out += k;
            n -= k;
        }
        return true;
    }

    uint64_t lineNumber() const { return mLine; }

    /// Bytes of the file consumed so far (lines returned, bytes copied).
    uint64_t offset() const { return mFileOffset + mBegin; }

private:
    /// Moves the unread bytes to the front and reads more (grows the buffer for a long line).
    void refill();

    std::string mPath;
    std::FILE* mFile = nullptr;
    std::vector<char> mBuf;
    size_t mBegin = 0, mEnd = 0;
    uint64_t mFileOffset = 0; ///< file offset of mBuf[0]
    bool mEof = false;
    uint64_t mLine = 0;
};

/// Whitespace-separated tokens across lines (for OFF and ASCII PLY bodies).
class TokenReader
{
public:
    explicit TokenReader(FileReader& r) : mReader(r) {}

    bool next(std::string_view& tok)
    {
        for (;;) {
            if (nextToken(mRest, tok)) return true;
            if (!mReader.nextLine(mRest)) return false;
        }
    }
    /// Drops what is left of the current line.
    void skipRestOfLine() { mRest = {}; }
    uint64_t line() const { return mReader.lineNumber(); }

private:
    FileReader& mReader;
    std::string_view mRest;
};

// --------------------------------------------------------------------------------- pre-scan

/// Bytes of @a path after @a offset (0 when the size cannot be read).
uint64_t bytesAfter(const std::string& path, uint64_t offset);

/// "the header claims <count> <what> but the file holds only <bytes> bytes after the header":
/// the note of a header whose counts cannot fit in the rest of the file. The pre-scans check a
/// header's counts against the bytes that remain before they allocate anything sized from them
/// (binary: the exact bytes needed; text: at least two bytes per number, a digit and a
/// separator, one less at the very end), allocate only what the file can hold, and add the
/// note to the error they report when the data runs out.
std::string headerClaimNote(uint64_t count, const std::string& what, uint64_t bytes);

/// What the pre-scan learnt about a file.
struct Prescan
{
    bool binary = false;
    bool haveFaces = false;
    uint64_t faces = 0;              ///< faces (polygons / facets) in the file
    bool havePoints = false;
    std::vector<Vec3d> points;       ///< exact positions, file order (OBJ, OFF, PLY)
    /// The importer's points are already the exact positions of the file (the parallel fast path
    /// of MeshParseFast.h read them with the pre-scan's own parser): assemble() takes them as
    /// they are and reports double precision.
    bool importerPointsExact = false;
};

/// Pre-scans an OBJ file: coordinates, face indices, exact positions (MeshScanObj.cc).
void prescanObj(const std::string& path, Prescan& out);

/// Pre-scans an OFF file, ASCII or binary (MeshScanOff.cc).
void prescanOff(const std::string& path, Prescan& out);

/// Pre-scans a PLY file, ASCII or binary (MeshScanPly.cc).
void prescanPly(const std::string& path, Prescan& out);

/// Pre-scans an STL file, ASCII or binary; @a ext is the lower-case extension (MeshScanStl.cc).
void prescanStl(const std::string& path, const std::string& ext, Prescan& out);

// ------------------------------------------------------------------------------- attributes

/// One attribute as a file holds it, before it is spread over the triangles' corners.
struct AttributeSource
{
    std::string name;
    int components = 3;
    /// true: `values` holds one entry per vertex (OBJ colours, PLY properties); false: `values` is
    /// a table (OBJ `vt` / `vn` lines) and `cornerIndex` picks an entry for each face corner.
    bool perVertex = true;
    std::vector<float> values;         ///< entries * components
    std::vector<int32_t> cornerIndex;  ///< !perVertex: per corner of AttributeScan, table entry or -1
};

/// What an attribute scan found: the names the file offers and the sources asked for. For OBJ,
/// also the faces as OpenMesh hands them over (repeated corners removed keeping the first,
/// faces with fewer than three distinct corners left out), so that their corners can be matched
/// with the triangles made from them.
struct AttributeScan
{
    std::vector<std::string> available;
    std::vector<AttributeSource> sources;   ///< in the order asked for
    std::vector<uint64_t> faceStart;        ///< OBJ: face f's corners are [faceStart[f], faceStart[f+1])
    std::vector<int32_t> cornerVertex;      ///< OBJ: 0-based vertex of each corner
};

/// Scans an OBJ file for attributes (MeshScanObj.cc): the names it offers, and the sources of
/// @a want (none: only the names). Throws InvalidArgumentError for a name it does not offer,
/// InvalidMeshError for a corner or vertex that lacks a value.
void scanObjAttributes(const std::string& path, const std::vector<std::string>& want, AttributeScan& out);

/// As scanObjAttributes() for PLY (MeshScanPly.cc): vertex properties.
void scanPlyAttributes(const std::string& path, const std::vector<std::string>& want, AttributeScan& out);

/// "<path>: no vertex attribute 'X' (it has: Cd, N)" (MeshReader.cc).
[[noreturn]] void throwNoAttribute(const std::string& path, const std::string& name,
                                   const std::vector<std::string>& available);

/// Spreads the sources of @a scan over the corners of @a mesh's triangles (MeshAssemble.cc),
/// through mesh.faceIndex for OBJ's per-corner tables.
void attachAttributes(const std::string& path, const AttributeScan& scan, TriangleMesh& mesh);

/// PLY property types (MeshScanPly.cc), shared by the sequential and the parallel reader.
enum class PlyType { Int8, UInt8, Int16, UInt16, Int32, UInt32, Float32, Float64, Invalid };
/// The type named by a PLY header word ("uchar", "float32", ...); Invalid for anything else.
PlyType plyType(std::string_view s);
/// Bytes of one value of type t (0 for Invalid).
size_t plySize(PlyType t);

} // namespace meshio_internal

} // namespace levelforge
