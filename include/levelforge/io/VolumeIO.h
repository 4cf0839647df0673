// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Reading scalar volumes (NIfTI-1, INRIMAGE-4, VolPack .den, raw, .vdb) into a
///        ScalarVolume, and writing NIfTI-1 / INRIMAGE-4 float volumes.
///
/// readVolume() picks the reader from the extension (case-insensitive, an extra ".gz" allowed):
///   .nii .nii.gz   NIfTI-1 single file ("n+1"), either byte order
///   .inr .inr.gz   INRIMAGE-4
///   .den           VolPack / UNC density map (62-byte header, uint8 voxels)
///   .raw           headerless (or fixed-header) samples described by a RawVolumeLayout
///   .vdb           a float / double / int32 / int64 scalar grid of an OpenVDB file
/// and, for any other extension, from the content (NIfTI-1, INRIMAGE-4 and VDB magic numbers),
/// or as raw data when ReadVolumeOptions::raw is given. gzip compression is recognised by its
/// magic bytes, whatever the extension, and decompressed with zlib as the file is read.
///
/// Conventions (those of DenseVolume.h): sample (i,j,k) is a voxel centre at world position
/// origin + (i*sx, j*sy, k*sz); data is x fastest. Every source value type is converted to
/// float (integers above 2^24 lose precision); NIfTI scl_slope/scl_inter are applied.
/// DenseVolume has no rotation: for a NIfTI qform/sform that is diagonal up to signs, axes with a
/// negative step are reversed in memory so that world positions stay exact (VolumeInfo::
/// reversedAxes); any rotation or shear is dropped and reported in VolumeInfo::warnings.
/// docs/volumes.md says what is read from each header.
///
/// Errors (every message names the file, and the field or voxel at fault):
///  - IoError: missing / unreadable file, unknown format, corrupt or truncated gzip stream,
///    cannot write;
///  - InvalidVolumeError: the content is wrong: bad magic or header field, unsupported value
///    type, dims <= 0, truncated voxel data, trailing bytes (raw and .den), NaN or Inf values;
///  - ResourceLimitError: the volume has more than ReadVolumeOptions::maxVoxels samples (checked
///    from the header, before any allocation);
///  - InvalidArgumentError: bad options (a .raw file without a RawVolumeLayout, dims <= 0 in it)
///    or, for the writers, a volume that cannot be written.
/// Reading converts whole buffers (no per-voxel virtual calls); ~10^7 voxels take well under a
/// second. The functions are thread-safe (no shared state beyond openvdb::initialize()).
#pragma once

#include <openvdb/Types.h> // openvdb::Coord, openvdb::Vec3d (before DenseVolume.h, which needs them)

#include <levelforge/core/DenseVolume.h>
#include <levelforge/core/Exceptions.h>

#include <openvdb/openvdb.h>

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace levelforge {

/// A volume file is readable but its content is unusable (bad header field, unsupported value
/// type, truncated data, NaN/Inf sample). The message names the file and the field or voxel.
class InvalidVolumeError : public Error
{
public:
    explicit InvalidVolumeError(const std::string& msg) : Error(msg) {}
};

/// Type of the samples stored in a file (all are converted to float on reading).
enum class VolumeValueType { UInt8, Int8, UInt16, Int16, UInt32, Int32, UInt64, Int64, Float32, Float64 };

/// @brief The name of a sample type, as error messages print it.
/// @param[in] type  a sample type
/// @return "uint8", "int8", "uint16", "int16", "uint32", "int32", "uint64", "int64", "float32"
///         or "float64".
std::string volumeValueTypeName(VolumeValueType type);

/// @brief The size of one sample of @p type.
/// @param[in] type  a sample type
/// @return bytes per sample: 1, 2, 4 or 8.
size_t volumeValueTypeBytes(VolumeValueType type);

/// How a headerless (raw) file is laid out: headerBytes bytes to skip, then dims.x*dims.y*dims.z
/// samples of @a type, x fastest. The file size must be exactly headerBytes + samples * size.
struct RawVolumeLayout
{
    openvdb::Coord dims{0, 0, 0};          ///< samples along x, y, z (> 0)
    VolumeValueType type = VolumeValueType::UInt8;
    bool bigEndian = false;                ///< byte order of multi-byte samples
    openvdb::Vec3d spacing{1.0, 1.0, 1.0}; ///< world units between samples (> 0)
    openvdb::Vec3d origin{0.0, 0.0, 0.0};  ///< world position of sample (0,0,0)
    uint64_t headerBytes = 0;              ///< bytes before the first sample
};

/// What a reader found in the file beyond the samples.
struct VolumeInfo
{
    std::string format;                    ///< "nifti", "inr", "den", "raw" or "vdb"
    VolumeValueType sourceType = VolumeValueType::Float32; ///< sample type in the file
    bool compressed = false;               ///< the file was gzip-compressed
    bool bigEndian = false;                ///< byte order of the file's header and samples
    std::string gridName;                  ///< .vdb: name of the grid read
    double minValue = 0.0;                 ///< smallest sample after conversion (and scaling)
    double maxValue = 0.0;                 ///< largest sample after conversion (and scaling)
    std::array<bool, 3> reversedAxes{{false, false, false}}; ///< NIfTI: axes stored in decreasing
                                                              ///< world order, reversed in memory
    std::vector<std::string> warnings;     ///< what could not be represented (rotation, ...)
};

/// Options of readVolume().
struct ReadVolumeOptions
{
    /// Layout of raw data: required for .raw files; for a file whose extension is not one of
    /// .nii/.inr/.den/.vdb (with optional .gz) it makes readVolume() read the file as raw.
    std::optional<RawVolumeLayout> raw;
    /// .vdb: the grid to read; empty: the first float, double, int32 or int64 grid in the
    /// order OpenVDB lists a file's grids (by name).
    std::string vdbGridName;
    /// .vdb: voxels added on every side of the active bounding box (the dense box then also holds
    /// the band a distance transform will fill around data that ends at the box), >= 0.
    int vdbPadding = 0;
    /// Largest number of samples accepted; more throws ResourceLimitError (default 2^31,
    /// i.e. 8 GiB of floats).
    uint64_t maxVoxels = uint64_t(1) << 31;
};

/// @brief Reads a scalar volume, choosing the format from the extension or the content (see the
///        file comment).
/// @param[in]  path     the volume file
/// @param[in]  options  raw layout, .vdb grid and padding, sample limit
/// @param[out] info     when not null: what the file held beyond the samples
/// @return the volume, samples converted to float.
/// @throws IoError, InvalidVolumeError, ResourceLimitError or InvalidArgumentError (see the file
///         comment).
ScalarVolume readVolume(const std::string& path, const ReadVolumeOptions& options = {},
                        VolumeInfo* info = nullptr);

/// @brief Reads a NIfTI-1 single-file image (.nii, .nii.gz; either byte order), whatever the
///        extension. dim[0] must be <= 3, or larger with every dim[4..] == 1. Datatypes: 2 uint8,
///        4 int16, 8 int32, 16 float32, 64 float64, 256 int8, 512 uint16, 768 uint32, 1024 int64,
///        1280 uint64.
/// @param[in]  path     the image file
/// @param[in]  options  ReadVolumeOptions::maxVoxels applies
/// @param[out] info     when not null: byte order, sample type, reversed axes, warnings, ...
/// @return the volume (scl_slope / scl_inter applied).
/// @throws IoError, InvalidVolumeError or ResourceLimitError (see the file comment).
ScalarVolume readNifti(const std::string& path, const ReadVolumeOptions& options = {},
                       VolumeInfo* info = nullptr);

/// @brief Reads an INRIMAGE-4 image (.inr, .inr.gz) with VDIM=1, whatever the extension.
/// @param[in]  path     the image file
/// @param[in]  options  ReadVolumeOptions::maxVoxels applies
/// @param[out] info     when not null: byte order, sample type, warnings, ...
/// @return the volume.
/// @throws IoError, InvalidVolumeError or ResourceLimitError (see the file comment).
ScalarVolume readInr(const std::string& path, const ReadVolumeOptions& options = {},
                     VolumeInfo* info = nullptr);

/// @brief Reads a VolPack / UNC .den density map (version 1, uint8 samples; either byte order).
///        The format stores no spacing: spacing is 1 and origin 0.
/// @param[in]  path     the density map
/// @param[in]  options  ReadVolumeOptions::maxVoxels applies
/// @param[out] info     when not null: byte order, compression, value range
/// @return the volume.
/// @throws IoError, InvalidVolumeError (also for bytes after the samples) or ResourceLimitError.
ScalarVolume readDen(const std::string& path, const ReadVolumeOptions& options = {},
                     VolumeInfo* info = nullptr);

/// @brief Reads raw samples laid out as @p layout (the file may be gzip-compressed; the size
///        check applies to the decompressed bytes).
/// @param[in]  path       the data file
/// @param[in]  layout     header bytes, dims, sample type, byte order, spacing and origin
/// @param[in]  maxVoxels  largest number of samples accepted
/// @param[out] info       when not null: what was read
/// @return the volume.
/// @throws InvalidArgumentError for a bad @p layout; IoError, InvalidVolumeError (the file size
///         is not exactly the layout's) or ResourceLimitError.
ScalarVolume readRaw(const std::string& path, const RawVolumeLayout& layout,
                     uint64_t maxVoxels = uint64_t(1) << 31, VolumeInfo* info = nullptr);

/// @brief Reads a scalar grid (float, double, int32 or int64) of a .vdb file as a dense volume
///        over its active-voxel bounding box grown by ReadVolumeOptions::vdbPadding.
///
/// Voxels inside the box that are inactive keep the value the tree holds there (the
/// background, or -background inside a level set). The transform must be linear, axis-aligned
/// with positive scale (a translation is fine): spacing = voxel size, origin = world position
/// of the bounding box minimum.
/// @param[in]  path     the .vdb file
/// @param[in]  options  vdbGridName, vdbPadding and maxVoxels apply
/// @param[out] info     when not null: the grid read, its value type, the value range
/// @return the dense volume.
/// @throws IoError (missing or unreadable file, not a VDB file), InvalidVolumeError (no such
///         grid, not a scalar grid, no active voxels, rotated or mirrored transform, NaN or Inf
///         values) or ResourceLimitError.
ScalarVolume readVdbVolume(const std::string& path, const ReadVolumeOptions& options = {},
                           VolumeInfo* info = nullptr);

/// @brief The same grid as readVdbVolume() chooses (same checks and errors), kept sparse: a
///        FloatGrid sharing nothing with the file (double and integer grids are converted to
///        float), with its transform and name, for sparseVolumeToLevelSet()
///        (<levelforge/volume/SparseVolumeToLevelSet.h>). No dense box is made.
/// @param[in]  path     the .vdb file
/// @param[in]  options  vdbGridName applies
/// @param[out] info     when not null: the grid read and its value type
/// @return the grid, as floats.
/// @throws InvalidVolumeError when @p path does not end with .vdb; otherwise as readVdbVolume().
openvdb::FloatGrid::Ptr readVdbScalarGrid(const std::string& path, const ReadVolumeOptions& options = {},
                                          VolumeInfo* info = nullptr);

/// @brief Writes @p volume as a float32 NIfTI-1 single file (.nii, or gzip-compressed when
///        @p path ends with .gz).
///
/// Spacing goes to pixdim, the origin to qoffset and to the sform's last column
/// (qform_code = sform_code = 1, identity rotation, units unknown). Atomic: the data goes to a
/// temporary file in the same folder, flushed to disk and renamed over @p path when complete.
/// @param[in] path    the file to create or replace
/// @param[in] volume  the volume
/// @throws InvalidArgumentError (empty volume, dims above 32767, spacing <= 0, non-finite
///         sample) or IoError (missing directory, cannot write; nothing is left behind).
void writeNifti(const std::string& path, const ScalarVolume& volume);

/// @brief Writes @p volume as a float32 INRIMAGE-4 image (.inr, or gzip-compressed when
///        @p path ends with .gz): XDIM/YDIM/ZDIM, VDIM=1, TYPE=float, PIXSIZE=32 bits,
///        CPU=decm, VX/VY/VZ and the origin as XO/YO/ZO. Atomic, like writeNifti().
/// @param[in] path    the file to create or replace
/// @param[in] volume  the volume
/// @throws InvalidArgumentError (empty volume, spacing <= 0, non-finite sample) or IoError.
void writeInr(const std::string& path, const ScalarVolume& volume);

/// @brief Whether readVolume() recognises the extension of @p path without a RawVolumeLayout
///        (the file is not opened).
/// @param[in] path  a file path
/// @return true for .nii, .inr and .den (each with an optional .gz) and .vdb, in any letter
///         case.
bool isReadableVolumeFile(const std::string& path);

/// @brief The extensions readVolume() recognises without a RawVolumeLayout.
/// @return lower case with the dot: ".nii", ".nii.gz", ".inr", ".inr.gz", ".den", ".vdb".
std::vector<std::string> readableVolumeExtensions();

} // namespace levelforge
