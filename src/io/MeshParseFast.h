// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Private to src/io/Mesh*.cc: the parallel fast path of readMesh() for plain OBJ, PLY
///        (ASCII and binary little endian) and STL (ASCII and binary) files.
///
/// The fast path maps the file, splits it into chunks of a fixed size at line boundaries,
/// parses the chunks in parallel (TBB) and concatenates their results in chunk order, so the
/// result does not depend on the number of threads. It produces exactly what the pre-scan plus
/// OpenMesh's readers hand to assemble() for the same file: the same exact double positions (the
/// same std::from_chars parse as the pre-scan), the same face stream (OBJ: repeated corners
/// removed keeping the first; STL: corners with identical coordinates merged in order of first
/// appearance, 0 and -0 equal, facets with two equal corners dropped).
///
/// It accepts only files whose reading it can reproduce exactly; on anything else (an error, an
/// unusual layout, a value whose float rounding OpenMesh might treat differently) it returns
/// false and readMesh() takes the sequential path, which reports the first error with its line.
#pragma once

#include "io/MeshIOInternal.h"

namespace levelforge {

namespace meshio_internal {

/// What the fast path read: the same arrays the OpenMesh importer would hold.
struct FastMesh
{
    std::vector<Vec3d> points;      ///< file order (STL: merged corners, order of first use)
    std::vector<int32_t> faceStream; ///< per face: corner count, then the 0-based corners
    uint64_t faceCount = 0;         ///< faces in faceStream
    uint64_t fileFaces = 0;         ///< faces in the file (faceCount + the faces without area)
    bool binary = false;
    bool exactPoints = false;       ///< points are the exact values of the file (not STL)
};

/// Reads @a path the fast way when its layout allows. @a format is "obj", "ply" or "stl", @a ext
/// the lower-case extension. Returns false (and leaves @a out in an unspecified state) when the
/// sequential path must read the file instead. Throws IoError only when the file cannot be
/// mapped or read.
bool fastReadMesh(const std::string& path, const std::string& ext, const std::string& format,
                  FastMesh& out);

} // namespace meshio_internal

} // namespace levelforge
