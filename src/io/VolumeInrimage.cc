// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief INRIMAGE-4 images (.inr, .inr.gz): readInr() and writeInr().
#include "io/VolumeIOInternal.h"

#include <charconv>
#include <cmath>
#include <cstdlib>
#include <sstream>

namespace levelforge {

namespace volumeio_internal {

// ----------------------------------------------------------------------------- INRIMAGE-4

ScalarVolume readInrStream(InputFile& in, const ReadVolumeOptions& options, VolumeInfo& info)
{
    const std::string& path = in.path();
    std::string header;
    header.resize(256);
    const uint64_t first = in.read(header.data(), 256);
    header.resize(size_t(first));
    if (header.compare(0, sizeof(kInrMagic) - 1, kInrMagic) != 0) {
        throwInvalid(path, "not an INRIMAGE-4 file: it does not start with '#INRIMAGE-4#{'");
    }
    if (first < 256) throwInvalid(path, "truncated INRIMAGE-4 header: " + std::to_string(first) + " of 256 bytes");
    // The header is padded to a multiple of 256 bytes and ends with "##}\n".
    size_t end = header.find("##}");
    while (end == std::string::npos || header.size() < ((end + 4 + 255) / 256) * 256) {
        if (header.size() >= (1u << 16)) throwInvalid(path, "no '##}' ending the INRIMAGE-4 header in its first 64 KiB");
        const size_t old = header.size();
        header.resize(old + 256);
        const uint64_t got = in.read(header.data() + old, 256);
        if (got < 256) throwInvalid(path, "truncated INRIMAGE-4 header: no '##}' before the end of the file");
        if (end == std::string::npos) end = header.find("##}");
    }
    const size_t headerBytes = ((end + 4 + 255) / 256) * 256;
    info.format = "inr";

    int64_t dims[3] = {-1, -1, 1};
    int64_t vdim = 1;
    std::string typeText;
    int64_t bits = -1;
    std::string cpu;
    openvdb::Vec3d spacing(1.0), origin(0.0);
    std::istringstream lines(header.substr(sizeof(kInrMagic) - 1, end - (sizeof(kInrMagic) - 1)));
    std::string line;
    auto parseInt = [&](const std::string& key, const std::string& value) {
        int64_t v = 0;
        const char* b = value.data();
        const char* e = b + value.size();
        const auto r = std::from_chars(b, e, v);
        if (r.ec != std::errc() || b == e) throwInvalid(path, key + " = " + message_internal::quotedExcerpt(value) + " is not an integer");
        return v;
    };
    auto parseReal = [&](const std::string& key, const std::string& value) {
        char* e = nullptr;
        const double v = std::strtod(value.c_str(), &e);
        if (e == value.c_str() || !std::isfinite(v)) {
            throwInvalid(path, key + " = " + message_internal::quotedExcerpt(value) + " is not a finite number");
        }
        return v;
    };
    while (std::getline(lines, line)) {
        while (!line.empty() && (line.back() == '\r' || line.back() == ' ')) line.pop_back();
        if (line.empty() || line[0] == '#') continue;
        const size_t eq = line.find('=');
        if (eq == std::string::npos) continue;
        std::string key = line.substr(0, eq);
        std::string value = line.substr(eq + 1);
        while (!key.empty() && key.back() == ' ') key.pop_back();
        while (!value.empty() && value.front() == ' ') value.erase(0, 1);
        if (key == "XDIM") dims[0] = parseInt(key, value);
        else if (key == "YDIM") dims[1] = parseInt(key, value);
        else if (key == "ZDIM") dims[2] = parseInt(key, value);
        else if (key == "VDIM") vdim = parseInt(key, value);
        else if (key == "TYPE") typeText = value;
        else if (key == "PIXSIZE") {
            bits = parseInt(key, value.substr(0, value.find(' ')));
        } else if (key == "CPU") cpu = value;
        else if (key == "VX") spacing[0] = parseReal(key, value);
        else if (key == "VY") spacing[1] = parseReal(key, value);
        else if (key == "VZ") spacing[2] = parseReal(key, value);
        else if (key == "XO") origin[0] = parseReal(key, value);
        else if (key == "YO") origin[1] = parseReal(key, value);
        else if (key == "ZO") origin[2] = parseReal(key, value);
    }
    if (dims[0] < 0) throwInvalid(path, "the INRIMAGE-4 header has no XDIM");
    if (dims[1] < 0) throwInvalid(path, "the INRIMAGE-4 header has no YDIM");
    if (vdim != 1) {
        throwInvalid(path, "VDIM = " + std::to_string(vdim) + ": only scalar images (VDIM=1) are supported");
    }
    for (int a = 0; a < 3; ++a) {
        if (!(spacing[a] > 0.0)) {
            throwInvalid(path, std::string(a == 0 ? "VX" : a == 1 ? "VY" : "VZ") + " = " + formatDouble(spacing[a]) +
                                   " (the voxel spacing must be > 0)");
        }
    }
    if (typeText.empty()) throwInvalid(path, "the INRIMAGE-4 header has no TYPE");
    if (bits < 0) throwInvalid(path, "the INRIMAGE-4 header has no PIXSIZE");
    const std::string bitsText = std::to_string(bits);
    if (typeText == "float") {
        if (bits == 32) info.sourceType = VolumeValueType::Float32;
        else if (bits == 64) info.sourceType = VolumeValueType::Float64;
        else throwInvalid(path, "TYPE=float with PIXSIZE=" + bitsText + " bits is not supported (32 or 64)");
    } else if (typeText == "unsigned fixed" || typeText == "signed fixed") {
        const bool s = typeText[0] == 's';
        switch (bits) {
        case 8: info.sourceType = s ? VolumeValueType::Int8 : VolumeValueType::UInt8; break;
        case 16: info.sourceType = s ? VolumeValueType::Int16 : VolumeValueType::UInt16; break;
        case 32: info.sourceType = s ? VolumeValueType::Int32 : VolumeValueType::UInt32; break;
        case 64: info.sourceType = s ? VolumeValueType::Int64 : VolumeValueType::UInt64; break;
        default:
            throwInvalid(path, "TYPE=" + typeText + " with PIXSIZE=" + bitsText +
                                   " bits is not supported (8, 16, 32 or 64)");
        }
    } else {
        throwInvalid(path, "unsupported TYPE " + message_internal::quotedExcerpt(typeText) +
                               " (supported: 'unsigned fixed', 'signed fixed', 'float')");
    }
    bool big = false;
    if (cpu.empty() || cpu == "decm" || cpu == "pc" || cpu == "alpha") {
        big = false;
        if (cpu.empty() && typeBytes(info.sourceType) > 1) {
            info.warnings.push_back(path + ": no CPU in the INRIMAGE-4 header; little endian assumed");
        }
    } else if (cpu == "sun" || cpu == "sgi") {
        big = true;
    } else {
        throwInvalid(path, "unknown CPU " + message_internal::quotedExcerpt(cpu) + " (expected decm, pc, alpha, sun or sgi)");
    }
    info.bigEndian = big;

    const char* dimNames[3] = {"XDIM", "YDIM", "ZDIM"};
    const uint64_t count = checkDims(path, dims, options.maxVoxels, dimNames);
    // The header's numbers against the file's size, before anything is allocated: a plain file
    // must hold every sample; a gzip file is bounded by the deflate ratio and its samples are
    // allocated as they arrive (readSamples()).
    const io_internal::FileCapacity capacity = io_internal::fileCapacity(path);
    const std::string problem =
        io_internal::declaredDataProblem(capacity, headerBytes, "the header", dims, typeBytes(info.sourceType));
    if (!problem.empty()) throwInvalid(path, "truncated voxel data: " + problem);
    ScalarVolume vol;
    if (capacity.gzip) vol.dims = openvdb::Coord(int(dims[0]), int(dims[1]), int(dims[2]));
    else allocate(path, vol, dims, count);
    vol.spacing = spacing;
    vol.origin = origin;
    if (in.skip(headerBytes - header.size()) < headerBytes - header.size()) {
        throwInvalid(path, "truncated INRIMAGE-4 header");
    }
    readSamples(in, info.sourceType, big, false, 1.0, 0.0, vol);
    info.compressed = in.compressed();
    in.drain(); // verifies the gzip checksum
    finish(path, vol, info, "");
    return vol;
}

} // namespace volumeio_internal

// ================================================================================== public API

ScalarVolume readInr(const std::string& path, const ReadVolumeOptions& options, VolumeInfo* info)
{
    VolumeInfo local;
    volumeio_internal::InputFile in(path);
    ScalarVolume vol = volumeio_internal::readInrStream(in, options, local);
    if (info) *info = std::move(local);
    return vol;
}

void writeInr(const std::string& path, const ScalarVolume& volume)
{
    using namespace volumeio_internal;
    checkWritable(path, volume, "INRIMAGE-4");
    auto real = [](double v) { return formatDouble(v); }; // finite (checkWritable)
    std::string header = std::string(kInrMagic) + "\n";
    header += "XDIM=" + std::to_string(volume.dims.x()) + "\n";
    header += "YDIM=" + std::to_string(volume.dims.y()) + "\n";
    header += "ZDIM=" + std::to_string(volume.dims.z()) + "\n";
    header += "VDIM=1\nTYPE=float\nPIXSIZE=32 bits\nCPU=decm\n";
    header += "VX=" + real(volume.spacing[0]) + "\nVY=" + real(volume.spacing[1]) + "\nVZ=" +
              real(volume.spacing[2]) + "\n";
    header += "XO=" + real(volume.origin[0]) + "\nYO=" + real(volume.origin[1]) + "\nZO=" +
              real(volume.origin[2]) + "\n";
    const size_t total = ((header.size() + 4 + 255) / 256) * 256;
    header.append(total - 4 - header.size(), '\n');
    header += "##}\n";
    writeAtomic(path, [&](auto& write) {
        write(header.data(), header.size());
        writeFloatsLE(write, volume.data);
    });
}

} // namespace levelforge
