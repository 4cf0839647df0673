// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief The volume format choice (extension, then content) and readVolume() (see VolumeIO.h).
#include "io/VolumeIOInternal.h"

namespace levelforge {

namespace volumeio_internal {

// ----------------------------------------------------------------------------- format choice

Format formatFromExtension(const std::string& path)
{
    std::string name = lowerFileName(path);
    const bool gz = endsWith(name, ".gz");
    if (gz) name.resize(name.size() - 3);
    if (endsWith(name, ".vdb")) return gz ? Format::Unknown : Format::Vdb;
    if (endsWith(name, ".nii")) return Format::Nifti;
    if (endsWith(name, ".inr")) return Format::Inr;
    if (endsWith(name, ".den")) return Format::Den;
    if (endsWith(name, ".raw")) return Format::Raw;
    return Format::Unknown;
}

Format formatFromContent(const std::string& path)
{
    InputFile in(path);
    unsigned char h[kNiftiHeaderBytes] = {};
    const uint64_t got = in.read(h, sizeof(h));
    if (got >= sizeof(kInrMagic) - 1 && std::memcmp(h, kInrMagic, sizeof(kInrMagic) - 1) == 0) return Format::Inr;
    if (got >= 8 && !in.compressed() && getField<int64_t>(h, 0, false) == int64_t(0x56444220)) return Format::Vdb;
    if (got == sizeof(h) && (getField<int32_t>(h, 0, false) == 348 || getField<int32_t>(h, 0, true) == 348) &&
        std::memcmp(h + 344, "n+1", 4) == 0) {
        return Format::Nifti;
    }
    return Format::Unknown;
}

} // namespace volumeio_internal

// ================================================================================== public API

std::string volumeValueTypeName(VolumeValueType type)
{
    switch (type) {
    case VolumeValueType::UInt8: return "uint8";
    case VolumeValueType::Int8: return "int8";
    case VolumeValueType::UInt16: return "uint16";
    case VolumeValueType::Int16: return "int16";
    case VolumeValueType::UInt32: return "uint32";
    case VolumeValueType::Int32: return "int32";
    case VolumeValueType::UInt64: return "uint64";
    case VolumeValueType::Int64: return "int64";
    case VolumeValueType::Float32: return "float32";
    case VolumeValueType::Float64: return "float64";
    }
    return "unknown";
}

size_t volumeValueTypeBytes(VolumeValueType type) { return volumeio_internal::typeBytes(type); }

ScalarVolume readVolume(const std::string& path, const ReadVolumeOptions& options, VolumeInfo* info)
{
    using namespace volumeio_internal;
    Format format = formatFromExtension(path);
    if (format == Format::Raw && !options.raw) {
        throw InvalidArgumentError(path + ": a .raw volume needs a RawVolumeLayout (dims, value type, "
                                          "byte order, spacing, header bytes)");
    }
    if (format == Format::Unknown) {
        format = options.raw ? Format::Raw : formatFromContent(path);
    }
    switch (format) {
    case Format::Nifti: return readNifti(path, options, info);
    case Format::Inr: return readInr(path, options, info);
    case Format::Den: return readDen(path, options, info);
    case Format::Raw: return readRaw(path, *options.raw, options.maxVoxels, info);
    case Format::Vdb: return readVdbVolume(path, options, info);
    case Format::Unknown: break;
    }
    throw IoError("cannot read '" + path + "': unrecognised volume format (extension is not one of .nii, "
                  ".nii.gz, .inr, .inr.gz, .den, .raw, .vdb and the content is not NIfTI-1, INRIMAGE-4 "
                  "or VDB); for headerless data pass a RawVolumeLayout");
}

bool isReadableVolumeFile(const std::string& path)
{
    const auto f = volumeio_internal::formatFromExtension(path);
    return f != volumeio_internal::Format::Unknown && f != volumeio_internal::Format::Raw;
}

std::vector<std::string> readableVolumeExtensions()
{
    return {".nii", ".nii.gz", ".inr", ".inr.gz", ".den", ".vdb"};
}

} // namespace levelforge
