// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief writeMesh(): OBJ and OFF (shortest round-trip decimal form), binary little-endian PLY
///        (float coordinates when every coordinate is exactly a float, else double) and binary STL, each written atomically.
#include "io/MeshIOInternal.h"

#include "detail/AtomicFile.h"

#include <cmath>
#include <cstdio>
#include <cstring>
#include <vector>
#include <limits>

namespace levelforge {

namespace meshio_internal {

// ---------------------------------------------------------------------------------- writing

/// Buffered writing of a mesh file through a detail::AtomicFile: the file appears on commit().
class MeshFileWriter
{
public:
    explicit MeshFileWriter(const std::string& path)
        : mFile(path, "cannot write mesh file '" + path + "'")
    {
        mStream = ::fdopen(mFile.descriptor(), "wb");
        if (!mStream) mFile.fail(std::strerror(errno));
        mFile.releaseDescriptor(); // now owned by mStream
        mBuf.reserve(kChunk + 256);
    }
    ~MeshFileWriter()
    {
        if (mStream) std::fclose(mStream);
        // mFile removes the temporary file unless committed.
    }
    MeshFileWriter(const MeshFileWriter&) = delete;
    MeshFileWriter& operator=(const MeshFileWriter&) = delete;

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
        if (kHostBigEndian) std::reverse(b, b + sizeof(T));
        put(b, sizeof(T));
    }

    void commit()
    {
        flush();
        const bool bad = std::fflush(mStream) != 0 || std::ferror(mStream);
        const int closeResult = std::fclose(mStream);
        mStream = nullptr;
        if (bad || closeResult != 0) mFile.fail(std::strerror(errno));
        mFile.sync();
        mFile.commit();
    }

private:
    void flush()
    {
        if (mBuf.empty()) return;
        if (std::fwrite(mBuf.data(), 1, mBuf.size(), mStream) != mBuf.size()) {
            mFile.fail(std::strerror(errno));
        }
        mBuf.clear();
    }

    static constexpr size_t kChunk = size_t(1) << 20;
    detail::AtomicFile mFile;
    std::FILE* mStream = nullptr;
    std::string mBuf;
};

std::string oneLine(const std::string& s)
{
    std::string out = s;
    for (char& c : out) {
        if (c == '\n' || c == '\r') c = ' ';
    }
    return out;
}

/// The text lines of OBJ and OFF: one "<vertexPrefix>x y z" line per vertex, then one
/// "<facePrefix>i j k" line per triangle with indices from `base` (OBJ 1, OFF 0).
void putLines(MeshFileWriter& w, const TriangleMesh& mesh, const char* vertexPrefix, const char* facePrefix,
              uint64_t base)
{
    for (const Vec3d& p : mesh.points) {
        w.put(vertexPrefix);
        w.putNumber(p[0]);
        w.put(' ');
        w.putNumber(p[1]);
        w.put(' ');
        w.putNumber(p[2]);
        w.put('\n');
    }
    for (const Vec3I& t : mesh.triangles) {
        w.put(facePrefix);
        w.putNumber(uint64_t(t[0]) + base);
        w.put(' ');
        w.putNumber(uint64_t(t[1]) + base);
        w.put(' ');
        w.putNumber(uint64_t(t[2]) + base);
        w.put('\n');
    }
}

void writeObj(const TriangleMesh& mesh, MeshFileWriter& w)
{
    w.put("# written by levelforge\n");
    if (!mesh.source.empty()) {
        w.put("# source: ");
        w.put(oneLine(mesh.source));
        w.put('\n');
    }
    putLines(w, mesh, "v ", "f ", 1);
}

void writeOff(const TriangleMesh& mesh, MeshFileWriter& w)
{
    w.put("OFF\n");
    w.putNumber(uint64_t(mesh.points.size()));
    w.put(' ');
    w.putNumber(uint64_t(mesh.triangles.size()));
    w.put(" 0\n");
    putLines(w, mesh, "", "3 ", 0);
}

void writePly(const TriangleMesh& mesh, MeshFileWriter& w)
{
    const bool smallIndices = mesh.points.size() <= size_t(std::numeric_limits<int32_t>::max());
    // Coordinates that are all exactly single-precision numbers (a mesh extracted from a float
    // grid, a mesh read from a float file) are written as floats: the same values, half the bytes.
    // (The float goes through a volatile: GCC 12.2's SLP vectorizer at -O2 drops a
    // double -> float -> double round trip in a loop, which would make every mesh look float.)
    bool asFloat = true;
    for (const Vec3d& p : mesh.points) {
        for (int k = 0; k < 3; ++k) {
            const double v = p[k];
            if (!(std::abs(v) <= double(std::numeric_limits<float>::max()))) {
                asFloat = false;
                break;
            }
            volatile float rounded = static_cast<float>(v);
            if (static_cast<double>(rounded) != v) {
                asFloat = false;
                break;
            }
        }
        if (!asFloat) break;
    }
    const char* type = asFloat ? "float" : "double";
    std::string header = "ply\nformat binary_little_endian 1.0\ncomment written by levelforge\n";
    if (!mesh.source.empty()) header += "comment source: " + oneLine(mesh.source) + "\n";
    header += "element vertex " + std::to_string(mesh.points.size()) + "\n";
    header += std::string("property ") + type + " x\nproperty " + type + " y\nproperty " + type + " z\n";
    header += "element face " + std::to_string(mesh.triangles.size()) + "\n";
    header += smallIndices ? "property list uchar int vertex_indices\n"
                           : "property list uchar uint vertex_indices\n";
    header += "end_header\n";
    w.put(header);
    // Records are packed into a block and handed over in one put() per block.
    constexpr size_t kBlock = 1 << 16;
    std::vector<unsigned char> block;
    block.reserve(kBlock * 24);
    auto append = [&block](auto v) {
        unsigned char b[sizeof(v)];
        std::memcpy(b, &v, sizeof(v));
        if (kHostBigEndian) std::reverse(b, b + sizeof(v));
        block.insert(block.end(), b, b + sizeof(v));
    };
    for (size_t i = 0; i < mesh.points.size(); ++i) {
        const Vec3d& p = mesh.points[i];
        for (int k = 0; k < 3; ++k) {
            if (asFloat) append(float(p[k]));
            else append(p[k]);
        }
        if (block.size() >= kBlock * 12) {
            w.put(block.data(), block.size());
            block.clear();
        }
    }
    for (const Vec3I& t : mesh.triangles) {
        append(uint8_t(3));
        append(uint32_t(t[0]));
        append(uint32_t(t[1]));
        append(uint32_t(t[2]));
        if (block.size() >= kBlock * 12) {
            w.put(block.data(), block.size());
            block.clear();
        }
    }
    w.put(block.data(), block.size());
}

void writeStl(const TriangleMesh& mesh, const std::string& path, MeshFileWriter& w)
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

void writeMesh(const TriangleMesh& mesh, const std::string& path)
{
    using namespace meshio_internal;
    const std::string ext = lowerExtension(path);
    if (ext != ".obj" && ext != ".off" && ext != ".ply" && ext != ".stl") {
        throw IoError("cannot write mesh file '" + path + "': unsupported format '" + ext +
            "' (supported: .obj .off .ply .stl)");
    }
    MeshFileWriter w(path);
    if (ext == ".obj") writeObj(mesh, w);
    else if (ext == ".off") writeOff(mesh, w);
    else if (ext == ".ply") writePly(mesh, w);
    else writeStl(mesh, path, w);
    w.commit();
}

} // namespace levelforge
