// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Reading and writing triangle meshes (OBJ, OFF, PLY, STL).
///
/// readMesh() reads OBJ, OFF, PLY (ASCII and binary) and STL (ASCII and binary) through
/// OpenMesh's own readers (OpenMesh::IO::IOManager), but with an importer that copies vertices and
/// faces straight into a TriangleMesh. OpenMesh's half-edge mesh is never built, so nothing is
/// lost to it: faces on non-manifold ("complex") edges, faces of a soup, faces whose winding
/// disagrees with their neighbours all arrive as they are in the file.
///
/// Guarantees of readMesh():
///  - every triangle indexes an existing vertex and every vertex coordinate is finite; otherwise
///    it throws InvalidMeshError naming the file, the element (0-based face / vertex number, and
///    the line for text files) and the offending value;
///  - quads are split along their 0-2 diagonal (0-1-2, 0-2-3), as OpenVDB's meshToVolume and
///    most tools split them, unless that diagonal leaves the quad seen in its best-fit (Newell)
///    plane (a non-convex quad: the split would fold the surface) or is already an edge of
///    another face while 1-3 is not (the split would make that edge non-manifold); then along
///    1-3 (1-2-3, 1-3-0). A non-planar quad split the other way would move the surface by up to the quad's
///    out-of-plane height, so the rule matters for matching other tools. Larger polygons (and
///    bow-tie quads) are triangulated by ear clipping in the best-fit plane, so concave polygons
///    come out right and every triangle keeps the polygon's winding; a polygon that ear
///    clipping cannot handle (self-intersecting, collinear) falls back to a fan;
///  - faces with fewer than three distinct corners carry no area and are dropped (OpenMesh's OBJ
///    and STL readers drop them before we see them); MeshReadInfo::droppedFaces counts them.
///    (OpenMesh's OBJ reader also removes every repeated corner of a polygon, keeping the first
///    occurrence, before we see it.) Zero-area faces with three distinct corners are kept;
///    validateMesh() reports them;
///  - TriangleMesh::faceIndex says which face each triangle came from: the 0-based index of the
///    face among the faces of the file, in file order (dropped faces keep their number, so the
///    indices are those of the file; faces OpenMesh's OBJ and STL readers drop before we see them
///    are the exception). It is left empty when triangle i is face i (a file of triangles only,
///    none dropped);
///  - the file order of vertices (OBJ, OFF, PLY) and of faces is kept; STL has no shared vertices,
///    OpenMesh's STL reader merges corners with bit-identical coordinates (0 and -0 count as equal);
///  - OpenMesh hands coordinates over in single precision. For OBJ, OFF and PLY the positions are
///    recovered in double precision from the file text (or the binary PLY doubles) by the same
///    pre-scan that checks the file (MeshReadInfo::doublePrecision says whether that happened);
///    STL is single precision by definition of the format;
///  - an empty file, or a file with no face, throws InvalidMeshError ("no triangles").
/// Errors: the file is missing, unreadable, or has an unsupported extension -> IoError; the file
/// is readable but its content is wrong -> InvalidMeshError. Every message names the file.
///
/// The pre-scan: OpenMesh's text readers are silent about several faults. An OBJ vertex that does
/// not parse ("v nan 0 0", "v 1e39 0 0") is skipped, shifting every later index; an OFF/PLY
/// number that does not parse derails the stream into garbage faces; a binary STL facet with a NaN
/// corner is merged away; out-of-range OBJ/OFF indices are passed on as invalid handles. So before
/// OpenMesh reads the file, a light scan (buffered, no allocation per line) checks coordinates and
/// face indices and reports the first fault with its line number. It follows OpenMesh's own
/// reading rules, so OFF files with comments or with the counts on the "OFF" line (which
/// OpenMesh reads as empty) are reported as errors rather than read as nothing.
///
/// writeMesh() writes OBJ, OFF (ASCII, shortest round-trip decimal form of each double), PLY
/// (binary little endian; float coordinates when every coordinate is exactly a float, which
/// loses nothing, else double) or STL (binary, single precision), chosen by the
/// extension. It writes what it is given (validate first if you need guarantees; only STL, which
/// stores coordinates per facet, checks indices). The file appears atomically: the data goes to a
/// temporary file in the same folder, which is flushed to disk and renamed over the target when
/// complete; on failure nothing is left behind.
///
/// Thread safety: OpenMesh's reader modules are singletons with state; readMesh() serialises the
/// OpenMesh part of the work with a mutex, so it may be called from several threads.
#pragma once

#include <levelforge/core/TriangleMesh.h>

#include <cstdint>
#include <string>
#include <vector>

namespace levelforge {

/// What readMesh() found in a file beyond the mesh itself.
struct MeshReadInfo
{
    std::string format;            ///< "obj", "off", "ply" or "stl"
    bool binary = false;           ///< binary PLY / STL / OFF
    uint64_t fileVertices = 0;     ///< vertices handed over by OpenMesh (STL: after merging)
    uint64_t fileFaces = 0;        ///< faces in the file (before triangulation)
    uint64_t polygons = 0;         ///< faces with more than three corners, triangulated
    uint64_t fanFallbacks = 0;     ///< polygons ear clipping could not handle, fan-triangulated
    uint64_t droppedFaces = 0;     ///< faces with fewer than three distinct corners (no area)
    bool doublePrecision = false;  ///< positions recovered in double precision from the file
};

/// What readMesh() keeps beyond positions and faces. Nothing by default: reading then costs
/// exactly what it costs without options.
///
/// Attributes (TriangleMesh::attributes, one value per triangle corner, see MeshAttribute) are
/// named as Houdini names them:
///  - "Cd", the colour (3 floats): OBJ `v x y z r g b` (as written, usually 0..1); PLY vertex
///    properties red, green, blue (integer types divided by their maximum, 255 for uchar; float
///    types as written);
///  - "N", the normal (3 floats, as written, not renormalised): OBJ `vn` lines referenced by
///    face corners `v//vn` or `v/vt/vn`; PLY vertex properties nx, ny, nz;
///  - "uv", the texture coordinate (3 floats, w = 0 unless the file gives it): OBJ `vt` lines
///    referenced by face corners `v/vt` or `v/vt/vn`; PLY vertex properties u, v (or s, t, or
///    texture_u, texture_v);
///  - PLY only: any other scalar vertex property (not x, y, z), by its own name (1 float; e.g.
///    "quality", "alpha").
/// OBJ `vt` / `vn` indices belong to face corners, so a vertex can have a different UV or
/// normal in each face that uses it (a seam); they are kept per corner and stay right across
/// seams. Per-vertex values (colours, PLY properties) are copied to every corner of the vertex.
/// Polygons keep the value of each of their corners in the triangles they are split into;
/// dropped faces take theirs with them. Only OBJ and PLY files carry attributes (OFF and STL
/// have none here).
struct MeshReadOptions
{
    /// The attributes to keep, by name. A name the file does not have throws
    /// InvalidArgumentError "<file>: no vertex attribute 'X' (it has: Cd, N)"; an OBJ face corner
    /// without the `vt` / `vn` index the attribute needs, or an OBJ vertex without a colour,
    /// throws InvalidMeshError naming the face or vertex.
    std::vector<std::string> attributes;
};

/// @brief The attribute names a mesh file offers (see MeshReadOptions), in the order Cd, N, uv,
///        then PLY properties in file order; empty for OFF and STL. Reads the header (PLY) or
///        scans the file (OBJ); does not check the rest of the file.
/// @throws IoError when the file cannot be opened or has an unsupported extension.
std::vector<std::string> meshFileAttributes(const std::string& path);

/// @brief Reads a triangle mesh (.obj, .off, .ply, .stl, also .stla/.stlb; case-insensitive),
///        with the guarantees of the file comment.
/// @param[in] path  the mesh file; the extension chooses the format
/// @return the mesh, with mesh.source set to @p path.
/// @throws IoError when the file is missing, unreadable or has an unsupported extension.
/// @throws InvalidMeshError when its content is wrong (the message names the file, the element
///         and the value).
/// @throws ResourceLimitError when the mesh would not fit in memory (an allocation failed while
///         reading; the message names the file).
TriangleMesh readMesh(const std::string& path);

/// @brief As readMesh(path), and says what the file held.
/// @param[in]  path  the mesh file
/// @param[out] info  format, counts of vertices, faces, triangulated and dropped faces, and
///                   whether positions are double precision
/// @return the mesh, with mesh.source set to @p path.
/// @throws IoError, InvalidMeshError, ResourceLimitError as readMesh(path).
TriangleMesh readMesh(const std::string& path, MeshReadInfo& info);

/// @brief As readMesh(path, info), and keeps what @p options asks for (per-corner attributes).
/// @param[in]  path     the mesh file
/// @param[in]  options  the attributes to keep (see MeshReadOptions)
/// @param[out] info     as readMesh(path, info)
/// @return the mesh, with mesh.attributes in the order of options.attributes.
/// @throws IoError, InvalidMeshError, ResourceLimitError as readMesh(path); InvalidArgumentError
///         for an attribute the file does not have (the message lists those it has).
TriangleMesh readMesh(const std::string& path, const MeshReadOptions& options, MeshReadInfo& info);

/// @brief Writes @p mesh to @p path atomically; the format follows the extension (.obj, .off,
///        .ply, .stl; case-insensitive), see the file comment.
/// @param[in] mesh  the mesh, written as it is (validate first if you need guarantees)
/// @param[in] path  the file to create or replace
/// @throws IoError on an unsupported extension, or when the file cannot be created or written
///         (nothing is left behind then).
/// @throws InvalidMeshError, for STL only, when a triangle index is out of range.
void writeMesh(const TriangleMesh& mesh, const std::string& path);

/// @brief Whether readMesh() accepts the extension of @p path (the file is not opened).
/// @param[in] path  a file path
/// @return true for .obj, .off, .ply, .stl, .stla and .stlb, in any letter case.
bool isReadableMeshFile(const std::string& path);

/// @brief The extensions readMesh() accepts.
/// @return lower case with the dot: ".obj", ".off", ".ply", ".stl", ".stla", ".stlb".
std::vector<std::string> readableMeshExtensions();

} // namespace levelforge
