// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief readMesh() and the list of readable formats: the parallel fast path for plain files
///        (MeshParseFast.h), otherwise pre-scan, OpenMesh's readers; then assembly (see MeshIO.h).
#include <levelforge/io/MeshIO.h>

#include "io/MeshImporter.h"
#include "io/MeshParseFast.h"

#include <OpenMesh/Core/IO/IOManager.hh>
#include <OpenMesh/Core/IO/reader/OBJReader.hh>
#include <OpenMesh/Core/IO/reader/OFFReader.hh>
#include <OpenMesh/Core/IO/reader/PLYReader.hh>
#include <OpenMesh/Core/IO/reader/STLReader.hh>
#include <OpenMesh/Core/System/omstream.hh>

#include <mutex>
#include <new>
#include <stdexcept>

namespace levelforge {

namespace meshio_internal {

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

namespace {

TriangleMesh readMeshUnguarded(const std::string& path, MeshReadInfo& info)
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
    if (info.format != "off") {
        // Plain OBJ / PLY / STL files: the parallel fast path, the same result as below.
        FastMesh fast;
        if (fastReadMesh(path, ext, info.format, fast)) {
            info.binary = fast.binary;
            pre.binary = fast.binary;
            pre.faces = fast.fileFaces;
            pre.haveFaces = true;
            pre.importerPointsExact = fast.exactPoints;
            Importer importer;
            importer.mPoints = std::move(fast.points);
            importer.mFaceStream = std::move(fast.faceStream);
            importer.mFaceCount = fast.faceCount;
            TriangleMesh mesh;
            mesh.source = path;
            assemble(path, importer, pre, mesh, info);
            return mesh;
        }
    }
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

} // namespace

namespace {

/// The attributes of @p want (duplicates once) from the file of @p mesh, spread over its corners.
void readAttributes(const std::string& path, const std::vector<std::string>& want, TriangleMesh& mesh)
{
    using namespace meshio_internal;
    std::vector<std::string> names;
    for (const std::string& n : want)
        if (std::find(names.begin(), names.end(), n) == names.end()) names.push_back(n);
    const std::string ext = lowerExtension(path);
    AttributeScan scan;
    if (ext == ".obj") scanObjAttributes(path, names, scan);
    else if (ext == ".ply") scanPlyAttributes(path, names, scan);
    else throwNoAttribute(path, names.front(), {});
    attachAttributes(path, scan, mesh);
}

} // namespace

std::vector<std::string> meshFileAttributes(const std::string& path)
{
    using namespace meshio_internal;
    const std::string ext = lowerExtension(path);
    if (!isReadableMeshFile(path)) {
        throw IoError("cannot read mesh file '" + path + "': unsupported format '" + ext + "'");
    }
    AttributeScan scan;
    if (ext == ".obj") scanObjAttributes(path, {}, scan);
    else if (ext == ".ply") scanPlyAttributes(path, {}, scan);
    return scan.available;
}

TriangleMesh readMesh(const std::string& path, const MeshReadOptions& options, MeshReadInfo& info)
{
    TriangleMesh mesh = readMesh(path, info);
    if (options.attributes.empty()) return mesh;
    try {
        readAttributes(path, options.attributes, mesh);
    } catch (const Error&) {
        throw;
    } catch (const std::bad_alloc&) {
        throw ResourceLimitError(path + ": out of memory while reading the mesh's attributes");
    }
    return mesh;
}

TriangleMesh readMesh(const std::string& path, MeshReadInfo& info)
{
    // The pre-scans check every count before anything is sized from it, but OpenMesh and the
    // assembly still allocate: an allocation that fails (a mesh too large for this machine, or a
    // reader fault the pre-scan misses) ends here as a typed error naming the file, never as a
    // bare std::bad_alloc / std::length_error.
    try {
        return readMeshUnguarded(path, info);
    } catch (const Error&) {
        throw;
    } catch (const std::bad_alloc&) {
        throw ResourceLimitError(path + ": out of memory while reading the mesh");
    } catch (const std::length_error& e) {
        throw ResourceLimitError(path + ": out of memory while reading the mesh (" + e.what() + ")");
    }
}

} // namespace levelforge
