// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief A pre-scan of a .vdb file's header, metadata and grid descriptors, run before the
///        file is handed to OpenVDB, so that a corrupt length field is refused with a short
///        message instead of becoming a huge allocation (or a gigabyte-long error text) inside
///        OpenVDB. Private to src/io (readGrids()) and its white-box tests.
///
/// What is checked (the layout of openvdb/io/Archive.cc, File.cc, GridDescriptor.cc and
/// MetaMap.cc, file format versions 221 to 224):
///  - the header: magic number 0x56444220 (int64), file format version (uint32, >= 221, which
///    is what OpenVDB still reads), library major / minor version (uint32 each), the
///    "has grid offsets" flag (char), for version 221 the compression flag (char), the
///    36-character UUID;
///  - the file-level metadata: entry count (uint32; each entry needs at least 12 bytes), and
///    per entry the name and type name (uint32 length + characters), the value size (uint32)
///    and value: every length must fit in the bytes left; fixed-size types (float, int32,
///    vec3d, mat4d, ...) must declare their own size; the "__delayedload" entry's inner counts
///    and Blosc headers must agree with its size;
///  - when the file has grid offsets (every file OpenVDB writes to disk): the grid count
///    (int32, >= 0, at least 36 bytes each) and each grid descriptor: unique name, grid type
///    and instance-parent name (strings), grid / block / end positions (int64), which must
///    satisfy descriptor end <= grid <= block <= end <= file size; then, at the grid's
///    position, its compression flags (uint32, version >= 222), its metadata (as above, within
///    [grid, block)) and the name of its transform's map type (a string).
/// Not checked: the tree topology and the voxel buffers (OpenVDB reads them; readGrids() turns
/// std::bad_alloc and std::length_error thrown there into IoError).
#pragma once

#include <cstdint>
#include <string>

namespace levelforge::vdbio_internal {

/// What checkVdbHeader() found (for tests and messages).
struct VdbHeaderSummary
{
    uint32_t fileVersion = 0;     ///< the file format version (221..224 today)
    uint32_t libraryMajor = 0;    ///< the OpenVDB version that wrote the file
    uint32_t libraryMinor = 0;
    bool hasGridOffsets = false;  ///< grid descriptors (and the grids' headers) were checked
    int32_t gridCount = 0;        ///< grids described (0 when !hasGridOffsets)
    uint64_t fileBytes = 0;       ///< size of the file
    /// End of the first grid's checked header (just after its transform's type name; its map
    /// data and tree follow): the bytes before it, except the UUID and the library version,
    /// are the ones this check reads. 0 when there is no grid or no grid offsets.
    uint64_t firstTreeOffset = 0;
};

/// @brief Pre-scans the .vdb file @p path as described in the file comment.
/// @return what the header holds.
/// @throws IoError "cannot read '<path>': not a VDB file (...)" or "cannot read '<path>':
///         corrupt VDB file: <field> claims N bytes but only M bytes are left in <region>",
///         with every length printed as a number, never as the data it announces.
VdbHeaderSummary checkVdbHeader(const std::string& path);

} // namespace levelforge::vdbio_internal
