// levelforge — reading scalar volumes (NIfTI-1, INRIMAGE-4, VolPack .den, raw, .vdb) into a
// ScalarVolume, and writing NIfTI-1 / INRIMAGE-4 float volumes.
//
// readVolume() picks the reader from the extension (case-insensitive, an extra ".gz" allowed):
//   .nii .nii.gz   NIfTI-1 single file ("n+1"), either byte order
//   .inr .inr.gz   INRIMAGE-4
//   .den           VolPack / UNC density map (62-byte header, uint8 voxels)
//   .raw           headerless (or fixed-header) samples described by a RawVolumeLayout
//   .vdb           a float / double / int32 / int64 scalar grid of an OpenVDB file
// and, for any other extension, from the content (NIfTI-1, INRIMAGE-4 and VDB magic numbers),
// or as raw data when ReadVolumeOptions::raw is given. gzip compression is recognised by its
// magic bytes, whatever the extension, and decompressed with zlib as the file is read.
//
// Conventions (those of DenseVolume.h): sample (i,j,k) is a voxel centre at world position
// origin + (i*sx, j*sy, k*sz); data is x fastest. Every source value type is converted to
// float (integers above 2^24 lose precision); NIfTI scl_slope/scl_inter are applied.
// DenseVolume has no rotation: for a NIfTI qform/sform that is diagonal up to signs, axes with a
// negative step are reversed in memory so that world positions stay exact (VolumeInfo::
// reversedAxes); any rotation or shear is dropped and reported in VolumeInfo::warnings.
// docs/volumes.md says what is read from each header.
//
// Errors (every message names the file, and the field or voxel at fault):
//  - IoError: missing / unreadable file, unknown format, corrupt or truncated gzip stream,
//    cannot write;
//  - InvalidVolumeError: the content is wrong: bad magic or header field, unsupported value
//    type, dims <= 0, truncated voxel data, trailing bytes (raw and .den), NaN or Inf values;
//  - ResourceLimitError: the volume has more than ReadVolumeOptions::maxVoxels samples (checked
//    from the header, before any allocation);
//  - InvalidArgumentError: bad options (a .raw file without a RawVolumeLayout, dims <= 0 in it)
//    or, for the writers, a volume that cannot be written.
// Reading converts whole buffers (no per-voxel virtual calls); ~10^7 voxels take well under a
// second. The functions are thread-safe (no shared state beyond openvdb::initialize()).
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

/// "uint8", "int8", "uint16", "int16", "uint32", "int32", "uint64", "int64", "float32", "float64".
std::string volumeValueTypeName(VolumeValueType type);

/// Bytes per sample of @a type (1, 2, 4 or 8).
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

/// Reads a scalar volume, choosing the format from the extension or the content (see above).
/// Fills @a info when given. Throws IoError, InvalidVolumeError, ResourceLimitError or
/// InvalidArgumentError (see the file comment).
ScalarVolume readVolume(const std::string& path, const ReadVolumeOptions& options = {},
                        VolumeInfo* info = nullptr);

/// Reads a NIfTI-1 single-file image (.nii, .nii.gz; either byte order). dim[0] must be <= 3,
/// or larger with every dim[4..] == 1. Datatypes: 2 uint8, 4 int16, 8 int32, 16 float32,
/// 64 float64, 256 int8, 512 uint16, 768 uint32, 1024 int64, 1280 uint64.
ScalarVolume readNifti(const std::string& path, const ReadVolumeOptions& options = {},
                       VolumeInfo* info = nullptr);

/// Reads an INRIMAGE-4 image (.inr, .inr.gz) with VDIM=1.
ScalarVolume readInr(const std::string& path, const ReadVolumeOptions& options = {},
                     VolumeInfo* info = nullptr);

/// Reads a VolPack / UNC .den density map (version 1, uint8 samples; either byte order).
/// The format stores no spacing: spacing is 1 and origin 0.
ScalarVolume readDen(const std::string& path, const ReadVolumeOptions& options = {},
                     VolumeInfo* info = nullptr);

/// Reads raw samples laid out as @a layout (the file may be gzip-compressed; the size check
/// applies to the decompressed bytes).
ScalarVolume readRaw(const std::string& path, const RawVolumeLayout& layout,
                     uint64_t maxVoxels = uint64_t(1) << 31, VolumeInfo* info = nullptr);

/// Reads a scalar grid (float, double, int32 or int64) of a .vdb file as a dense volume over
/// its active-voxel bounding box grown by ReadVolumeOptions::vdbPadding. Voxels inside the box that are inactive keep the value the
/// tree holds there (the background, or -background inside a level set). The transform must
/// be linear, axis-aligned with positive scale (a translation is fine): spacing = voxel size,
/// origin = world position of the bounding box minimum.
ScalarVolume readVdbVolume(const std::string& path, const ReadVolumeOptions& options = {},
                           VolumeInfo* info = nullptr);

/// The same grid as readVdbVolume() chooses (same checks and errors), kept sparse: a FloatGrid
/// sharing nothing with the file (double and integer grids are converted to float), with its
/// transform, for sparseVolumeToLevelSet() (SparseVolumeToLevelSet.h). No dense box is made.
/// A path that is not a .vdb file is refused with InvalidVolumeError.
openvdb::FloatGrid::Ptr readVdbScalarGrid(const std::string& path, const ReadVolumeOptions& options = {},
                                          VolumeInfo* info = nullptr);

/// Writes @a volume as a float32 NIfTI-1 single file (.nii, or gzip-compressed when @a path
/// ends with .gz). Spacing goes to pixdim, the origin to qoffset and to the sform's last
/// column (qform_code = sform_code = 1, identity rotation, units unknown). Atomic: the data goes
/// to a temporary file in the same folder, renamed over @a path when complete.
/// Throws InvalidArgumentError (empty volume, dims above 32767, spacing <= 0, non-finite
/// sample) or IoError.
void writeNifti(const std::string& path, const ScalarVolume& volume);

/// Writes @a volume as a float32 INRIMAGE-4 image (.inr, or gzip-compressed when @a path ends
/// with .gz): XDIM/YDIM/ZDIM, VDIM=1, TYPE=float, PIXSIZE=32 bits, CPU=decm, VX/VY/VZ and the
/// origin as XO/YO/ZO. Atomic, like writeNifti(). Throws InvalidArgumentError or IoError.
void writeInr(const std::string& path, const ScalarVolume& volume);

/// True when readVolume() recognises the extension of @a path without a RawVolumeLayout.
bool isReadableVolumeFile(const std::string& path);

/// Extensions readVolume() recognises, lower case with the dot: ".nii", ".nii.gz", ".inr", ...
std::vector<std::string> readableVolumeExtensions();

} // namespace levelforge
