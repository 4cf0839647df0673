// levelforge — reading and writing .vdb files safely.
//
// Writes are atomic: grids go to a temporary file in the destination directory, which is
// flushed and then rename()d over the destination. A failure at any point removes the
// temporary file and throws IoError, so a reader (or a render-farm job watching the folder)
// never sees a half-written .vdb and a failed conversion never leaves an output file behind.
//
// Files are written with Blosc compression when this OpenVDB build has it
// (io::COMPRESS_BLOSC | io::COMPRESS_ACTIVE_MASK), else zip + active mask, as vdb_tool and
// Houdini do. Level sets are stamped with metadata that says how they were made
// (stampLevelSetMetadata), readable by `vdb_print -l`, pyopenvdb and Houdini.
#pragma once

#include <openvdb/Grid.h>
#include <openvdb/MetaMap.h>

#include <string>

namespace levelforge {

/// "levelforge <version>", the value of the "levelforge:generator" metadata.
std::string generatorString();

/// Writes `grids` (and file-level metadata) to `path` atomically (see the file comment).
/// Calls openvdb::initialize(). Throws IoError naming `path` and the cause (missing directory,
/// permission, disk full, ...); on failure neither `path` nor a temporary file is left behind,
/// and an existing file at `path` is left untouched.
void writeGridsAtomic(const std::string& path, const openvdb::GridPtrVec& grids,
                      const openvdb::MetaMap& fileMeta = {});

/// Throws the IoError writeGridsAtomic(path, ...) would throw for the location alone (missing
/// directory, not a directory, `path` is a directory, no write permission), so that a long
/// computation can fail fast, before any work is done. Creates nothing.
void checkOutputPath(const std::string& path);

/// Reads every grid of a .vdb file, fully loaded (no delayed loading, so the file may be
/// replaced afterwards). Throws IoError naming `path` when it is missing, not a regular file,
/// not a VDB file, or corrupt.
openvdb::GridPtrVecPtr readGrids(const std::string& path);

/// Marks `grid` as a level set and records how it was made:
///   class                            GRID_LEVEL_SET
///   "levelforge:exterior_band_voxels" float, half-width of the band outside, in voxels
///   "levelforge:interior_band_voxels" float, half-width of the band inside, in voxels
///   "levelforge:source"               string, the input (file path or generator description)
///   "levelforge:generator"            string, generatorString()
///   "levelforge:method"               string, the algorithm (e.g. "chang2008-exact")
void stampLevelSetMetadata(openvdb::GridBase& grid, double exteriorBandVoxels,
                           double interiorBandVoxels, const std::string& source,
                           const std::string& method);

} // namespace levelforge
