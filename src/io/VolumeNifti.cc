// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief NIfTI-1 single files (.nii, .nii.gz): readNifti() and writeNifti().
#include "io/VolumeIOInternal.h"

#include <cmath>
#include <cstdio>

namespace levelforge {

namespace volumeio_internal {

/// Reverses the samples of @a vol along axis @a a.
void reverseAxis(ScalarVolume& vol, int a)
{
    const size_t nx = size_t(vol.dims.x()), ny = size_t(vol.dims.y()), nz = size_t(vol.dims.z());
    float* d = vol.data.data();
    if (a == 0) {
        for (size_t row = 0; row < ny * nz; ++row) std::reverse(d + row * nx, d + row * nx + nx);
    } else if (a == 1) {
        for (size_t z = 0; z < nz; ++z) {
            float* slice = d + z * nx * ny;
            for (size_t y = 0; y < ny / 2; ++y) {
                std::swap_ranges(slice + y * nx, slice + y * nx + nx, slice + (ny - 1 - y) * nx);
            }
        }
    } else {
        const size_t s = nx * ny;
        for (size_t z = 0; z < nz / 2; ++z) std::swap_ranges(d + z * s, d + z * s + s, d + (nz - 1 - z) * s);
    }
}

// ----------------------------------------------------------------------------------- NIfTI-1

struct NiftiType
{
    int code;
    VolumeValueType type;
};
constexpr NiftiType kNiftiTypes[] = {
    {2, VolumeValueType::UInt8},    {4, VolumeValueType::Int16},   {8, VolumeValueType::Int32},
    {16, VolumeValueType::Float32}, {64, VolumeValueType::Float64}, {256, VolumeValueType::Int8},
    {512, VolumeValueType::UInt16}, {768, VolumeValueType::UInt32}, {1024, VolumeValueType::Int64},
    {1280, VolumeValueType::UInt64}};

const char* niftiTypeDescription(int code)
{
    switch (code) {
    case 0: return "unknown";
    case 1: return "binary (1 bit)";
    case 32: return "complex64";
    case 128: return "rgb24";
    case 1536: return "float128";
    case 1792: return "complex128";
    case 2048: return "complex256";
    case 2304: return "rgba32";
    default: return "not a NIfTI-1 datatype";
    }
}

ScalarVolume readNiftiStream(InputFile& in, const ReadVolumeOptions& options, VolumeInfo& info)
{
    const std::string& path = in.path();
    unsigned char h[kNiftiHeaderBytes];
    const uint64_t got = in.read(h, sizeof(h));
    if (got < sizeof(h)) {
        throwInvalid(path, "not a NIfTI-1 file: " + std::to_string(got) +
                               " bytes, shorter than the 348-byte NIfTI-1 header");
    }
    bool big = false;
    const int32_t sizeLE = getField<int32_t>(h, 0, false);
    const int32_t sizeBE = getField<int32_t>(h, 0, true);
    if (sizeLE == 348) {
        big = false;
    } else if (sizeBE == 348) {
        big = true;
    } else if (sizeLE == 540 || sizeBE == 540) {
        throwInvalid(path, "NIfTI-2 files (sizeof_hdr = 540) are not supported; save as NIfTI-1");
    } else {
        throwInvalid(path, "not a NIfTI-1 file: sizeof_hdr = " + std::to_string(sizeLE) + " (expected 348)");
    }
    info.format = "nifti";
    info.bigEndian = big;
    const std::string magic(reinterpret_cast<const char*>(h + 344), 4);
    if (magic == std::string("ni1\0", 4)) {
        throwInvalid(path, "two-file NIfTI-1 (magic 'ni1', .hdr + .img) is not supported; "
                           "convert it to a single .nii file");
    }
    if (magic != std::string("n+1\0", 4)) {
        throwInvalid(path, "magic " + message_internal::quotedExcerpt(magic) + " is not the NIfTI-1 single-file magic 'n+1' "
                                                      "(an Analyze 7.5 header?)");
    }

    // dim[8] at 40.
    int64_t dim[8];
    for (int i = 0; i < 8; ++i) dim[i] = getField<int16_t>(h, 40 + 2 * size_t(i), big);
    if (dim[0] < 1 || dim[0] > 7) {
        throwInvalid(path, "dim[0] = " + std::to_string(dim[0]) + " (the number of dimensions must be 1..7)");
    }
    for (int i = 4; i <= dim[0]; ++i) {
        if (dim[i] != 1) {
            throwInvalid(path, "dim[0] = " + std::to_string(dim[0]) + " with dim[" + std::to_string(i) +
                                   "] = " + std::to_string(dim[i]) + ": only 3-D volumes are supported "
                                   "(a time series or vector image has dim[4..] > 1)");
        }
    }
    int64_t dims[3];
    for (int a = 0; a < 3; ++a) dims[a] = (a + 1 <= dim[0]) ? dim[a + 1] : 1;
    const char* dimNames[3] = {"dim[1]", "dim[2]", "dim[3]"};

    const int datatype = getField<int16_t>(h, 70, big);
    bool known = false;
    for (const NiftiType& t : kNiftiTypes) {
        if (t.code == datatype) {
            info.sourceType = t.type;
            known = true;
        }
    }
    if (!known) {
        throwInvalid(path, "unsupported datatype " + std::to_string(datatype) + " (" +
                               niftiTypeDescription(datatype) + "); supported: 2 uint8, 4 int16, 8 int32, "
                               "16 float32, 64 float64, 256 int8, 512 uint16, 768 uint32, 1024 int64, 1280 uint64");
    }

    float pixdim[8];
    for (int i = 0; i < 8; ++i) pixdim[i] = getField<float>(h, 76 + 4 * size_t(i), big);
    openvdb::Vec3d spacing;
    for (int a = 0; a < 3; ++a) {
        const double p = std::fabs(double(pixdim[a + 1]));
        if (!(p > 0.0) || !std::isfinite(p)) {
            if (a + 1 > dim[0]) { // an axis the file does not have
                spacing[a] = 1.0;
                continue;
            }
            throwInvalid(path, "pixdim[" + std::to_string(a + 1) + "] = " + formatDouble(pixdim[a + 1]) +
                                   " (the voxel spacing must be finite and non-zero)");
        }
        spacing[a] = p;
    }

    const float voxOffset = getField<float>(h, 108, big);
    if (!std::isfinite(voxOffset) || voxOffset < float(kNiftiHeaderBytes) || voxOffset != std::floor(voxOffset) ||
        voxOffset > 1e9f) {
        throwInvalid(path, "vox_offset = " + formatDouble(voxOffset) +
                               " (must be a whole number of bytes >= 348)");
    }
    const double slope = getField<float>(h, 112, big);
    double inter = getField<float>(h, 116, big);
    const bool scale = std::isfinite(slope) && slope != 0.0 && !(slope == 1.0 && (inter == 0.0 || !std::isfinite(inter)));
    if (!std::isfinite(inter)) inter = 0.0;

    // Geometry: sform if sform_code > 0, else qform if qform_code > 0, else pixdim only.
    const int qformCode = getField<int16_t>(h, 252, big);
    const int sformCode = getField<int16_t>(h, 254, big);
    double m[3][3] = {{spacing[0], 0, 0}, {0, spacing[1], 0}, {0, 0, spacing[2]}}; // column a = step of index a
    double t[3] = {0, 0, 0};
    std::string xform = "pixdim";
    if (sformCode > 0) {
        xform = "sform";
        for (int r = 0; r < 3; ++r) {
            for (int c = 0; c < 3; ++c) m[r][c] = getField<float>(h, 280 + 16 * size_t(r) + 4 * size_t(c), big);
            t[r] = getField<float>(h, 280 + 16 * size_t(r) + 12, big);
        }
    } else if (qformCode > 0) {
        xform = "qform";
        const double b = getField<float>(h, 256, big), c = getField<float>(h, 260, big),
                     d = getField<float>(h, 264, big);
        const double a = std::sqrt(std::max(0.0, 1.0 - (b * b + c * c + d * d)));
        const double r[3][3] = {{a * a + b * b - c * c - d * d, 2 * (b * c - a * d), 2 * (b * d + a * c)},
                                {2 * (b * c + a * d), a * a + c * c - b * b - d * d, 2 * (c * d - a * b)},
                                {2 * (b * d - a * c), 2 * (c * d + a * b), a * a + d * d - c * c - b * b}};
        const double qfac = pixdim[0] < 0 ? -1.0 : 1.0;
        const double s[3] = {spacing[0], spacing[1], qfac * spacing[2]};
        for (int row = 0; row < 3; ++row) {
            for (int col = 0; col < 3; ++col) m[row][col] = r[row][col] * s[col];
        }
        for (int row = 0; row < 3; ++row) t[row] = getField<float>(h, 268 + 4 * size_t(row), big);
    }
    for (int r = 0; r < 3; ++r) {
        bool ok = std::isfinite(t[r]);
        for (int c = 0; c < 3; ++c) ok &= std::isfinite(m[r][c]);
        if (!ok) throwInvalid(path, "the " + xform + " holds a NaN or infinite value");
    }

    const uint64_t count = checkDims(path, dims, options.maxVoxels, dimNames);
    // The header's numbers against the file's size, before anything is allocated: a plain file
    // must hold every sample; a gzip file is bounded by the deflate ratio and its samples are
    // allocated as they arrive (readSamples()).
    const uint64_t offset = uint64_t(voxOffset);
    const io_internal::FileCapacity capacity = io_internal::fileCapacity(path);
    const std::string problem =
        io_internal::declaredDataProblem(capacity, offset, "the header", dims, typeBytes(info.sourceType));
    if (!problem.empty()) throwInvalid(path, "truncated voxel data: " + problem);
    ScalarVolume vol;
    if (capacity.gzip) vol.dims = openvdb::Coord(int(dims[0]), int(dims[1]), int(dims[2]));
    else allocate(path, vol, dims, count);

    // Skip header extensions up to vox_offset, then read.
    if (in.skip(offset - kNiftiHeaderBytes) < offset - kNiftiHeaderBytes) {
        throwInvalid(path, "truncated: the file ends before vox_offset = " + std::to_string(offset));
    }
    readSamples(in, info.sourceType, big, scale, slope, inter, vol);
    info.compressed = in.compressed();
    in.drain(); // verifies the gzip checksum; trailing bytes are allowed by NIfTI-1

    // Axis-aligned part of the transform.
    double maxDiag = 0.0;
    for (int a = 0; a < 3; ++a) maxDiag = std::max(maxDiag, std::fabs(m[a][a]));
    bool diagonal = maxDiag > 0.0;
    for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) {
            if (r != c && std::fabs(m[r][c]) > 1e-6 * maxDiag) diagonal = false;
        }
        if (!(std::fabs(m[r][r]) > 0.0)) diagonal = false;
    }
    if (diagonal) {
        for (int a = 0; a < 3; ++a) {
            vol.spacing[a] = std::fabs(m[a][a]);
            vol.origin[a] = t[a];
            if (m[a][a] < 0.0) {
                reverseAxis(vol, a);
                vol.origin[a] = t[a] + double(dims[a] - 1) * m[a][a];
                info.reversedAxes[size_t(a)] = true;
            }
        }
    } else {
        for (int a = 0; a < 3; ++a) {
            const double len = std::sqrt(m[0][a] * m[0][a] + m[1][a] * m[1][a] + m[2][a] * m[2][a]);
            vol.spacing[a] = len > 0.0 ? len : spacing[a];
            vol.origin[a] = t[a];
        }
        info.warnings.push_back(path + ": the " + xform + " rotates or shears the voxel axes; only the "
                                       "voxel sizes and the offset are used (world positions are approximate)");
    }
    finish(path, vol, info, scale ? "after scl_slope/scl_inter" : std::string());
    return vol;
}

} // namespace volumeio_internal

// ================================================================================== public API

ScalarVolume readNifti(const std::string& path, const ReadVolumeOptions& options, VolumeInfo* info)
{
    VolumeInfo local;
    volumeio_internal::InputFile in(path);
    ScalarVolume vol = volumeio_internal::readNiftiStream(in, options, local);
    if (info) *info = std::move(local);
    return vol;
}

void writeNifti(const std::string& path, const ScalarVolume& volume)
{
    using namespace volumeio_internal;
    checkWritable(path, volume, "NIfTI-1");
    for (int a = 0; a < 3; ++a) {
        if (volume.dims[a] > 32767) {
            throw InvalidArgumentError("cannot write NIfTI-1 '" + path + "': dims " + formatCoord(volume.dims) +
                                       " exceed the format's 32767 samples per axis");
        }
    }
    unsigned char h[352] = {};
    putLE<int32_t>(h, 0, 348);
    h[38] = 'r'; // regular
    putLE<int16_t>(h, 40, 3);
    for (int a = 0; a < 3; ++a) putLE<int16_t>(h, 42 + 2 * size_t(a), int16_t(volume.dims[a]));
    for (int i = 4; i < 8; ++i) putLE<int16_t>(h, 40 + 2 * size_t(i), 1);
    putLE<int16_t>(h, 70, 16);  // float32
    putLE<int16_t>(h, 72, 32);  // bitpix
    putLE<float>(h, 76, 1.0f);  // qfac
    for (int a = 0; a < 3; ++a) putLE<float>(h, 80 + 4 * size_t(a), float(volume.spacing[a]));
    putLE<float>(h, 108, 352.0f); // vox_offset
    putLE<float>(h, 112, 1.0f);   // scl_slope
    std::snprintf(reinterpret_cast<char*>(h + 148), 80, "levelforge");
    putLE<int16_t>(h, 252, 1); // qform_code: scanner
    putLE<int16_t>(h, 254, 1); // sform_code: scanner
    for (int a = 0; a < 3; ++a) putLE<float>(h, 268 + 4 * size_t(a), float(volume.origin[a]));
    for (int r = 0; r < 3; ++r) {
        putLE<float>(h, 280 + 16 * size_t(r) + 4 * size_t(r), float(volume.spacing[r]));
        putLE<float>(h, 280 + 16 * size_t(r) + 12, float(volume.origin[r]));
    }
    std::memcpy(h + 344, "n+1", 4);
    writeAtomic(path, [&](auto& write) {
        write(h, sizeof(h)); // 348 bytes of header + 4 bytes of (empty) extension flag
        writeFloatsLE(write, volume.data);
    });
}

} // namespace levelforge
