// levelforge — mesh reading (through OpenMesh's readers) and writing. See MeshIO.h.
#include <levelforge/io/MeshIO.h>

#include <levelforge/core/Exceptions.h>

#include "detail/MessageText.h"

#include <OpenMesh/Core/IO/IOManager.hh>
#include <OpenMesh/Core/IO/importer/BaseImporter.hh>
#include <OpenMesh/Core/IO/reader/OBJReader.hh>
#include <OpenMesh/Core/IO/reader/OFFReader.hh>
#include <OpenMesh/Core/IO/reader/PLYReader.hh>
#include <OpenMesh/Core/IO/reader/STLReader.hh>
#include <OpenMesh/Core/System/omstream.hh>

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cerrno>
#include <cfloat>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <limits>
#include <mutex>
#include <sstream>
#include <string_view>
#include <system_error>

namespace levelforge {

namespace meshio_internal {

namespace fs = std::filesystem;

// ------------------------------------------------------------------------------------ helpers

std::string lowerExtension(const std::string& path)
{
    std::string ext = fs::path(path).extension().string();
    for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
    return ext;
}


std::string formatDouble(double v)
{
    char buf[64];
    auto r = std::to_chars(buf, buf + sizeof(buf), v);
    return std::string(buf, r.ptr);
}

std::string formatPoint(const Vec3d& p)
{
    return "(" + formatDouble(p[0]) + ", " + formatDouble(p[1]) + ", " + formatDouble(p[2]) + ")";
}

/// Throws InvalidMeshError "<path>: line <line>: <what>" (no line part when line == 0).
[[noreturn]] void throwInvalid(const std::string& path, uint64_t line, const std::string& what)
{
    std::string msg = path + ": ";
    if (line > 0) msg += "line " + std::to_string(line) + ": ";
    throw InvalidMeshError(msg + what);
}

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
NumberStatus parseCoordinate(std::string_view tok, double& v)
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

std::string describeCoordinateProblem(NumberStatus st, std::string_view tok)
{
    switch (st) {
    case NumberStatus::NotANumber: return "cannot parse coordinate " + message_internal::quotedExcerpt(tok);
    case NumberStatus::NonFinite: return "non-finite coordinate " + message_internal::quotedExcerpt(tok);
    case NumberStatus::OutOfFloatRange:
        return "coordinate " + message_internal::quotedExcerpt(tok) + " is beyond the single-precision range";
    case NumberStatus::Ok: break;
    }
    return "bad coordinate " + message_internal::quotedExcerpt(tok);
}

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
    explicit FileReader(const std::string& path) : mPath(path)
    {
        mFile = std::fopen(path.c_str(), "rb");
        if (!mFile) {
            throw IoError("cannot open mesh file '" + path + "': " + std::strerror(errno));
        }
        mBuf.resize(size_t(1) << 20);
    }
    ~FileReader()
    {
        if (mFile) std::fclose(mFile);
    }
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

private:
    void refill()
    {
        const size_t avail = mEnd - mBegin;
        if (mBegin > 0) {
            std::memmove(mBuf.data(), mBuf.data() + mBegin, avail);
            mBegin = 0;
            mEnd = avail;
        }
        if (mEnd == mBuf.size()) mBuf.resize(mBuf.size() * 2); // a line longer than the buffer
        const size_t got = std::fread(mBuf.data() + mEnd, 1, mBuf.size() - mEnd, mFile);
        mEnd += got;
        if (got == 0) {
            if (std::ferror(mFile)) {
                throw IoError("error reading mesh file '" + mPath + "': " + std::strerror(errno));
            }
            mEof = true;
        }
    }

    std::string mPath;
    std::FILE* mFile = nullptr;
    std::vector<char> mBuf;
    size_t mBegin = 0, mEnd = 0;
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

/// What the pre-scan learnt about a file.
struct Prescan
{
    bool binary = false;
    bool haveFaces = false;
    uint64_t faces = 0;              ///< faces (polygons / facets) in the file
    bool havePoints = false;
    std::vector<Vec3d> points;       ///< exact positions, file order (OBJ, OFF, PLY)
};

// OBJ: every 'v' must carry three parseable, finite coordinates (OpenMesh silently skips the
// vertex otherwise, which shifts every later index); every 'f' corner must name an existing
// vertex (OpenMesh passes out-of-range indices on as invalid handles).
void prescanObj(const std::string& path, Prescan& out)
{
    FileReader reader(path);
    std::string_view line, rest, tok;
    uint64_t vertexCount = 0, faceCount = 0;

    // Faces that refer to vertices not yet defined (legal in OBJ when they come later).
    struct ForwardRef { uint64_t face, line; long long index; };
    std::vector<ForwardRef> forward;

    out.points.clear();
    while (reader.nextLine(line)) {
        rest = line;
        if (!nextToken(rest, tok) || tok[0] == '#') continue;
        if (tok == "v") {
            Vec3d p;
            for (int k = 0; k < 3; ++k) {
                if (!nextToken(rest, tok)) {
                    throwInvalid(path, reader.lineNumber(),
                        "vertex " + std::to_string(vertexCount) + " has fewer than 3 coordinates");
                }
                const NumberStatus st = parseCoordinate(tok, p[k]);
                if (st != NumberStatus::Ok) {
                    throwInvalid(path, reader.lineNumber(), "vertex " + std::to_string(vertexCount) +
                        ": " + describeCoordinateProblem(st, tok));
                }
            }
            out.points.push_back(p);
            ++vertexCount;
        } else if (tok == "f") {
            long long maxIndex = 0;
            int corners = 0;
            while (nextToken(rest, tok)) {
                if (tok[0] == '#') break; // trailing comment
                const std::string_view idxPart = tok.substr(0, tok.find('/'));
                long long idx = 0;
                const char* b = idxPart.data();
                const char* e = b + idxPart.size();
                if (b != e && *b == '+') ++b;
                const auto r = std::from_chars(b, e, idx);
                if (idxPart.empty() || r.ec != std::errc() || r.ptr == b) {
                    throwInvalid(path, reader.lineNumber(), "face " + std::to_string(faceCount) +
                        ": cannot parse corner " + message_internal::quotedExcerpt(tok));
                }
                long long resolved = idx;
                if (idx < 0) resolved = (long long)vertexCount + idx + 1; // relative index
                if (idx == 0 || resolved < 1) {
                    throwInvalid(path, reader.lineNumber(), "face " + std::to_string(faceCount) +
                        ": vertex index " + std::to_string(idx) + " is out of range (the file has " +
                        std::to_string(vertexCount) + " vertices before this line; OBJ indices "
                        "start at 1)");
                }
                maxIndex = std::max(maxIndex, resolved);
                ++corners;
            }
            if (corners > 0 && maxIndex > (long long)vertexCount) {
                forward.push_back({faceCount, reader.lineNumber(), maxIndex});
            }
            ++faceCount;
        }
    }
    for (const ForwardRef& f : forward) {
        if (f.index > (long long)vertexCount) {
            throwInvalid(path, f.line, "face " + std::to_string(f.face) + ": vertex index " +
                std::to_string(f.index) + " is out of range (the file has " +
                std::to_string(vertexCount) + " vertices; OBJ indices start at 1)");
        }
    }
    out.faces = faceCount;
    out.haveFaces = true;
    out.havePoints = true;
}

// OFF (binary, OpenMesh's layout: little-endian uint32 counts, float32 coordinates, uint32
// corner counts and indices). OpenMesh trusts the counts (its face loop does not stop at the end
// of the file), so they are checked against the data here.
void prescanBinaryOff(const std::string& path, FileReader& reader, bool extras, Prescan& out)
{
    auto readU32 = [&](uint32_t& v) {
        unsigned char b[4];
        if (!reader.readBytes(b, 4)) return false;
        v = uint32_t(b[0]) | (uint32_t(b[1]) << 8) | (uint32_t(b[2]) << 16) | (uint32_t(b[3]) << 24);
        return true;
    };
    uint32_t nV = 0, nF = 0, nE = 0;
    if (!readU32(nV) || !readU32(nF) || !readU32(nE)) throwInvalid(path, 0, "truncated binary OFF header");
    if (nV > uint32_t(std::numeric_limits<int>::max()) || nF > uint32_t(std::numeric_limits<int>::max())) {
        throwInvalid(path, 0, "binary OFF vertex or face count too large");
    }
    if (extras) {
        // Colours / normals / texture coordinates: only make sure the counts are plausible.
        std::error_code ec;
        const uint64_t size = fs::file_size(path, ec);
        if (!ec && size < 12 * uint64_t(nV) + 4 * uint64_t(nF)) {
            throwInvalid(path, 0, "binary OFF is shorter than its " + std::to_string(nV) +
                " vertices and " + std::to_string(nF) + " faces");
        }
        return;
    }
    for (uint32_t v = 0; v < nV; ++v) {
        for (int k = 0; k < 3; ++k) {
            uint32_t bits = 0;
            if (!readU32(bits)) {
                throwInvalid(path, 0, "the file ends inside vertex " + std::to_string(v) + " of " +
                    std::to_string(nV));
            }
            float x;
            std::memcpy(&x, &bits, 4);
            if (!std::isfinite(x)) {
                throwInvalid(path, 0, "vertex " + std::to_string(v) + ": non-finite coordinate " +
                    formatDouble(x));
            }
        }
    }
    for (uint32_t f = 0; f < nF; ++f) {
        uint32_t corners = 0;
        if (!readU32(corners)) {
            throwInvalid(path, 0, "the file ends before face " + std::to_string(f) + " of " +
                std::to_string(nF));
        }
        for (uint32_t c = 0; c < corners; ++c) {
            uint32_t idx = 0;
            if (!readU32(idx)) throwInvalid(path, 0, "the file ends inside face " + std::to_string(f));
            if (idx >= nV) {
                throwInvalid(path, 0, "face " + std::to_string(f) + ": vertex index " +
                    std::to_string(idx) + " is out of range (the file has " + std::to_string(nV) +
                    " vertices, numbered from 0)");
            }
        }
    }
    out.faces = nF;
    out.haveFaces = true;
}

// OFF (ASCII): header counts, then vertices and faces read the way OpenMesh reads them (three
// numbers then the rest of the line per vertex; a count and that many indices per face).
void prescanOff(const std::string& path, Prescan& out)
{
    FileReader reader(path);
    std::string_view header;
    if (!reader.nextLine(header)) throwInvalid(path, 0, "the file is empty");
    header = trimmed(header);

    // [ST][C][N][4][n]OFF [BINARY]
    std::string_view p = header;
    bool hasTex = false, hasColor = false, hasNormal = false, higherDim = false;
    if (p.substr(0, 2) == "ST") { hasTex = true; p.remove_prefix(2); }
    if (p.substr(0, 1) == "C") { hasColor = true; p.remove_prefix(1); }
    if (p.substr(0, 1) == "N") { hasNormal = true; p.remove_prefix(1); }
    if (p.substr(0, 1) == "4") { higherDim = true; p.remove_prefix(1); }
    if (p.substr(0, 1) == "n") { higherDim = true; p.remove_prefix(1); }
    if (p.substr(0, 3) != "OFF") {
        throwInvalid(path, 1, "not an OFF file: the first line is " + message_internal::quotedExcerpt(header) +
            ", expected 'OFF' (optionally prefixed by ST, C, N)");
    }
    p.remove_prefix(3);
    std::string_view extra = trimmed(p);
    if (extra.substr(0, 6) == "BINARY") {
        out.binary = true;
        prescanBinaryOff(path, reader, hasTex || hasColor || hasNormal || higherDim, out);
        return;
    }
    if (!extra.empty()) {
        throwInvalid(path, 1, "the OFF header line must hold only the keyword (OpenMesh reads the "
            "counts from the next line), found " + message_internal::quotedExcerpt(header));
    }
    if (higherDim) return; // let OpenMesh decide about 4OFF / nOFF
    (void)hasTex;

    TokenReader tokens(reader);
    std::string_view tok;
    uint64_t counts[3] = {0, 0, 0};
    const char* countNames[3] = {"vertex count", "face count", "edge count"};
    for (int i = 0; i < 3; ++i) {
        if (!tokens.next(tok)) throwInvalid(path, tokens.line(), std::string("missing ") + countNames[i]);
        if (!parseInteger(tok, counts[i])) {
            throwInvalid(path, tokens.line(), std::string("cannot parse the ") + countNames[i] +
                " " + message_internal::quotedExcerpt(tok) + (tok[0] == '#' ? " (OpenMesh's OFF reader does not accept "
                "comments)" : ""));
        }
    }
    const uint64_t nV = counts[0], nF = counts[1];
    if (nV > uint64_t(std::numeric_limits<int>::max()) || nF > uint64_t(std::numeric_limits<int>::max())) {
        throwInvalid(path, tokens.line(), "vertex or face count too large");
    }
    tokens.skipRestOfLine();

    out.points.resize(nV);
    for (uint64_t v = 0; v < nV; ++v) {
        Vec3d& q = out.points[v];
        for (int k = 0; k < (hasNormal ? 6 : 3); ++k) {
            if (!tokens.next(tok)) {
                throwInvalid(path, tokens.line(), "the file ends inside vertex " + std::to_string(v) +
                    " of " + std::to_string(nV));
            }
            double value = 0;
            const NumberStatus st = parseCoordinate(tok, value);
            if (st != NumberStatus::Ok) {
                throwInvalid(path, tokens.line(), "vertex " + std::to_string(v) + ": " +
                    (k < 3 ? describeCoordinateProblem(st, tok) : "cannot parse normal " + message_internal::quotedExcerpt(tok)));
            }
            if (k < 3) q[k] = value;
        }
        tokens.skipRestOfLine(); // colours / texture coordinates
    }
    for (uint64_t f = 0; f < nF; ++f) {
        if (!tokens.next(tok)) {
            throwInvalid(path, tokens.line(), "the file ends before face " + std::to_string(f) +
                " of " + std::to_string(nF));
        }
        uint32_t corners = 0;
        if (!parseInteger(tok, corners)) {
            throwInvalid(path, tokens.line(), "face " + std::to_string(f) +
                ": cannot parse the corner count " + message_internal::quotedExcerpt(tok));
        }
        for (uint32_t c = 0; c < corners; ++c) {
            if (!tokens.next(tok)) {
                throwInvalid(path, tokens.line(), "the file ends inside face " + std::to_string(f));
            }
            long long idx = 0;
            if (!parseInteger(tok, idx)) {
                throwInvalid(path, tokens.line(), "face " + std::to_string(f) +
                    ": cannot parse vertex index " + message_internal::quotedExcerpt(tok));
            }
            if (idx < 0 || uint64_t(idx) >= nV) {
                throwInvalid(path, tokens.line(), "face " + std::to_string(f) + ": vertex index " +
                    std::to_string(idx) + " is out of range (the file has " + std::to_string(nV) +
                    " vertices, numbered from 0)");
            }
        }
        if (hasColor) tokens.skipRestOfLine();
    }
    out.faces = nF;
    out.haveFaces = true;
    out.havePoints = true;
}

// PLY (ASCII and binary): header, then every element in order; checks vertex x/y/z and the
// face index lists, keeps exact positions.
enum class PlyType { Int8, UInt8, Int16, UInt16, Int32, UInt32, Float32, Float64, Invalid };

PlyType plyType(std::string_view s)
{
    if (s == "char" || s == "int8") return PlyType::Int8;
    if (s == "uchar" || s == "uint8") return PlyType::UInt8;
    if (s == "short" || s == "int16") return PlyType::Int16;
    if (s == "ushort" || s == "uint16") return PlyType::UInt16;
    if (s == "int" || s == "int32") return PlyType::Int32;
    if (s == "uint" || s == "uint32") return PlyType::UInt32;
    if (s == "float" || s == "float32") return PlyType::Float32;
    if (s == "double" || s == "float64") return PlyType::Float64;
    return PlyType::Invalid;
}

size_t plySize(PlyType t)
{
    switch (t) {
    case PlyType::Int8: case PlyType::UInt8: return 1;
    case PlyType::Int16: case PlyType::UInt16: return 2;
    case PlyType::Int32: case PlyType::UInt32: case PlyType::Float32: return 4;
    case PlyType::Float64: return 8;
    case PlyType::Invalid: break;
    }
    return 0;
}

struct PlyProperty
{
    std::string name;
    bool isList = false;
    PlyType type = PlyType::Invalid;      ///< value type (list item type for lists)
    PlyType countType = PlyType::Invalid; ///< list count type
};

struct PlyElement
{
    std::string name;
    uint64_t count = 0;
    std::vector<PlyProperty> props;
};

enum class PlyFormat { Ascii, BinaryLE, BinaryBE };

/// Reads one PLY value (binary) as double.
bool readPlyBinary(FileReader& r, PlyType t, bool swap, double& out)
{
    unsigned char b[8];
    const size_t n = plySize(t);
    if (!r.readBytes(b, n)) return false;
    if (swap) std::reverse(b, b + n);
    switch (t) {
    case PlyType::Int8: { int8_t v; std::memcpy(&v, b, 1); out = v; break; }
    case PlyType::UInt8: { uint8_t v; std::memcpy(&v, b, 1); out = v; break; }
    case PlyType::Int16: { int16_t v; std::memcpy(&v, b, 2); out = v; break; }
    case PlyType::UInt16: { uint16_t v; std::memcpy(&v, b, 2); out = v; break; }
    case PlyType::Int32: { int32_t v; std::memcpy(&v, b, 4); out = v; break; }
    case PlyType::UInt32: { uint32_t v; std::memcpy(&v, b, 4); out = v; break; }
    case PlyType::Float32: { float v; std::memcpy(&v, b, 4); out = v; break; }
    case PlyType::Float64: { std::memcpy(&out, b, 8); break; }
    case PlyType::Invalid: return false;
    }
    return true;
}

bool hostIsLittleEndian()
{
    const uint16_t one = 1;
    unsigned char c;
    std::memcpy(&c, &one, 1);
    return c == 1;
}

void prescanPly(const std::string& path, Prescan& out)
{
    FileReader reader(path);
    std::string_view line, rest, tok;
    if (!reader.nextLine(line)) throwInvalid(path, 0, "the file is empty");
    if (trimmed(line) != "ply") {
        throwInvalid(path, 1, "not a PLY file: the first line is " + message_internal::quotedExcerpt(trimmed(line)) +
            ", expected 'ply'");
    }
    PlyFormat format = PlyFormat::Ascii;
    bool haveFormat = false, ended = false;
    std::vector<PlyElement> elements;
    // OpenMesh parses the header token by token across lines and loops forever when a line has
    // a token too few or a non-number where it expects one: check every line exactly.
    std::string_view t[6];
    while (reader.nextLine(line)) {
        rest = line;
        if (!nextToken(rest, t[0])) continue;
        if (t[0] == "comment" || t[0] == "obj_info") continue;
        int n = 1;
        while (n < 6 && nextToken(rest, t[n])) ++n;
        if (n == 6 || nextToken(rest, tok)) n = 7; // too many
        auto malformed = [&](const char* expected) {
            throwInvalid(path, reader.lineNumber(), "malformed PLY header line " + message_internal::quotedExcerpt(trimmed(line)) +
                ", expected '" + expected + "'");
        };
        if (t[0] == "end_header") {
            if (n != 1) malformed("end_header");
            ended = true;
            break;
        }
        if (t[0] == "format") {
            double version = 0;
            if (n != 3 || parseCoordinate(t[2], version) != NumberStatus::Ok) {
                malformed("format ascii|binary_little_endian|binary_big_endian 1.0");
            }
            if (t[1] == "ascii") format = PlyFormat::Ascii;
            else if (t[1] == "binary_little_endian") format = PlyFormat::BinaryLE;
            else if (t[1] == "binary_big_endian") format = PlyFormat::BinaryBE;
            else throwInvalid(path, reader.lineNumber(), "unknown PLY format " + message_internal::quotedExcerpt(t[1]));
            haveFormat = true;
        } else if (t[0] == "element") {
            PlyElement e;
            if (n != 3 || !parseInteger(t[2], e.count) ||
                e.count > uint64_t(std::numeric_limits<int>::max())) {
                malformed("element <name> <count>");
            }
            e.name = std::string(t[1]);
            elements.push_back(std::move(e));
        } else if (t[0] == "property") {
            if (elements.empty()) {
                throwInvalid(path, reader.lineNumber(), "property before any element");
            }
            PlyProperty prop;
            if (n >= 2 && t[1] == "list") {
                if (n != 5) malformed("property list <count type> <item type> <name>");
                prop.isList = true;
                prop.countType = plyType(t[2]);
                prop.type = plyType(t[3]);
                prop.name = std::string(t[4]);
                if (prop.countType == PlyType::Invalid || prop.type == PlyType::Invalid ||
                    prop.countType == PlyType::Float32 || prop.countType == PlyType::Float64) {
                    throwInvalid(path, reader.lineNumber(), "unsupported PLY list types in " +
                        message_internal::quotedExcerpt(trimmed(line)));
                }
            } else {
                if (n != 3) malformed("property <type> <name>");
                prop.type = plyType(t[1]);
                prop.name = std::string(t[2]);
                if (prop.type == PlyType::Invalid) {
                    throwInvalid(path, reader.lineNumber(), "unknown PLY type " + message_internal::quotedExcerpt(t[1]));
                }
            }
            elements.back().props.push_back(std::move(prop));
        } else {
            const bool number = std::isdigit(static_cast<unsigned char>(t[0][0])) || t[0][0] == '-' ||
                                t[0][0] == '.';
            throwInvalid(path, reader.lineNumber(), "unknown PLY header keyword " + message_internal::quotedExcerpt(t[0]) +
                (number ? " (is 'end_header' missing?)" : ""));
        }
    }
    if (!ended) throwInvalid(path, reader.lineNumber(), "the PLY header has no 'end_header'");
    if (!haveFormat) throwInvalid(path, 0, "the PLY header has no 'format' line");
    out.binary = format != PlyFormat::Ascii;
    const bool swap = (format == PlyFormat::BinaryLE) != hostIsLittleEndian();

    uint64_t nV = 0;
    for (const PlyElement& e : elements) {
        if (e.name == "vertex") nV = e.count;
    }
    TokenReader tokens(reader);
    bool sawVertices = false;
    for (const PlyElement& e : elements) {
        const bool isVertex = e.name == "vertex";
        const bool isFace = e.name == "face";
        int xyz[3] = {-1, -1, -1};
        int faceList = -1;
        for (size_t i = 0; i < e.props.size(); ++i) {
            const PlyProperty& p = e.props[i];
            if (isVertex && !p.isList) {
                if (p.name == "x") xyz[0] = int(i);
                if (p.name == "y") xyz[1] = int(i);
                if (p.name == "z") xyz[2] = int(i);
            }
            if (isFace && p.isList && (p.name == "vertex_indices" || p.name == "vertex_index")) {
                faceList = int(i);
            }
        }
        const bool keepPoints = isVertex && xyz[0] >= 0 && xyz[1] >= 0 && xyz[2] >= 0;
        if (keepPoints) out.points.resize(e.count);
        if (isVertex) sawVertices = true;
        const std::string what = isVertex ? "vertex" : (isFace ? "face" : e.name);
        for (uint64_t n = 0; n < e.count; ++n) {
            for (size_t i = 0; i < e.props.size(); ++i) {
                const PlyProperty& p = e.props[i];
                double value = 0;
                uint64_t items = 1;
                if (p.isList) {
                    if (format == PlyFormat::Ascii) {
                        if (!tokens.next(tok) || !parseInteger(tok, items)) {
                            throwInvalid(path, tokens.line(), what + " " + std::to_string(n) +
                                ": cannot read the list length of '" + p.name + "'");
                        }
                    } else {
                        if (!readPlyBinary(reader, p.countType, swap, value)) {
                            throwInvalid(path, 0, "the file ends inside " + what + " " + std::to_string(n));
                        }
                        items = uint64_t(value);
                    }
                }
                for (uint64_t k = 0; k < items; ++k) {
                    NumberStatus st = NumberStatus::Ok;
                    if (format == PlyFormat::Ascii) {
                        if (!tokens.next(tok)) {
                            throwInvalid(path, tokens.line(), "the file ends inside " + what + " " +
                                std::to_string(n) + " of " + std::to_string(e.count));
                        }
                        st = parseCoordinate(tok, value);
                        if (st == NumberStatus::NotANumber) {
                            throwInvalid(path, tokens.line(), what + " " + std::to_string(n) +
                                ": cannot parse the value " + message_internal::quotedExcerpt(tok) + " of '" + p.name + "'");
                        }
                    } else {
                        if (!readPlyBinary(reader, p.type, swap, value)) {
                            throwInvalid(path, 0, "the file ends inside " + what + " " +
                                std::to_string(n) + " of " + std::to_string(e.count));
                        }
                        if (!std::isfinite(value)) st = NumberStatus::NonFinite;
                        else if (std::abs(value) > double(FLT_MAX)) st = NumberStatus::OutOfFloatRange;
                    }
                    const uint64_t lineNo = format == PlyFormat::Ascii ? tokens.line() : 0;
                    if (keepPoints && (int(i) == xyz[0] || int(i) == xyz[1] || int(i) == xyz[2])) {
                        if (st != NumberStatus::Ok) {
                            throwInvalid(path, lineNo, "vertex " + std::to_string(n) + ": " +
                                describeCoordinateProblem(st, format == PlyFormat::Ascii ? tok
                                    : std::string_view(formatDouble(value))));
                        }
                        out.points[n][int(i) == xyz[0] ? 0 : (int(i) == xyz[1] ? 1 : 2)] = value;
                    }
                    if (int(i) == faceList) {
                        if (st != NumberStatus::Ok || value != std::floor(value) || value < 0 ||
                            value >= double(nV) || !sawVertices) {
                            throwInvalid(path, lineNo, "face " + std::to_string(n) + ": vertex index " +
                                formatDouble(value) + " is out of range (the file has " +
                                std::to_string(nV) + " vertices, numbered from 0)");
                        }
                    }
                }
            }
        }
        if (isFace) {
            out.faces = e.count;
            out.haveFaces = true;
        }
        if (keepPoints) out.havePoints = true;
    }
}

/// OpenMesh's rule: a .stl file is binary when its size is 84 + 50 * (facet count in the header).
bool stlIsBinary(const std::string& path, const std::string& ext)
{
    if (ext == ".stlb") return true;
    if (ext == ".stla") return false;
    std::error_code ec;
    const uint64_t size = fs::file_size(path, ec);
    if (ec || size < 84) return false;
    FileReader r(path);
    char header[80];
    uint32_t n = 0;
    if (!r.readBytes(header, 80) || !r.readBytes(&n, 4)) return false;
    if (!hostIsLittleEndian()) n = __builtin_bswap32(n);
    return size == 84 + 50 * uint64_t(n);
}

// STL: every corner coordinate finite (a NaN corner in a binary STL is merged away by OpenMesh's
// vertex map and the facet disappears); counts facets.
void prescanStl(const std::string& path, const std::string& ext, Prescan& out)
{
    out.binary = stlIsBinary(path, ext);
    FileReader reader(path);
    if (out.binary) {
        char header[80];
        uint32_t n = 0;
        if (!reader.readBytes(header, 80) || !reader.readBytes(&n, 4)) {
            throwInvalid(path, 0, "truncated binary STL header");
        }
        if (!hostIsLittleEndian()) n = __builtin_bswap32(n);
        unsigned char rec[50];
        for (uint32_t f = 0; f < n; ++f) {
            if (!reader.readBytes(rec, 50)) {
                throwInvalid(path, 0, "the file ends inside facet " + std::to_string(f) + " of " +
                    std::to_string(n));
            }
            for (int c = 0; c < 3; ++c) {
                for (int k = 0; k < 3; ++k) {
                    unsigned char b[4];
                    std::memcpy(b, rec + 12 + 12 * c + 4 * k, 4);
                    if (!hostIsLittleEndian()) std::reverse(b, b + 4);
                    float v;
                    std::memcpy(&v, b, 4);
                    if (!std::isfinite(v)) {
                        throwInvalid(path, 0, "facet " + std::to_string(f) + ", corner " +
                            std::to_string(c) + ": non-finite coordinate " + formatDouble(v));
                    }
                }
            }
        }
        out.faces = n;
        out.haveFaces = true;
        return;
    }
    // ASCII: as OpenMesh does, a line containing "outer" starts a facet whose corners are the
    // next three lines ("vertex x y z").
    std::string_view line, rest, tok;
    uint64_t facets = 0;
    while (reader.nextLine(line)) {
        if (line.find("outer") == std::string_view::npos && line.find("OUTER") == std::string_view::npos) {
            continue;
        }
        for (int c = 0; c < 3; ++c) {
            if (!reader.nextLine(line)) {
                throwInvalid(path, reader.lineNumber(), "the file ends inside facet " + std::to_string(facets));
            }
            rest = line;
            nextToken(rest, tok); // "vertex"
            for (int k = 0; k < 3; ++k) {
                double v = 0;
                if (!nextToken(rest, tok)) {
                    throwInvalid(path, reader.lineNumber(), "facet " + std::to_string(facets) +
                        ", corner " + std::to_string(c) + ": expected 'vertex x y z'");
                }
                const NumberStatus st = parseCoordinate(tok, v);
                if (st != NumberStatus::Ok) {
                    throwInvalid(path, reader.lineNumber(), "facet " + std::to_string(facets) +
                        ", corner " + std::to_string(c) + ": " + describeCoordinateProblem(st, tok));
                }
            }
        }
        ++facets;
    }
    out.faces = facets;
    out.haveFaces = true;
}

// --------------------------------------------------------------------------------- importer

/// Receives OpenMesh's reader calls. Vertices and faces go into flat arrays; no half-edges.
class Importer final : public OpenMesh::IO::BaseImporter
{
public:
    using VertexHandle = OpenMesh::VertexHandle;
    using FaceHandle = OpenMesh::FaceHandle;
    using HalfedgeHandle = OpenMesh::HalfedgeHandle;
    using EdgeHandle = OpenMesh::EdgeHandle;
    using Vec2f = OpenMesh::Vec2f;
    using Vec3f = OpenMesh::Vec3f;
    using Vec3dOM = OpenMesh::Vec3d;
    using Vec3uc = OpenMesh::Vec3uc;
    using Vec4uc = OpenMesh::Vec4uc;
    using Vec4f = OpenMesh::Vec4f;
    using Status = OpenMesh::Attributes::StatusInfo;

    std::vector<Vec3d> mPoints;
    std::vector<int32_t> mFaceStream; ///< per face: corner count, then the corner indices
    uint64_t mFaceCount = 0;

    VertexHandle add_vertex(const Vec3f& p) override { return addPoint(Vec3d(p[0], p[1], p[2])); }
    VertexHandle add_vertex(const Vec3dOM& p) override { return addPoint(Vec3d(p[0], p[1], p[2])); }
    VertexHandle add_vertex() override { return addPoint(Vec3d(0.0)); }
    void set_point(VertexHandle vh, const Vec3f& p) override
    {
        if (vh.idx() >= 0 && size_t(vh.idx()) < mPoints.size()) {
            mPoints[size_t(vh.idx())] = Vec3d(p[0], p[1], p[2]);
        }
    }
    FaceHandle add_face(const VHandles& corners) override
    {
        mFaceStream.push_back(int32_t(corners.size()));
        for (const VertexHandle& h : corners) mFaceStream.push_back(h.idx());
        return FaceHandle(int(mFaceCount++));
    }
    void reserve(unsigned int nV, unsigned int, unsigned int nF) override
    {
        // A hint from the file's header: capped, the pre-scan has checked it against the data.
        constexpr unsigned int kCap = 1u << 26;
        mPoints.reserve(std::min(nV, kCap));
        mFaceStream.reserve(size_t(std::min(nF, kCap)) * 4);
    }
    size_t n_vertices() const override { return mPoints.size(); }
    size_t n_faces() const override { return size_t(mFaceCount); }
    size_t n_edges() const override { return 0; }

    // Half-edge construction (OM format only) is not supported: nothing is built.
    HalfedgeHandle add_edge(VertexHandle, VertexHandle) override { return HalfedgeHandle(); }
    FaceHandle add_face(HalfedgeHandle) override { return FaceHandle(); }

    // Attributes are irrelevant to distance fields: ignored.
    void add_face_texcoords(FaceHandle, VertexHandle, const std::vector<Vec2f>&) override {}
    void add_face_texcoords(FaceHandle, VertexHandle, const std::vector<Vec3f>&) override {}
    void set_face_texindex(FaceHandle, int) override {}
    void set_halfedge(VertexHandle, HalfedgeHandle) override {}
    void set_normal(VertexHandle, const Vec3f&) override {}
    void set_normal(VertexHandle, const Vec3dOM&) override {}
    void set_color(VertexHandle, const Vec3uc&) override {}
    void set_color(VertexHandle, const Vec4uc&) override {}
    void set_color(VertexHandle, const Vec3f&) override {}
    void set_color(VertexHandle, const Vec4f&) override {}
    void set_texcoord(VertexHandle, const Vec2f&) override {}
    void set_status(VertexHandle, const Status&) override {}
    void set_next(HalfedgeHandle, HalfedgeHandle) override {}
    void set_face(HalfedgeHandle, FaceHandle) override {}
    void request_face_texcoords2D() override {}
    void set_texcoord(HalfedgeHandle, const Vec2f&) override {}
    void set_texcoord(VertexHandle, const Vec3f&) override {}
    void set_texcoord(HalfedgeHandle, const Vec3f&) override {}
    void set_status(HalfedgeHandle, const Status&) override {}
    void set_color(EdgeHandle, const Vec3uc&) override {}
    void set_color(EdgeHandle, const Vec4uc&) override {}
    void set_color(EdgeHandle, const Vec3f&) override {}
    void set_color(EdgeHandle, const Vec4f&) override {}
    void set_status(EdgeHandle, const Status&) override {}
    void set_normal(FaceHandle, const Vec3f&) override {}
    void set_normal(FaceHandle, const Vec3dOM&) override {}
    void set_color(FaceHandle, const Vec3uc&) override {}
    void set_color(FaceHandle, const Vec4uc&) override {}
    void set_color(FaceHandle, const Vec3f&) override {}
    void set_color(FaceHandle, const Vec4f&) override {}
    void set_status(FaceHandle, const Status&) override {}
    void add_texture_information(int, std::string) override {}

private:
    VertexHandle addPoint(const Vec3d& p)
    {
        mPoints.push_back(p);
        return VertexHandle(int(mPoints.size() - 1));
    }
};

// ----------------------------------------------------------------------------- ear clipping

/// Triangulates simple polygons by ear clipping in their best-fit plane. Buffers are reused
/// from polygon to polygon.
class EarClipper
{
public:
    /// Appends triangles for @a corners (k >= 4 distinct consecutive corners) to @a out.
    /// Returns false if it had to fall back to a fan.
    bool triangulate(const std::vector<Vec3d>& P, const uint32_t* corners, size_t k,
                     std::vector<Vec3I>& out)
    {
        // Newell normal, relative to the first corner for accuracy.
        const Vec3d o = P[corners[0]];
        Vec3d n(0.0);
        for (size_t i = 0; i < k; ++i) {
            const Vec3d a = P[corners[i]] - o;
            const Vec3d b = P[corners[(i + 1) % k]] - o;
            n += a.cross(b);
        }
        const double len = n.length();
        if (!(len > 0.0)) return fan(corners, k, out);
        n /= len;
        // Orthonormal basis (u, v) of the plane with u x v = n: the polygon is CCW in (u, v).
        Vec3d u = std::abs(n[0]) < 0.9 ? Vec3d(1, 0, 0).cross(n) : Vec3d(0, 1, 0).cross(n);
        u.normalize();
        const Vec3d v = n.cross(u);
        mQ.resize(k);
        for (size_t i = 0; i < k; ++i) {
            const Vec3d d = P[corners[i]] - o;
            mQ[i] = {d.dot(u), d.dot(v)};
        }
        mRing.resize(k);
        for (size_t i = 0; i < k; ++i) mRing[i] = uint32_t(i);

        size_t guard = 0;
        size_t i = 0;
        while (mRing.size() > 3) {
            const size_t m = mRing.size();
            if (guard++ > m) { // went once around without finding an ear
                fanRing(corners, out);
                return false;
            }
            const size_t ip = (i + m - 1) % m, in = (i + 1) % m;
            const uint32_t a = mRing[ip], b = mRing[i], c = mRing[in];
            if (isEar(a, b, c)) {
                out.emplace_back(corners[a], corners[b], corners[c]);
                mRing.erase(mRing.begin() + std::ptrdiff_t(i));
                if (i >= mRing.size()) i = 0;
                guard = 0;
            } else {
                i = (i + 1) % m;
            }
        }
        out.emplace_back(corners[mRing[0]], corners[mRing[1]], corners[mRing[2]]);
        return true;
    }

private:
    struct P2 { double x, y; };

    static double orient(const P2& a, const P2& b, const P2& c)
    {
        return (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
    }

    bool isEar(uint32_t a, uint32_t b, uint32_t c) const
    {
        const P2 &A = mQ[a], &B = mQ[b], &C = mQ[c];
        if (!(orient(A, B, C) > 0.0)) return false; // reflex or flat corner
        for (uint32_t r : mRing) {
            if (r == a || r == b || r == c) continue;
            const P2& R = mQ[r];
            if ((R.x == A.x && R.y == A.y) || (R.x == B.x && R.y == B.y) || (R.x == C.x && R.y == C.y)) {
                continue; // a repeated position (touching polygon)
            }
            if (orient(A, B, R) >= 0.0 && orient(B, C, R) >= 0.0 && orient(C, A, R) >= 0.0) return false;
        }
        return true;
    }

    static bool fan(const uint32_t* corners, size_t k, std::vector<Vec3I>& out)
    {
        for (size_t i = 1; i + 1 < k; ++i) out.emplace_back(corners[0], corners[i], corners[i + 1]);
        return false;
    }

    void fanRing(const uint32_t* corners, std::vector<Vec3I>& out) const
    {
        for (size_t i = 1; i + 1 < mRing.size(); ++i) {
            out.emplace_back(corners[mRing[0]], corners[mRing[i]], corners[mRing[i + 1]]);
        }
    }

    std::vector<P2> mQ;
    std::vector<uint32_t> mRing;
};

// ------------------------------------------------------------------------------- assembling

/// True when the float OpenMesh produced is (within one float step of) the exact value.
inline bool sameAsFloat(double exact, double received)
{
    const float f = float(exact);
    const float r = float(received);
    return f == r || std::nextafter(f, FLT_MAX) == r || std::nextafter(f, -FLT_MAX) == r;
}

void assemble(const std::string& path, Importer& imp, Prescan& pre, TriangleMesh& mesh,
              MeshReadInfo& info)
{
    // Positions: exact doubles from the pre-scan when they agree with what OpenMesh read.
    bool exact = pre.havePoints && pre.points.size() == imp.mPoints.size();
    for (size_t i = 0; exact && i < pre.points.size(); ++i) {
        for (int k = 0; k < 3; ++k) {
            if (!sameAsFloat(pre.points[i][k], imp.mPoints[i][k])) { exact = false; break; }
        }
    }
    if (exact) {
        mesh.points = std::move(pre.points);
    } else {
        mesh.points = std::move(imp.mPoints);
    }
    info.doublePrecision = exact;
    info.fileVertices = mesh.points.size();
    for (size_t i = 0; i < mesh.points.size(); ++i) {
        const Vec3d& p = mesh.points[i];
        if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2])) {
            throwInvalid(path, 0, "vertex " + std::to_string(i) + " has a non-finite coordinate " +
                formatPoint(p));
        }
    }

    // Faces: range check, drop faces with fewer than three distinct corners, triangulate.
    const int64_t nV = int64_t(mesh.points.size());
    std::vector<uint32_t> poly;
    EarClipper clipper;
    const std::vector<int32_t>& s = imp.mFaceStream;
    size_t pos = 0, expected = 0;
    for (uint64_t f = 0; f < imp.mFaceCount; ++f) { // at most k - 2 triangles per face
        const size_t k = size_t(s[pos]);
        expected += k >= 3 ? k - 2 : 0;
        pos += 1 + k;
    }
    mesh.triangles.clear();
    mesh.triangles.reserve(expected);
    uint64_t dropped = 0;
    pos = 0;
    for (uint64_t f = 0; f < imp.mFaceCount; ++f) {
        const size_t k = size_t(s[pos]);
        const int32_t* c = s.data() + pos + 1;
        pos += 1 + k;
        for (size_t j = 0; j < k; ++j) {
            if (c[j] < 0 || c[j] >= nV) {
                throwInvalid(path, 0, "face " + std::to_string(f) + ": vertex index " +
                    (c[j] < 0 ? std::string("invalid (negative)") : std::to_string(c[j])) +
                    " is out of range (the file has " + std::to_string(nV) + " vertices)");
            }
        }
        if (k == 3) {
            if (c[0] == c[1] || c[1] == c[2] || c[0] == c[2]) {
                ++dropped;
            } else {
                mesh.triangles.emplace_back(uint32_t(c[0]), uint32_t(c[1]), uint32_t(c[2]));
            }
            continue;
        }
        // Polygon: remove repeated consecutive corners (cyclically).
        poly.clear();
        for (size_t j = 0; j < k; ++j) {
            const uint32_t idx = uint32_t(c[j]);
            if (poly.empty() || poly.back() != idx) poly.push_back(idx);
        }
        while (poly.size() > 1 && poly.back() == poly.front()) poly.pop_back();
        size_t distinct = poly.size();
        if (distinct >= 3) { // count distinct values (small polygons: quadratic is fine)
            distinct = 0;
            for (size_t j = 0; j < poly.size(); ++j) {
                if (std::find(poly.begin(), poly.begin() + std::ptrdiff_t(j), poly[j]) ==
                    poly.begin() + std::ptrdiff_t(j)) {
                    ++distinct;
                }
            }
        }
        if (distinct < 3) {
            ++dropped;
            continue;
        }
        if (poly.size() == 3) {
            mesh.triangles.emplace_back(poly[0], poly[1], poly[2]);
            continue;
        }
        ++info.polygons;
        const size_t first = mesh.triangles.size();
        if (!clipper.triangulate(mesh.points, poly.data(), poly.size(), mesh.triangles)) {
            ++info.fanFallbacks;
            // A fan over a polygon that repeats a corner may produce collapsed triangles.
            auto collapsed = [](const Vec3I& t) { return t[0] == t[1] || t[1] == t[2] || t[0] == t[2]; };
            mesh.triangles.erase(std::remove_if(mesh.triangles.begin() + std::ptrdiff_t(first),
                                     mesh.triangles.end(), collapsed), mesh.triangles.end());
        }
    }
    const uint64_t received = imp.mFaceCount;
    info.fileFaces = pre.haveFaces ? std::max(pre.faces, received) : received;
    info.droppedFaces = dropped + (info.fileFaces - received);
    if (mesh.triangles.empty()) {
        std::string what = "no triangles (read " + std::to_string(mesh.points.size()) +
            " vertices and " + std::to_string(info.fileFaces) + " faces";
        if (info.droppedFaces > 0) {
            what += ", " + std::to_string(info.droppedFaces) + " of them without area";
        } else if (info.fileFaces == 0) {
            what += "; is it really a ." + info.format + " file?";
        }
        throwInvalid(path, 0, what + ")");
    }
}

/// Silences OpenMesh's omerr/omlog while it reads (our exceptions carry the message).
class QuietOpenMesh
{
public:
    QuietOpenMesh()
        : mErr(::omerr().is_enabled()), mLog(::omlog().is_enabled())
        , mOut(::omout().is_enabled())
    {
        ::omerr().disable();
        ::omlog().disable();
        ::omout().disable();
    }
    ~QuietOpenMesh()
    {
        if (mErr) ::omerr().enable();
        if (mLog) ::omlog().enable();
        if (mOut) ::omout().enable();
    }

private:
    bool mErr, mLog, mOut;
};

std::mutex& openMeshMutex()
{
    static std::mutex m;
    return m;
}

const std::vector<std::string>& readableExtensions()
{
    static const std::vector<std::string> exts = {".obj", ".off", ".ply", ".stl", ".stla", ".stlb"};
    return exts;
}

// ---------------------------------------------------------------------------------- writing

/// Writes a file through a temporary sibling that is renamed over the target on commit().
class AtomicFileWriter
{
public:
    explicit AtomicFileWriter(const std::string& path) : mPath(path)
    {
        static std::atomic<uint64_t> counter{0};
        // A hidden sibling ending in .tmp (git-ignorable), unique per process and call.
        const fs::path target(path);
        mTemp = (target.parent_path() / ("." + target.filename().string() + "." +
                 std::to_string(::getpid()) + "." + std::to_string(counter++) + ".tmp")).string();
        mFile = std::fopen(mTemp.c_str(), "wb");
        if (!mFile) {
            throw IoError("cannot write mesh file '" + path + "': " + std::strerror(errno));
        }
        mBuf.reserve(kChunk + 256);
    }
    ~AtomicFileWriter()
    {
        if (mFile) std::fclose(mFile);
        if (!mCommitted) {
            std::error_code ec;
            fs::remove(mTemp, ec);
        }
    }
    AtomicFileWriter(const AtomicFileWriter&) = delete;
    AtomicFileWriter& operator=(const AtomicFileWriter&) = delete;

    void put(const void* data, size_t n)
    {
        mBuf.append(static_cast<const char*>(data), n);
        if (mBuf.size() >= kChunk) flush();
    }
    void put(std::string_view s) { put(s.data(), s.size()); }
    void put(char c) { mBuf.push_back(c); }
    void putNumber(double v)
    {
        char tmp[64];
        const auto r = std::to_chars(tmp, tmp + sizeof(tmp), v); // shortest round-trip form
        put(tmp, size_t(r.ptr - tmp));
    }
    void putNumber(uint64_t v)
    {
        char tmp[32];
        const auto r = std::to_chars(tmp, tmp + sizeof(tmp), v);
        put(tmp, size_t(r.ptr - tmp));
    }
    template<typename T>
    void putLittleEndian(T v)
    {
        unsigned char b[sizeof(T)];
        std::memcpy(b, &v, sizeof(T));
        if (!hostIsLittleEndian()) std::reverse(b, b + sizeof(T));
        put(b, sizeof(T));
    }

    void commit()
    {
        flush();
        const bool bad = std::fflush(mFile) != 0 || std::ferror(mFile);
        const int closeResult = std::fclose(mFile);
        mFile = nullptr;
        if (bad || closeResult != 0) {
            throw IoError("cannot write mesh file '" + mPath + "': " + std::strerror(errno));
        }
        std::error_code ec;
        fs::rename(mTemp, mPath, ec);
        if (ec) throw IoError("cannot write mesh file '" + mPath + "': " + ec.message());
        mCommitted = true;
    }

private:
    void flush()
    {
        if (mBuf.empty()) return;
        if (std::fwrite(mBuf.data(), 1, mBuf.size(), mFile) != mBuf.size()) {
            throw IoError("cannot write mesh file '" + mPath + "': " + std::strerror(errno));
        }
        mBuf.clear();
    }

    static constexpr size_t kChunk = size_t(1) << 20;
    std::string mPath, mTemp;
    std::FILE* mFile = nullptr;
    std::string mBuf;
    bool mCommitted = false;
};

std::string oneLine(const std::string& s)
{
    std::string out = s;
    for (char& c : out) {
        if (c == '\n' || c == '\r') c = ' ';
    }
    return out;
}

void writeObj(const TriangleMesh& mesh, AtomicFileWriter& w)
{
    w.put("# written by levelforge\n");
    if (!mesh.source.empty()) {
        w.put("# source: ");
        w.put(oneLine(mesh.source));
        w.put('\n');
    }
    for (const Vec3d& p : mesh.points) {
        w.put("v ");
        w.putNumber(p[0]);
        w.put(' ');
        w.putNumber(p[1]);
        w.put(' ');
        w.putNumber(p[2]);
        w.put('\n');
    }
    for (const Vec3I& t : mesh.triangles) {
        w.put("f ");
        w.putNumber(uint64_t(t[0]) + 1);
        w.put(' ');
        w.putNumber(uint64_t(t[1]) + 1);
        w.put(' ');
        w.putNumber(uint64_t(t[2]) + 1);
        w.put('\n');
    }
}

void writeOff(const TriangleMesh& mesh, AtomicFileWriter& w)
{
    w.put("OFF\n");
    w.putNumber(uint64_t(mesh.points.size()));
    w.put(' ');
    w.putNumber(uint64_t(mesh.triangles.size()));
    w.put(" 0\n");
    for (const Vec3d& p : mesh.points) {
        w.putNumber(p[0]);
        w.put(' ');
        w.putNumber(p[1]);
        w.put(' ');
        w.putNumber(p[2]);
        w.put('\n');
    }
    for (const Vec3I& t : mesh.triangles) {
        w.put("3 ");
        w.putNumber(uint64_t(t[0]));
        w.put(' ');
        w.putNumber(uint64_t(t[1]));
        w.put(' ');
        w.putNumber(uint64_t(t[2]));
        w.put('\n');
    }
}

void writePly(const TriangleMesh& mesh, AtomicFileWriter& w)
{
    const bool smallIndices = mesh.points.size() <= size_t(std::numeric_limits<int32_t>::max());
    std::string header = "ply\nformat binary_little_endian 1.0\ncomment written by levelforge\n";
    if (!mesh.source.empty()) header += "comment source: " + oneLine(mesh.source) + "\n";
    header += "element vertex " + std::to_string(mesh.points.size()) + "\n";
    header += "property double x\nproperty double y\nproperty double z\n";
    header += "element face " + std::to_string(mesh.triangles.size()) + "\n";
    header += smallIndices ? "property list uchar int vertex_indices\n"
                           : "property list uchar uint vertex_indices\n";
    header += "end_header\n";
    w.put(header);
    for (const Vec3d& p : mesh.points) {
        w.putLittleEndian(p[0]);
        w.putLittleEndian(p[1]);
        w.putLittleEndian(p[2]);
    }
    for (const Vec3I& t : mesh.triangles) {
        w.putLittleEndian(uint8_t(3));
        w.putLittleEndian(uint32_t(t[0]));
        w.putLittleEndian(uint32_t(t[1]));
        w.putLittleEndian(uint32_t(t[2]));
    }
}

void writeStl(const TriangleMesh& mesh, const std::string& path, AtomicFileWriter& w)
{
    if (mesh.triangles.size() > size_t(std::numeric_limits<uint32_t>::max())) {
        throw IoError("cannot write mesh file '" + path + "': binary STL holds at most 2^32-1 triangles");
    }
    // 80-byte header that does not start with "solid" (some readers take that for ASCII).
    char header[80];
    std::memset(header, ' ', sizeof(header));
    const std::string text = "levelforge binary STL " + oneLine(mesh.source);
    std::memcpy(header, text.data(), std::min(text.size(), sizeof(header)));
    w.put(header, sizeof(header));
    w.putLittleEndian(uint32_t(mesh.triangles.size()));
    const size_t nV = mesh.points.size();
    for (size_t i = 0; i < mesh.triangles.size(); ++i) {
        const Vec3I& t = mesh.triangles[i];
        if (t[0] >= nV || t[1] >= nV || t[2] >= nV) {
            throw InvalidMeshError(path + ": cannot write triangle " + std::to_string(i) +
                ": vertex index out of range (the mesh has " + std::to_string(nV) + " vertices)");
        }
        const Vec3d &a = mesh.points[t[0]], &b = mesh.points[t[1]], &c = mesh.points[t[2]];
        Vec3d n = (b - a).cross(c - a);
        const double len = n.length();
        n = len > 0.0 ? n / len : Vec3d(0.0);
        for (int k = 0; k < 3; ++k) w.putLittleEndian(float(n[k]));
        for (const Vec3d* p : {&a, &b, &c}) {
            for (int k = 0; k < 3; ++k) w.putLittleEndian(float((*p)[k]));
        }
        w.putLittleEndian(uint16_t(0));
    }
}

} // namespace meshio_internal

// ====================================================================================== API

bool isReadableMeshFile(const std::string& path)
{
    const std::string ext = meshio_internal::lowerExtension(path);
    const auto& exts = meshio_internal::readableExtensions();
    return std::find(exts.begin(), exts.end(), ext) != exts.end();
}

std::vector<std::string> readableMeshExtensions()
{
    return meshio_internal::readableExtensions();
}

TriangleMesh readMesh(const std::string& path)
{
    MeshReadInfo info;
    return readMesh(path, info);
}

TriangleMesh readMesh(const std::string& path, MeshReadInfo& info)
{
    using namespace meshio_internal;
    info = MeshReadInfo();
    const std::string ext = lowerExtension(path);
    if (!isReadableMeshFile(path)) {
        throw IoError("cannot read mesh file '" + path + "': " +
            (ext.empty() ? std::string("no file extension") : "unsupported format '" + ext + "'") +
            " (supported: .obj .off .ply .stl)");
    }
    std::error_code ec;
    if (!fs::exists(path, ec)) throw IoError("mesh file '" + path + "' does not exist");
    if (!fs::is_regular_file(path, ec)) throw IoError("mesh file '" + path + "' is not a regular file");
    {
        FileReader probe(path); // throws IoError when it cannot be opened (permissions)
    }
    if (fs::file_size(path, ec) == 0 && !ec) throwInvalid(path, 0, "the file is empty");

    info.format = ext == ".stla" || ext == ".stlb" ? "stl" : ext.substr(1);

    Prescan pre;
    if (info.format == "obj") prescanObj(path, pre);
    else if (info.format == "off") prescanOff(path, pre);
    else if (info.format == "ply") prescanPly(path, pre);
    else prescanStl(path, ext, pre);
    info.binary = pre.binary;

    Importer importer;
    bool ok = false;
    {
        std::lock_guard<std::mutex> lock(openMeshMutex());
        // Make sure the reader modules exist (they register themselves with the IOManager).
        (void)OpenMesh::IO::OBJReader();
        (void)OpenMesh::IO::OFFReader();
        (void)OpenMesh::IO::PLYReader();
        (void)OpenMesh::IO::STLReader();
        QuietOpenMesh quiet;
        OpenMesh::IO::Options options; // positions and faces only
        ok = OpenMesh::IO::IOManager().read(path, importer, options);
    }
    if (!ok) {
        throwInvalid(path, 0, "OpenMesh could not parse the file as " + info.format +
            (info.format == "off" ? " (4OFF/nOFF and malformed headers are not supported)" : ""));
    }

    TriangleMesh mesh;
    mesh.source = path;
    assemble(path, importer, pre, mesh, info);
    return mesh;
}

void writeMesh(const TriangleMesh& mesh, const std::string& path)
{
    using namespace meshio_internal;
    const std::string ext = lowerExtension(path);
    if (ext != ".obj" && ext != ".off" && ext != ".ply" && ext != ".stl") {
        throw IoError("cannot write mesh file '" + path + "': unsupported format '" + ext +
            "' (supported: .obj .off .ply .stl)");
    }
    AtomicFileWriter w(path);
    if (ext == ".obj") writeObj(mesh, w);
    else if (ext == ".off") writeOff(mesh, w);
    else if (ext == ".ply") writePly(mesh, w);
    else writeStl(mesh, path, w);
    w.commit();
}

} // namespace levelforge
