// SPDX-License-Identifier: Apache-2.0
// PNG output for the benchmark pictures, through libpng's simplified API.
#pragma once

#include <levelforge/core/Exceptions.h>

#include <png.h>

#include <cstring>
#include <string>
#include <vector>

namespace levelforge_bench {

/// Writes an 8-bit RGB image (w x h, rows top to bottom); throws IoError on failure.
inline void writePng(const std::string& path, int w, int h, const std::vector<unsigned char>& rgb)
{
    png_image image;
    std::memset(&image, 0, sizeof(image));
    image.version = PNG_IMAGE_VERSION;
    image.width = png_uint_32(w);
    image.height = png_uint_32(h);
    image.format = PNG_FORMAT_RGB;
    if (!png_image_write_to_file(&image, path.c_str(), 0, rgb.data(), 0, nullptr))
        throw levelforge::IoError(path + ": cannot write PNG (" + image.message + ")");
}

} // namespace levelforge_bench
