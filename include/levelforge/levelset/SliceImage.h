// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief A picture of one axis-aligned slice of a level set: the signed distance in a diverging
///        colour map with its zero contour, or the error against the exact distance to a mesh as
///        a heat map, with a legend (`levelforge slice`; Houdini's *Volume Slice*, OpenVDB has no
///        such tool).
///
/// Layout: the slice covers the grid's active bounding box (evalActiveVoxelBoundingBox()) in the
/// two axes other than the slice axis; each voxel is a square of pixelsPerVoxel × pixelsPerVoxel
/// pixels. Horizontal / vertical (up) image axes: slicing along x shows (y, z), along y (x, z),
/// along z (x, y). Under the slice, a legend strip: the colour bar with numeric tick labels,
/// its units, the slice's axis and index, and (distance pictures) swatches of the inactive tones.
/// Text is drawn with levelforge's own 5×7 bitmap font (digits, lower-case letters, a few signs).
///
/// Distance picture: each voxel's value φ in a diverging map, blue inside (φ < 0), white at 0,
/// red outside, saturating at the band width (|background|; for a grid without a background,
/// the largest |φ| of the slice). Inactive values (background tiles, the interior and exterior
/// beyond the band) are a flat grey-blue or grey-red tone by their sign. The zero contour is a
/// black line one pixel wide: φ is interpolated bilinearly between voxel centres at every pixel
/// centre (the values are point samples), and of two neighbouring pixels (right or below) whose
/// interpolated values differ in sign, the one nearer to zero is drawn black. The contour is
/// therefore within one pixel of the bilinear zero crossing, which for a smooth signed distance
/// lies within O(h²) of the exact surface.
///
/// Error picture (options.reference set): at each active voxel of the slice, |φ − d| / h with d
/// the exact signed distance from the voxel centre to the mesh (reference/ExactReference.h:
/// exact closest point, pseudonormal sign), in a sequential colour map from dark (0) to yellow
/// (options.errorScale voxels and more). Inactive voxels have no stored distance to compare and
/// are drawn in a flat grey. The zero contour of φ is drawn as above, in white. The statistics
/// (SliceImageInfo: the largest and mean error and where the largest is) are exact for the
/// voxels of the slice.
///
/// writePng() writes the image as an 8-bit RGB PNG atomically (temporary file + rename through
/// the library's one atomic writer, as writeMesh() and writeGridsAtomic() do).
#pragma once

#include <openvdb/openvdb.h>
#include <openvdb/util/NullInterrupter.h>

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace levelforge {

class ExactReference;

/// An 8-bit RGB image, rows from top to bottom, three bytes per pixel.
struct RgbImage
{
    using Rgb = std::array<uint8_t, 3>;
    int width = 0, height = 0;
    std::vector<uint8_t> pixels; ///< width * height * 3 bytes

    RgbImage() = default;
    RgbImage(int w, int h, Rgb fill);
    Rgb at(int x, int y) const
    {
        const size_t i = (size_t(y) * size_t(width) + size_t(x)) * 3;
        return {pixels[i], pixels[i + 1], pixels[i + 2]};
    }
    void set(int x, int y, Rgb c)
    {
        if (x < 0 || y < 0 || x >= width || y >= height) return;
        const size_t i = (size_t(y) * size_t(width) + size_t(x)) * 3;
        pixels[i] = c[0];
        pixels[i + 1] = c[1];
        pixels[i + 2] = c[2];
    }
    void fillRect(int x, int y, int w, int h, Rgb c)
    {
        for (int j = y; j < y + h; ++j)
            for (int i = x; i < x + w; ++i) set(i, j, c);
    }
};

/// The slice axis (the axis the slice is perpendicular to).
enum class SliceAxis { X = 0, Y = 1, Z = 2 };

/// "x" / "y" / "z"; throws InvalidArgumentError otherwise.
SliceAxis sliceAxisFromString(const std::string& name);
/// "x" / "y" / "z".
const char* toString(SliceAxis axis);

/// Units of the legend of a distance picture.
enum class SliceUnits { Voxels, World };

/// @brief The fixed colours of the pictures (for tests and documentation).
namespace slice_colours {
constexpr RgbImage::Rgb kInactiveInside{96, 110, 150};   ///< inactive value < 0 (distance picture)
constexpr RgbImage::Rgb kInactiveOutside{165, 120, 120}; ///< inactive value >= 0 (distance picture)
constexpr RgbImage::Rgb kInactiveError{150, 150, 150};   ///< inactive voxel (error picture)
constexpr RgbImage::Rgb kContour{0, 0, 0};               ///< the zero contour (distance picture)
constexpr RgbImage::Rgb kErrorContour{255, 255, 255};    ///< the zero contour (error picture)
constexpr RgbImage::Rgb kCanvas{255, 255, 255};          ///< around the slice and in the legend
constexpr RgbImage::Rgb kText{0, 0, 0};                  ///< labels, ticks and frames
} // namespace slice_colours

/// @brief The diverging map of the distance picture: t = φ / saturation, clamped to [−1, 1];
///        −1 deep blue, 0 white, +1 deep red (linear in between).
RgbImage::Rgb divergingColour(double t);
/// @brief The sequential map of the error picture: t = error / scale, clamped to [0, 1]; 0 dark
///        purple, 1 yellow (piecewise linear through blue and green).
RgbImage::Rgb sequentialColour(double t);

/// @brief Options of renderSlice().
struct SliceImageOptions
{
    SliceAxis axis = SliceAxis::Z;
    /// Index coordinate of the slice along the axis; when neither index nor world is set, the
    /// middle of the active bounding box. Must lie inside the active bounding box.
    std::optional<int64_t> index;
    /// World coordinate of the slice along the axis (the nearest voxel plane is taken); not with
    /// index.
    std::optional<double> world;
    /// Pixels per voxel edge, 1–64; 0: the largest that keeps the slice's longer side at most
    /// 1024 pixels (at least 1).
    int pixelsPerVoxel = 0;
    /// Units of the distance legend's tick labels.
    SliceUnits units = SliceUnits::Voxels;
    /// Error picture only: an exact reference of the mesh the grid should match (not owned);
    /// null: distance picture.
    const ExactReference* reference = nullptr;
    /// Error picture only: the error, in voxels, at which the heat map saturates (> 0).
    double errorScale = 1.0;
    /// Polled once per row of the slice (progress 0–100); true throws InterruptedError.
    openvdb::util::NullInterrupter* interrupter = nullptr;
};

/// @brief What renderSlice() drew, and where.
struct SliceImageInfo
{
    SliceAxis axis = SliceAxis::Z;
    int64_t index = 0;         ///< index coordinate of the slice along the axis
    double worldCoordinate = 0.0; ///< world coordinate of the slice plane along the axis
    int uAxis = 0, vAxis = 1;  ///< grid axes shown horizontally and vertically (up)
    int64_t uMin = 0, uMax = 0, vMin = 0, vMax = 0; ///< index range shown (inclusive)
    int pixelsPerVoxel = 1;
    int sliceX = 0, sliceY = 0; ///< top-left pixel of the slice in the image
    int barX = 0, barY = 0, barWidth = 0, barHeight = 0; ///< the legend's colour bar in the image
    double saturation = 0.0;   ///< |φ| at which the distance map saturates, world units
    uint64_t activeVoxels = 0; ///< active voxels in the slice
    uint64_t contourPixels = 0;///< pixels drawn as the zero contour
    /// Error picture: active voxels compared, largest and mean |φ − d| / h, and the voxel of
    /// the largest (index coordinates).
    uint64_t errorVoxels = 0;
    double maxError = 0.0, meanError = 0.0;
    openvdb::Coord maxErrorVoxel{0, 0, 0};

    /// The pixel at the centre of voxel @p ijk's square (the slice coordinate of ijk is ignored).
    std::array<int, 2> pixelOf(const openvdb::Coord& ijk) const
    {
        const int p = pixelsPerVoxel;
        return {sliceX + int(ijk[uAxis] - uMin) * p + p / 2, sliceY + int(vMax - ijk[vAxis]) * p + p / 2};
    }
};

/// @brief Renders one slice of @p grid (see the file comment).
/// @param[in]  grid     a float grid with at least one active value (a level set in practice)
/// @param[in]  options  axis, position, scale, units, error reference
/// @param[out] info     optional: where the slice is and what was measured
/// @return the picture
/// @throws InvalidArgumentError no active values; index and world both set; the slice outside
///         the active bounding box; pixelsPerVoxel outside 0–64; an image side over 16384
///         pixels; errorScale not > 0
/// @throws InterruptedError the interrupter asked to stop
RgbImage renderSlice(const openvdb::FloatGrid& grid, const SliceImageOptions& options,
                     SliceImageInfo* info = nullptr);

/// @brief Writes @p image as an 8-bit RGB PNG file, atomically (nothing is left behind on failure).
/// @throws IoError the file cannot be written (the message names it)
/// @throws InvalidArgumentError an empty image
void writePng(const RgbImage& image, const std::string& path);

} // namespace levelforge
