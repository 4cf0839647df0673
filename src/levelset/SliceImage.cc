// SPDX-License-Identifier: Apache-2.0
// Pictures of one slice of a level set: signed distance with its zero contour, or the error
// against an exact reference, with a legend in levelforge's own bitmap font. See
// levelset/SliceImage.h.
#include <levelforge/levelset/SliceImage.h>

#include <levelforge/core/Exceptions.h>
#include <levelforge/reference/ExactReference.h>

#include "detail/AtomicFile.h"

#include <png.h>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <sstream>

namespace levelforge {

RgbImage::RgbImage(int w, int h, Rgb fill) : width(w), height(h), pixels(size_t(w) * size_t(h) * 3)
{
    for (size_t i = 0; i < pixels.size(); i += 3) {
        pixels[i] = fill[0];
        pixels[i + 1] = fill[1];
        pixels[i + 2] = fill[2];
    }
}

SliceAxis sliceAxisFromString(const std::string& name)
{
    if (name == "x") return SliceAxis::X;
    if (name == "y") return SliceAxis::Y;
    if (name == "z") return SliceAxis::Z;
    throw InvalidArgumentError("unknown slice axis '" + name + "' (x, y, z)");
}

const char* toString(SliceAxis axis)
{
    switch (axis) {
    case SliceAxis::X: return "x";
    case SliceAxis::Y: return "y";
    case SliceAxis::Z: return "z";
    }
    return "?";
}

namespace {

using Rgb = RgbImage::Rgb;

Rgb mix(const Rgb& a, const Rgb& b, double t)
{
    Rgb c;
    for (int k = 0; k < 3; ++k) c[k] = uint8_t(std::lround(double(a[k]) + (double(b[k]) - double(a[k])) * t));
    return c;
}

} // namespace

Rgb divergingColour(double t)
{
    static constexpr Rgb kBlue{33, 102, 172}, kWhite{255, 255, 255}, kRed{178, 24, 43};
    if (!(t == t)) t = 0.0; // NaN
    t = std::clamp(t, -1.0, 1.0);
    return t < 0.0 ? mix(kWhite, kBlue, -t) : mix(kWhite, kRed, t);
}

Rgb sequentialColour(double t)
{
    // Five key colours of the viridis map (dark purple, blue, teal, green, yellow).
    static constexpr Rgb kStops[5] = {{68, 1, 84}, {59, 82, 139}, {33, 145, 140}, {94, 201, 98}, {253, 231, 37}};
    if (!(t == t)) t = 0.0;
    t = std::clamp(t, 0.0, 1.0) * 4.0;
    const int i = std::min(int(t), 3);
    return mix(kStops[i], kStops[i + 1], t - double(i));
}

namespace {

// ------------------------------------------------------------------------------ bitmap font

/// One 5×7 glyph: seven rows, top first; bit 4 is the leftmost column.
struct Glyph
{
    char c;
    uint8_t rows[7];
};

// levelforge's own font: digits, lower-case letters (upper case is drawn as lower case) and the
// signs the legends use.
constexpr Glyph kFont[] = {
    {'0', {0x0E, 0x11, 0x13, 0x15, 0x19, 0x11, 0x0E}}, {'1', {0x04, 0x0C, 0x04, 0x04, 0x04, 0x04, 0x0E}},
    {'2', {0x0E, 0x11, 0x01, 0x02, 0x04, 0x08, 0x1F}}, {'3', {0x1F, 0x02, 0x04, 0x02, 0x01, 0x11, 0x0E}},
    {'4', {0x02, 0x06, 0x0A, 0x12, 0x1F, 0x02, 0x02}}, {'5', {0x1F, 0x10, 0x1E, 0x01, 0x01, 0x11, 0x0E}},
    {'6', {0x06, 0x08, 0x10, 0x1E, 0x11, 0x11, 0x0E}}, {'7', {0x1F, 0x01, 0x02, 0x04, 0x08, 0x08, 0x08}},
    {'8', {0x0E, 0x11, 0x11, 0x0E, 0x11, 0x11, 0x0E}}, {'9', {0x0E, 0x11, 0x11, 0x0F, 0x01, 0x02, 0x0C}},
    {'-', {0x00, 0x00, 0x00, 0x0E, 0x00, 0x00, 0x00}}, {'+', {0x00, 0x04, 0x04, 0x1F, 0x04, 0x04, 0x00}},
    {'.', {0x00, 0x00, 0x00, 0x00, 0x00, 0x0C, 0x0C}}, {',', {0x00, 0x00, 0x00, 0x00, 0x0C, 0x04, 0x08}},
    {'=', {0x00, 0x00, 0x1F, 0x00, 0x1F, 0x00, 0x00}}, {':', {0x00, 0x0C, 0x0C, 0x00, 0x0C, 0x0C, 0x00}},
    {'|', {0x04, 0x04, 0x04, 0x04, 0x04, 0x04, 0x04}}, {'(', {0x02, 0x04, 0x08, 0x08, 0x08, 0x04, 0x02}},
    {')', {0x08, 0x04, 0x02, 0x02, 0x02, 0x04, 0x08}}, {'/', {0x00, 0x01, 0x02, 0x04, 0x08, 0x10, 0x00}},
    {'>', {0x08, 0x04, 0x02, 0x01, 0x02, 0x04, 0x08}}, {'a', {0x00, 0x00, 0x0E, 0x01, 0x0F, 0x11, 0x0F}},
    {'b', {0x10, 0x10, 0x16, 0x19, 0x11, 0x11, 0x1E}}, {'c', {0x00, 0x00, 0x0E, 0x10, 0x10, 0x11, 0x0E}},
    {'d', {0x01, 0x01, 0x0D, 0x13, 0x11, 0x11, 0x0F}}, {'e', {0x00, 0x00, 0x0E, 0x11, 0x1F, 0x10, 0x0E}},
    {'f', {0x06, 0x09, 0x08, 0x1C, 0x08, 0x08, 0x08}}, {'g', {0x00, 0x00, 0x0F, 0x11, 0x0F, 0x01, 0x0E}},
    {'h', {0x10, 0x10, 0x16, 0x19, 0x11, 0x11, 0x11}}, {'i', {0x04, 0x00, 0x0C, 0x04, 0x04, 0x04, 0x0E}},
    {'j', {0x02, 0x00, 0x06, 0x02, 0x02, 0x12, 0x0C}}, {'k', {0x10, 0x10, 0x12, 0x14, 0x18, 0x14, 0x12}},
    {'l', {0x0C, 0x04, 0x04, 0x04, 0x04, 0x04, 0x0E}}, {'m', {0x00, 0x00, 0x1A, 0x15, 0x15, 0x11, 0x11}},
    {'n', {0x00, 0x00, 0x16, 0x19, 0x11, 0x11, 0x11}}, {'o', {0x00, 0x00, 0x0E, 0x11, 0x11, 0x11, 0x0E}},
    {'p', {0x00, 0x00, 0x1E, 0x11, 0x1E, 0x10, 0x10}}, {'q', {0x00, 0x00, 0x0D, 0x13, 0x0F, 0x01, 0x01}},
    {'r', {0x00, 0x00, 0x16, 0x19, 0x10, 0x10, 0x10}}, {'s', {0x00, 0x00, 0x0E, 0x10, 0x0E, 0x01, 0x1E}},
    {'t', {0x08, 0x08, 0x1C, 0x08, 0x08, 0x09, 0x06}}, {'u', {0x00, 0x00, 0x11, 0x11, 0x11, 0x13, 0x0D}},
    {'v', {0x00, 0x00, 0x11, 0x11, 0x11, 0x0A, 0x04}}, {'w', {0x00, 0x00, 0x11, 0x11, 0x15, 0x15, 0x0A}},
    {'x', {0x00, 0x00, 0x11, 0x0A, 0x04, 0x0A, 0x11}}, {'y', {0x00, 0x00, 0x11, 0x11, 0x0F, 0x01, 0x0E}},
    {'z', {0x00, 0x00, 0x1F, 0x02, 0x04, 0x08, 0x1F}},
};

const Glyph* glyphOf(char c)
{
    c = char(std::tolower(static_cast<unsigned char>(c)));
    for (const Glyph& g : kFont)
        if (g.c == c) return &g;
    return nullptr; // a space, or a character the font lacks: left blank
}

/// Width in pixels of @p text at scale @p s (6 s per character, no trailing gap).
int textWidth(const std::string& text, int s) { return text.empty() ? 0 : int(text.size()) * 6 * s - s; }

/// Draws @p text with its top-left corner at (x, y), each font pixel an s × s square.
void drawText(RgbImage& img, int x, int y, const std::string& text, int s, Rgb colour)
{
    for (const char c : text) {
        if (const Glyph* g = glyphOf(c)) {
            for (int row = 0; row < 7; ++row)
                for (int col = 0; col < 5; ++col)
                    if (g->rows[row] & (0x10 >> col)) img.fillRect(x + col * s, y + row * s, s, s, colour);
        }
        x += 6 * s;
    }
}

/// "%.3g" of @p v, with -0 written as 0.
std::string tickLabel(double v)
{
    if (std::abs(v) < 1e-12) v = 0.0;
    char buf[32];
    std::snprintf(buf, sizeof(buf), "%.3g", v);
    return buf;
}

// ------------------------------------------------------------------------------ the slice

/// The values of one slice, row-major, row 0 = vMax (the top of the picture).
struct SliceSamples
{
    int nu = 0, nv = 0;
    std::vector<float> value;
    std::vector<uint8_t> active;
    float at(int u, int v) const { return value[size_t(v) * size_t(nu) + size_t(u)]; }
};

/// φ interpolated bilinearly between voxel centres at the centre of pixel (x, y) of the slice
/// area (p pixels per voxel); beyond the outer voxel centres the nearest value is kept.
float bilinear(const SliceSamples& s, int p, int x, int y)
{
    const double fu = (double(x) + 0.5) / double(p) - 0.5; // in voxel units from the centre of column 0
    const double fv = (double(y) + 0.5) / double(p) - 0.5;
    const double cu = std::clamp(fu, 0.0, double(s.nu - 1)), cv = std::clamp(fv, 0.0, double(s.nv - 1));
    const int u0 = std::min(int(cu), s.nu - 1), v0 = std::min(int(cv), s.nv - 1);
    const int u1 = std::min(u0 + 1, s.nu - 1), v1 = std::min(v0 + 1, s.nv - 1);
    const double a = cu - double(u0), b = cv - double(v0);
    const double top = double(s.at(u0, v0)) * (1.0 - a) + double(s.at(u1, v0)) * a;
    const double bottom = double(s.at(u0, v1)) * (1.0 - a) + double(s.at(u1, v1)) * a;
    return float(top * (1.0 - b) + bottom * b);
}

void checkInterrupt(openvdb::util::NullInterrupter* interrupter, std::atomic<bool>& stop, int percent)
{
    if (interrupter && !stop.load(std::memory_order_relaxed) && interrupter->wasInterrupted(percent))
        stop.store(true, std::memory_order_relaxed);
}

std::string axisRange(const char* axis, int64_t lo, int64_t hi)
{
    std::ostringstream os;
    os << axis << " from " << lo << " to " << hi;
    return os.str();
}

} // namespace

RgbImage renderSlice(const openvdb::FloatGrid& grid, const SliceImageOptions& options, SliceImageInfo* infoOut)
{
    const std::string what = "slice of grid '" + grid.getName() + "'";
    if (options.index && options.world)
        throw InvalidArgumentError(what + ": give the slice position as an index or as a world coordinate, not both");
    if (options.pixelsPerVoxel < 0 || options.pixelsPerVoxel > 64)
        throw InvalidArgumentError(what + ": pixels per voxel must be 1 to 64 (0: automatic), got " +
                                   std::to_string(options.pixelsPerVoxel));
    if (options.reference && !(options.errorScale > 0.0 && std::isfinite(options.errorScale)))
        throw InvalidArgumentError(what + ": the error scale must be a positive number of voxels");
    const openvdb::CoordBBox bbox = grid.evalActiveVoxelBoundingBox();
    if (grid.activeVoxelCount() == 0 || bbox.empty())
        throw InvalidArgumentError(what + ": the grid has no active values, nothing to slice");

    SliceImageInfo info;
    info.axis = options.axis;
    const int w = int(options.axis);
    info.uAxis = w == 0 ? 1 : 0;
    info.vAxis = w == 2 ? 1 : 2;
    const char* axisName = toString(options.axis);
    const int64_t lo = bbox.min()[w], hi = bbox.max()[w];
    if (options.world) {
        openvdb::Vec3d p = grid.indexToWorld(bbox.getCenter());
        p[w] = *options.world;
        const double fi = grid.worldToIndex(p)[w];
        info.index = std::isfinite(fi) ? int64_t(std::llround(std::clamp(fi, -4e18, 4e18))) : lo - 1;
        if (info.index < lo || info.index > hi) {
            std::ostringstream os;
            os << what << ": world " << axisName << " = " << *options.world << " (index " << fi
               << ") is outside the active bounding box (index " << axisRange(axisName, lo, hi) << ")";
            throw InvalidArgumentError(os.str());
        }
    } else if (options.index) {
        info.index = *options.index;
        if (info.index < lo || info.index > hi)
            throw InvalidArgumentError(what + ": index " + axisName + " = " + std::to_string(info.index) +
                                       " is outside the active bounding box (" + axisRange(axisName, lo, hi) + ")");
    } else {
        info.index = lo + (hi - lo) / 2;
    }
    {
        openvdb::Vec3d c = bbox.getCenter();
        c[w] = double(info.index);
        info.worldCoordinate = grid.indexToWorld(c)[w];
    }
    info.uMin = bbox.min()[info.uAxis];
    info.uMax = bbox.max()[info.uAxis];
    info.vMin = bbox.min()[info.vAxis];
    info.vMax = bbox.max()[info.vAxis];
    SliceSamples s;
    s.nu = int(info.uMax - info.uMin + 1);
    s.nv = int(info.vMax - info.vMin + 1);
    const int longSide = std::max(s.nu, s.nv);
    const int p = options.pixelsPerVoxel > 0 ? options.pixelsPerVoxel : std::clamp(1024 / longSide, 1, 64);
    info.pixelsPerVoxel = p;
    constexpr int64_t kMaxSide = 16384;
    if (int64_t(longSide) * p > kMaxSide) {
        std::ostringstream os;
        os << what << ": the slice is " << s.nu << " x " << s.nv << " voxels; at " << p
           << " pixels per voxel its longer side would be " << int64_t(longSide) * p << " pixels (at most "
           << kMaxSide << ")";
        throw InvalidArgumentError(os.str());
    }
    const bool errorMode = options.reference != nullptr;
    const double h = grid.voxelSize()[0];
    openvdb::util::NullInterrupter* interrupter = options.interrupter;
    if (interrupter) interrupter->start(errorMode ? "slice error" : "slice");
    std::atomic<bool> stop{false};

    // 1. sample the slice (and, for the error picture, the exact distance at every active voxel)
    s.value.resize(size_t(s.nu) * size_t(s.nv));
    s.active.resize(s.value.size());
    std::vector<float> error(errorMode ? s.value.size() : 0, -1.0f); // voxels; -1: not compared
    std::atomic<int> rowsDone{0};
    tbb::parallel_for(tbb::blocked_range<int>(0, s.nv), [&](const tbb::blocked_range<int>& rows) {
        auto acc = grid.getConstAccessor();
        for (int row = rows.begin(); row != rows.end(); ++row) {
            if (stop.load(std::memory_order_relaxed)) return;
            openvdb::Coord ijk;
            ijk[w] = openvdb::Int32(info.index);
            ijk[info.vAxis] = openvdb::Int32(info.vMax - row);
            for (int col = 0; col < s.nu; ++col) {
                ijk[info.uAxis] = openvdb::Int32(info.uMin + col);
                const size_t i = size_t(row) * size_t(s.nu) + size_t(col);
                float v = 0.0f;
                s.active[i] = acc.probeValue(ijk, v) ? 1 : 0;
                s.value[i] = v;
                if (errorMode && s.active[i]) {
                    const double d = options.reference->signedDistance(grid.indexToWorld(ijk));
                    error[i] = float(std::abs(double(v) - d) / h);
                }
            }
            checkInterrupt(interrupter, stop, 80 * (rowsDone.fetch_add(1) + 1) / s.nv);
        }
    });
    if (stop) throw InterruptedError("slice: interrupted");

    for (const uint8_t a : s.active) info.activeVoxels += a;
    if (errorMode) {
        double sum = 0.0;
        for (size_t i = 0; i < error.size(); ++i) {
            if (error[i] < 0.0f) continue;
            ++info.errorVoxels;
            sum += double(error[i]);
            if (double(error[i]) > info.maxError || info.errorVoxels == 1) {
                info.maxError = double(error[i]);
                openvdb::Coord c;
                c[w] = openvdb::Int32(info.index);
                c[info.vAxis] = openvdb::Int32(info.vMax - int64_t(i / size_t(s.nu)));
                c[info.uAxis] = openvdb::Int32(info.uMin + int64_t(i % size_t(s.nu)));
                info.maxErrorVoxel = c;
            }
        }
        info.meanError = info.errorVoxels ? sum / double(info.errorVoxels) : 0.0;
    }
    double sat = std::abs(double(grid.background()));
    if (!(sat > 0.0)) {
        for (size_t i = 0; i < s.value.size(); ++i)
            if (s.active[i]) sat = std::max(sat, std::abs(double(s.value[i])));
    }
    if (!(sat > 0.0) || !std::isfinite(sat)) sat = h;
    info.saturation = sat;

    // 2. the canvas: the slice, then the legend strip under it
    const int sliceW = s.nu * p, sliceH = s.nv * p;
    const int ts = sliceW >= 600 ? 2 : 1; // text scale
    const int margin = 10 * ts;
    const int barW = std::clamp(sliceW - 40 * ts, 320 * ts, 640 * ts);
    const int barX = margin + 20 * ts;
    const int canvasW = std::max(margin + sliceW + margin, barX + barW + 20 * ts + margin);
    info.sliceX = margin + std::max(0, (canvasW - 2 * margin - sliceW) / 2);
    info.sliceY = margin;
    const int captionY = info.sliceY + sliceH + 8 * ts;
    const int barY = captionY + 12 * ts;
    const int barH = 12 * ts;
    const int labelY = barY + barH + 6 * ts;
    const int swatchY = labelY + 13 * ts;
    const int infoY = swatchY + 13 * ts;
    const int canvasH = infoY + 7 * ts + margin;
    RgbImage img(canvasW, canvasH, slice_colours::kCanvas);
    info.barX = barX;
    info.barY = barY;
    info.barWidth = barW;
    info.barHeight = barH;

    // 3. the slice's voxels (nearest), then the zero contour of the bilinear interpolant
    tbb::parallel_for(tbb::blocked_range<int>(0, sliceH), [&](const tbb::blocked_range<int>& rows) {
        for (int y = rows.begin(); y != rows.end(); ++y) {
            const int row = y / p;
            for (int x = 0; x < sliceW; ++x) {
                const size_t i = size_t(row) * size_t(s.nu) + size_t(x / p);
                Rgb c;
                if (errorMode) {
                    c = error[i] < 0.0f ? slice_colours::kInactiveError : sequentialColour(double(error[i]) / options.errorScale);
                } else if (s.active[i]) {
                    c = divergingColour(double(s.value[i]) / sat);
                } else {
                    c = s.value[i] < 0.0f ? slice_colours::kInactiveInside : slice_colours::kInactiveOutside;
                }
                img.set(info.sliceX + x, info.sliceY + y, c);
            }
        }
    });
    std::vector<uint8_t> contour(size_t(sliceW) * size_t(sliceH), 0);
    tbb::parallel_for(tbb::blocked_range<int>(0, sliceH), [&](const tbb::blocked_range<int>& rows) {
        const size_t rowLength = size_t(sliceW);
        std::vector<float> above(rowLength), here(rowLength), below(rowLength);
        for (int y = rows.begin(); y != rows.end(); ++y) {
            if (stop.load(std::memory_order_relaxed)) return;
            for (int x = 0; x < sliceW; ++x) {
                here[size_t(x)] = bilinear(s, p, x, y);
                if (y > 0) above[size_t(x)] = bilinear(s, p, x, y - 1);
                if (y + 1 < sliceH) below[size_t(x)] = bilinear(s, p, x, y + 1);
            }
            // A pixel is on the contour when a 4-neighbour lies on the other side of zero and is
            // not nearer to zero than it is.
            const auto crosses = [](float a, float b) { return (a < 0.0f) != (b < 0.0f) && std::abs(a) <= std::abs(b); };
            for (int x = 0; x < sliceW; ++x) {
                const float v = here[size_t(x)];
                const bool on = (x > 0 && crosses(v, here[size_t(x - 1)])) ||
                                (x + 1 < sliceW && crosses(v, here[size_t(x + 1)])) ||
                                (y > 0 && crosses(v, above[size_t(x)])) ||
                                (y + 1 < sliceH && crosses(v, below[size_t(x)]));
                if (on) contour[size_t(y) * size_t(sliceW) + size_t(x)] = 1;
            }
            checkInterrupt(interrupter, stop, 80 + 20 * (y + 1) / sliceH);
        }
    });
    if (stop) throw InterruptedError("slice: interrupted");
    for (int y = 0; y < sliceH; ++y)
        for (int x = 0; x < sliceW; ++x)
            if (contour[size_t(y) * size_t(sliceW) + size_t(x)]) {
                img.set(info.sliceX + x, info.sliceY + y, errorMode ? slice_colours::kErrorContour : slice_colours::kContour);
                ++info.contourPixels;
            }

    // 4. the legend: caption, colour bar with a frame, ticks and labels, swatches
    const double unit = (!errorMode && options.units == SliceUnits::World) ? 1.0 : 1.0 / h; // value -> label
    const std::string caption = errorMode ? "error |phi - exact|, voxels"
                                          : std::string("signed distance, ") +
                                                (options.units == SliceUnits::World ? "world units" : "voxels");
    std::ostringstream where;
    char worldText[32];
    std::snprintf(worldText, sizeof(worldText), "%.6g", info.worldCoordinate);
    where << axisName << " = " << info.index << " (world " << worldText << ")";
    if (errorMode) where << "   max " << tickLabel(info.maxError) << "   mean " << tickLabel(info.meanError);
    drawText(img, barX, infoY, where.str(), ts, slice_colours::kText);
    drawText(img, barX, captionY, caption, ts, slice_colours::kText);
    for (int x = 0; x < barW; ++x) {
        const double t = (double(x) + 0.5) / double(barW);
        const Rgb c = errorMode ? sequentialColour(t) : divergingColour(2.0 * t - 1.0);
        img.fillRect(barX + x, barY, 1, barH, c);
    }
    img.fillRect(barX - 1, barY - 1, barW + 2, 1, slice_colours::kText);
    img.fillRect(barX - 1, barY + barH, barW + 2, 1, slice_colours::kText);
    img.fillRect(barX - 1, barY - 1, 1, barH + 2, slice_colours::kText);
    img.fillRect(barX + barW, barY - 1, 1, barH + 2, slice_colours::kText);
    for (int k = 0; k <= 4; ++k) {
        const int x = barX + std::min(barW - 1, barW * k / 4);
        img.fillRect(x, barY + barH, std::max(1, ts), 4 * ts, slice_colours::kText);
        const double value = errorMode ? options.errorScale * k / 4.0 : sat * unit * (k / 2.0 - 1.0);
        const std::string label = (errorMode && k == 4 ? ">" : "") + tickLabel(value);
        const int lx = std::clamp(x - textWidth(label, ts) / 2, 0, canvasW - textWidth(label, ts));
        drawText(img, lx, labelY, label, ts, slice_colours::kText);
    }
    int sx = barX;
    const auto swatch = [&](const Rgb& c, const std::string& text) {
        img.fillRect(sx - 1, swatchY - 1, 7 * ts + 2, 7 * ts + 2, slice_colours::kText);
        img.fillRect(sx, swatchY, 7 * ts, 7 * ts, c);
        drawText(img, sx + 10 * ts, swatchY, text, ts, slice_colours::kText);
        sx += 10 * ts + textWidth(text, ts) + 12 * ts;
    };
    if (errorMode) {
        swatch(slice_colours::kInactiveError, "inactive");
    } else {
        swatch(slice_colours::kInactiveInside, "inactive inside");
        swatch(slice_colours::kInactiveOutside, "inactive outside");
    }
    swatch(errorMode ? slice_colours::kErrorContour : slice_colours::kContour, "zero contour");
    if (interrupter) interrupter->end();
    if (infoOut) *infoOut = info;
    return img;
}

void writePng(const RgbImage& image, const std::string& path)
{
    if (image.width <= 0 || image.height <= 0 || image.pixels.size() != size_t(image.width) * size_t(image.height) * 3)
        throw InvalidArgumentError("cannot write PNG '" + path + "': the image is empty");
    detail::AtomicFile file(path, "cannot write PNG '" + path + "'");
    std::FILE* stream = ::fdopen(file.descriptor(), "wb");
    if (!stream) file.fail(std::strerror(errno));
    file.releaseDescriptor(); // now owned by stream
    png_image png;
    std::memset(&png, 0, sizeof(png));
    png.version = PNG_IMAGE_VERSION;
    png.width = png_uint_32(image.width);
    png.height = png_uint_32(image.height);
    png.format = PNG_FORMAT_RGB;
    const bool ok = png_image_write_to_stdio(&png, stream, 0, image.pixels.data(), 0, nullptr) != 0;
    const std::string message = ok ? std::string() : std::string(png.message);
    const bool flushed = std::fflush(stream) == 0 && !std::ferror(stream);
    const int flushErrno = errno;
    const bool closed = std::fclose(stream) == 0;
    if (!ok) file.fail(message);
    if (!flushed || !closed) file.fail(std::strerror(flushed ? errno : flushErrno));
    file.sync();
    file.commit();
}

} // namespace levelforge
