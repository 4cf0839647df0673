// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief A bounded pre-scan of a whole .vdb file, run before the file is handed to OpenVDB,
///        so that a corrupt file is refused with a short typed message instead of becoming a
///        huge allocation, a heap overflow, a leak, undefined behaviour or a long loop inside
///        OpenVDB 10's reader (which trusts every count and size it reads). Private to src/io
///        (readGrids()) and its white-box tests.
///
/// What is checked (the layout of openvdb/io/Archive.cc, File.cc, GridDescriptor.cc,
/// MetaMap.cc, math/Maps.h, tree/RootNode.h, InternalNode.h, LeafNode*.h and io/Compression.h,
/// file format versions 222 to 224):
///  - the header: magic number 0x56444220 (int64), file format version (uint32; 221, the oldest
///    OpenVDB reads, is refused as unsupported: it has another node layout; later versions than
///    224 are scanned as 224, which is how OpenVDB 10 reads them), library major /
///    minor version (uint32 each), the "has grid offsets" flag (char), the 36-character UUID;
///  - the file-level metadata: entry count (uint32; each entry needs at least 12 bytes), and
///    per entry the name and type name (uint32 length + characters), the value size (uint32)
///    and value: every length must fit in the bytes left; fixed-size types (float, int32,
///    vec3d, mat4d, ...) must declare their own size; a bool must be 0 or 1; the
///    "__delayedload" entry's inner counts and Blosc headers must agree with its size;
///  - the grid count (int32, >= 0, at least 36 bytes each) and each grid descriptor: name,
///    grid type (a "_HalfFloat" suffix stripped) and instance-parent name (strings), grid /
///    block / end positions (int64). With grid offsets (files written by io::File) they must
///    satisfy descriptor end <= grid <= block <= end <= file size (an instance has no block
///    position); without (files written by io::Stream) each grid follows its descriptor;
///  - the grid type: Tree_{float,double,int32,int64,vec3s,vec3d,vec3i,bool,mask}_5_4_3 are
///    scanned; a type OpenVDB has not registered is left to OpenVDB (which refuses it); any other
///    registered type (point grids) is refused, since OpenVDB would read its tree unchecked;
///  - per grid: the compression flags (uint32, only zip 1 / active mask 2 / Blosc 4), the
///    metadata (as above; "is_saved_as_half_float", which decides whether values are stored as
///    half floats, must be a bool), the transform (the map type must be one OpenVDB knows, with
///    its fixed-size data; a frustum's second map must be a linear one);
///  - per tree (unless the grid is an instance): the buffer count (1), the background (bool
///    trees: 0 or 1), the root's tile and child counts (which must fit in the bytes left), each
///    tile's key, value and active byte (0 or 1), each child's key: keys are multiples of 4096,
///    ascending, no child at a tile's key; each internal node's child and value masks (no entry
///    both a child and an active tile), then its values as readCompressedValues() reads them:
///    the compression byte (0..6), up to two inactive values, a selection mask, then a chunk of
///    the active (or all) values, in half floats where the grid says so; a zip / Blosc chunk's
///    int64 size must be -(the values' bytes) (stored) or positive and at most the values' bytes
///    (zip) or the values' bytes + 16 (Blosc), and fit in the bytes left; a Blosc header must
///    agree with both sizes. Internal nodes' chunks are decompressed here with OpenVDB's own
///    routines (an exception inside OpenVDB's readTopology leaks the node being read) and bool
///    values must be 0 or 1. Then the leaves' 64-byte masks; and side by side, at the block
///    position, each leaf's buffer in OpenVDB's order: the mask again (must match), then the
///    values (same chunk rules, not decompressed) or, for bool and mask leaves, the origin
///    (must be the leaf's) and the bits. The topology must end exactly at the block position
///    and the buffers at the end position.
/// Every loop runs over bytes it has read, so the scan's time and memory are bounded by the
/// file's size (the tree is not built: the scan keeps two node masks per level and, for the
/// root, its tile keys); it reads the file once, with two buffered cursors.
/// Not checked: the compressed bytes of the leaves' chunks (zlib and Blosc decode them within
/// the sizes checked here; a failure there is an exception OpenVDB throws after the tree is
/// built, which readGrids() turns into IoError) and the values themselves (NaN, infinities).
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
    bool hasGridOffsets = false;  ///< written by io::File (grid positions in the descriptors)
    int32_t gridCount = 0;        ///< grids described
    uint64_t fileBytes = 0;       ///< size of the file
    /// End of the first grid's header (just after its transform's type name; its map data and
    /// tree follow). 0 when there is no grid.
    uint64_t firstTreeOffset = 0;
    uint64_t rootTileCount = 0;     ///< root tiles in all trees
    uint64_t internalNodeCount = 0; ///< internal nodes in all trees
    uint64_t leafCount = 0;         ///< leaf nodes in all trees
};

/// @brief Pre-scans the .vdb file @p path as described in the file comment.
/// @return what the file holds.
/// @throws IoError "cannot read '<path>': not a VDB file (...)" or "cannot read '<path>':
///         corrupt VDB file: <what>", e.g. "<field> claims N bytes but only M bytes are left in
///         <region>" or "grid 0 ('density'): internal node at (0, 0, 0) declares a zip chunk of
///         N bytes, more than the M bytes left in the topology of grid 0 ('density') (bytes a to
///         b)", with every length printed as a number, never as the data it announces.
VdbHeaderSummary checkVdbHeader(const std::string& path);

/// For tests: how many float grids writeGridsAtomic() has written with their leaf buffers
/// compressed in parallel (VdbIO.cc's ParallelBufferFloatGrid) since the process started.
uint64_t parallelBufferGridsWritten();

} // namespace levelforge::vdbio_internal
