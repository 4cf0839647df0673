// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Reading and writing .vdb files safely.
///
/// Writes are atomic: grids go to a temporary file in the destination directory, which is
/// flushed and then rename()d over the destination. A failure at any point removes the
/// temporary file and throws IoError, so a reader (or a render-farm job watching the folder)
/// never sees a half-written .vdb and a failed conversion never leaves an output file behind.
///
/// Files are written with Blosc compression when this OpenVDB build has it
/// (io::COMPRESS_BLOSC | io::COMPRESS_ACTIVE_MASK), else zip + active mask, as vdb_tool and
/// Houdini do. Level sets are stamped with metadata that says how they were made
/// (stampLevelSetMetadata), readable by `vdb_print -l`, pyopenvdb and Houdini.
#pragma once

#include <openvdb/Grid.h>
#include <openvdb/MetaMap.h>

#include <string>

namespace levelforge {

/// @brief The name and version of this library, the value of the meta::kGenerator
///        ("levelforge:generator") metadata.
/// @return "levelforge <version>", e.g. "levelforge 0.1.0".
std::string generatorString();

/// @brief Writes @p grids (and file-level metadata) to @p path atomically (see the file
///        comment). Calls openvdb::initialize().
/// @param[in] path      the .vdb file to create or replace
/// @param[in] grids     the grids to write, in this order
/// @param[in] fileMeta  file-level metadata
/// @throws IoError naming @p path and the cause (missing directory, permission, disk full,
///         the written file does not read back, ...); on failure neither @p path nor a
///         temporary file is left behind, and an existing file at @p path is left untouched.
void writeGridsAtomic(const std::string& path, const openvdb::GridPtrVec& grids,
                      const openvdb::MetaMap& fileMeta = {});

/// @brief Checks that writeGridsAtomic() can create @p path, so that a long computation can
///        fail fast, before any work is done. Creates nothing.
/// @param[in] path  the .vdb file a later writeGridsAtomic() will write
/// @throws IoError, the one writeGridsAtomic(path, ...) would throw for the location alone:
///         empty path, missing directory, not a directory, @p path is a directory, no write
///         permission.
void checkOutputPath(const std::string& path);

/// @brief Reads every grid of a .vdb file, fully loaded (no delayed loading, so the file may be
///        replaced afterwards). Calls openvdb::initialize().
/// @param[in] path  the .vdb file
/// @return the grids, in file order.
/// @throws IoError naming @p path when it is missing, not a regular file, unreadable, not a VDB
///         file, or corrupt.
openvdb::GridPtrVecPtr readGrids(const std::string& path);

/// @brief Marks @p grid as a level set and records how it was made, under the keys of
///        <levelforge/core/Metadata.h>:
///  - grid class GRID_LEVEL_SET;
///  - meta::kExteriorBandVoxels ("levelforge:exterior_band_voxels"), float: half-width of the
///    band outside, in voxels;
///  - meta::kInteriorBandVoxels ("levelforge:interior_band_voxels"), float: half-width of the
///    band inside, in voxels;
///  - meta::kSource ("levelforge:source"), string: the input (file path or generator
///    description);
///  - meta::kGenerator ("levelforge:generator"), string: generatorString();
///  - meta::kMethod ("levelforge:method"), string: the algorithm (e.g. "chang2008-exact").
/// @param[in,out] grid                the grid to mark
/// @param[in]     exteriorBandVoxels  half-width of the band outside, in voxels
/// @param[in]     interiorBandVoxels  half-width of the band inside, in voxels
/// @param[in]     source              the input (file path or generator description)
/// @param[in]     method              the algorithm that made the values
void stampLevelSetMetadata(openvdb::GridBase& grid, double exteriorBandVoxels,
                           double interiorBandVoxels, const std::string& source,
                           const std::string& method);

} // namespace levelforge
