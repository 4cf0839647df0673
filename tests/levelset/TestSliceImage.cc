// SPDX-License-Identifier: Apache-2.0
// renderSlice() and writePng(): the picture of an analytic sphere (colours at known voxels, the
// zero contour on the circle, the legend), the axis mapping, the slice position, the error heat
// map of an exact level set and of a perturbed one, and the PNG file decoded with libpng.
#include "TestUtil.h"

#include <levelforge/core/Exceptions.h>
#include <levelforge/levelset/SliceImage.h>
#include <levelforge/mesh/MeshToLevelSet.h>
#include <levelforge/reference/ExactReference.h>
#include <levelforge/reference/MeshShapes.h>

#include <openvdb/openvdb.h>
#include <openvdb/tools/LevelSetSphere.h>

#include <png.h>

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <string>

using namespace levelforge;
namespace fs = std::filesystem;

namespace {

constexpr double kH = 0.1; // voxel size
constexpr double kR = 1.0; // sphere radius: 10 voxels

openvdb::FloatGrid::Ptr sphere(const openvdb::Vec3d& c = openvdb::Vec3d(0.0))
{
    openvdb::initialize();
    return openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(float(kR), openvdb::Vec3f(c), float(kH), 3.0f);
}

/// Decodes a PNG file with libpng's simplified API into 8-bit RGB.
RgbImage decodePng(const std::string& path)
{
    png_image png;
    std::memset(&png, 0, sizeof(png));
    png.version = PNG_IMAGE_VERSION;
    if (!png_image_begin_read_from_file(&png, path.c_str())) {
        ADD_FAILURE() << path << ": " << png.message;
        return {};
    }
    png.format = PNG_FORMAT_RGB;
    RgbImage img(int(png.width), int(png.height), {0, 0, 0});
    if (!png_image_finish_read(&png, nullptr, img.pixels.data(), 0, nullptr)) {
        ADD_FAILURE() << path << ": " << png.message;
        return {};
    }
    return img;
}

/// Index-space position (u, v) of the centre of pixel (x, y) of the slice.
std::array<double, 2> pixelToIndex(const SliceImageInfo& info, int x, int y)
{
    const double p = info.pixelsPerVoxel;
    return {double(info.uMin) - 0.5 + (double(x - info.sliceX) + 0.5) / p,
            double(info.vMax) + 0.5 - (double(y - info.sliceY) + 0.5) / p};
}

bool insideSlice(const SliceImageInfo& info, int x, int y)
{
    const int w = int(info.uMax - info.uMin + 1) * info.pixelsPerVoxel;
    const int h = int(info.vMax - info.vMin + 1) * info.pixelsPerVoxel;
    return x >= info.sliceX && x < info.sliceX + w && y >= info.sliceY && y < info.sliceY + h;
}

/// Checks that every contour pixel lies within @p tolPx pixels of the circle of radius @p r
/// (voxels) centred at (cu, cv) (index space) and that the contour goes all round it.
void expectContourOnCircle(const RgbImage& img, const SliceImageInfo& info, double cu, double cv, double r, double tolPx)
{
    size_t n = 0;
    double worst = 0.0;
    int quadrants[4] = {0, 0, 0, 0};
    for (int y = 0; y < img.height; ++y)
        for (int x = 0; x < img.width; ++x) {
            if (!insideSlice(info, x, y) || img.at(x, y) != slice_colours::kContour) continue;
            const auto uv = pixelToIndex(info, x, y);
            const double du = uv[0] - cu, dv = uv[1] - cv;
            worst = std::max(worst, std::abs(std::hypot(du, dv) - r) * info.pixelsPerVoxel);
            ++quadrants[(du >= 0 ? 0 : 1) + (dv >= 0 ? 0 : 2)];
            ++n;
        }
    EXPECT_EQ(n, info.contourPixels);
    EXPECT_LE(worst, tolPx) << "contour pixel " << worst << " px off the circle";
    // a line one pixel wide all round: at least the circumference / sqrt(2) pixels
    EXPECT_GT(double(n), 2.0 * M_PI * r * info.pixelsPerVoxel / std::sqrt(2.0) * 0.95);
    for (int q = 0; q < 4; ++q) EXPECT_GT(quadrants[q], 0) << "quadrant " << q;
}

} // namespace

TEST(SliceImage, SphereSliceColoursContourAndLegend)
{
    const auto grid = sphere();
    SliceImageOptions o;
    o.pixelsPerVoxel = 8;
    SliceImageInfo info;
    const RgbImage img = renderSlice(*grid, o, &info);
    EXPECT_EQ(info.axis, SliceAxis::Z);
    EXPECT_EQ(info.index, 0); // the middle of the symmetric band's bounding box
    EXPECT_EQ(info.uAxis, 0);
    EXPECT_EQ(info.vAxis, 1);
    const int n = int(info.uMax - info.uMin + 1);
    EXPECT_EQ(n, 25); // the band's last voxels are 12 from the centre (13 is exactly the band width: background)
    EXPECT_GE(img.width, n * 8 + 2 * info.sliceX - 1);
    EXPECT_GT(img.height, n * 8 + info.sliceY);
    EXPECT_NEAR(info.saturation, 3.0 * kH, 1e-6);
    // the centre (inactive interior) and a far corner (inactive exterior)
    const auto c = info.pixelOf(openvdb::Coord(0, 0, 0));
    EXPECT_EQ(img.at(c[0], c[1]), slice_colours::kInactiveInside);
    const auto far = info.pixelOf(openvdb::Coord(int(info.uMin), int(info.vMin), 0));
    EXPECT_EQ(img.at(far[0], far[1]), slice_colours::kInactiveOutside);
    // active voxels in the band: the diverging colour of φ / band
    for (const int i : {-12, -11, -9, -8, 8, 9, 11, 12}) {
        const openvdb::Coord ijk(i, 0, 0);
        const float phi = grid->tree().getValue(ijk);
        ASSERT_TRUE(grid->tree().isValueOn(ijk));
        const auto px = info.pixelOf(ijk);
        EXPECT_EQ(img.at(px[0], px[1]), divergingColour(double(phi) / (3.0 * kH))) << i;
    }
    EXPECT_EQ(img.at(info.pixelOf(openvdb::Coord(0, 12, 0))[0], info.pixelOf(openvdb::Coord(0, 12, 0))[1]),
              divergingColour(2.0 / 3.0)); // φ = 2 voxels: red side
    EXPECT_EQ(divergingColour(0.0), (RgbImage::Rgb{255, 255, 255}));
    // the zero contour: within 1 px of the circle of radius 10 voxels
    expectContourOnCircle(img, info, 0.0, 0.0, kR / kH, 1.0);
    // the legend: a colour bar from blue through white to red, framed, with black labels under it
    const int midY = info.barY + info.barHeight / 2;
    EXPECT_EQ(img.at(info.barX, midY), divergingColour(-1.0 + 1.0 / info.barWidth));
    EXPECT_EQ(img.at(info.barX + info.barWidth - 1, midY), divergingColour(1.0 - 1.0 / info.barWidth));
    const RgbImage::Rgb mid = img.at(info.barX + info.barWidth / 2, midY);
    for (int k = 0; k < 3; ++k) EXPECT_GE(mid[k], 250);
    EXPECT_EQ(img.at(info.barX - 1, midY), slice_colours::kText); // frame
    size_t textPixels = 0;
    for (int y = info.barY + info.barHeight + 1; y < img.height; ++y)
        for (int x = 0; x < img.width; ++x) textPixels += img.at(x, y) == slice_colours::kText;
    EXPECT_GT(textPixels, 200u); // tick marks, five labels, swatch captions, the slice position
    size_t captionPixels = 0;
    for (int y = info.sliceY + n * 8; y < info.barY - 1; ++y)
        for (int x = 0; x < img.width; ++x) captionPixels += img.at(x, y) == slice_colours::kText;
    EXPECT_GT(captionPixels, 50u); // "signed distance, voxels"
}

TEST(SliceImage, EveryAxisShowsTheCircleWhereItIs)
{
    const openvdb::Vec3d c(0.32, -0.21, 0.14);
    const auto grid = sphere(c);
    const openvdb::Vec3d ci = grid->worldToIndex(c);
    for (const SliceAxis axis : {SliceAxis::X, SliceAxis::Y, SliceAxis::Z}) {
        SCOPED_TRACE(toString(axis));
        const int w = int(axis);
        SliceImageOptions o;
        o.axis = axis;
        o.pixelsPerVoxel = 6;
        o.index = int64_t(std::lround(ci[w])) + 3; // off-centre: a smaller circle
        SliceImageInfo info;
        const RgbImage img = renderSlice(*grid, o, &info);
        EXPECT_EQ(info.index, *o.index);
        const double dz = double(info.index) - ci[w];
        expectContourOnCircle(img, info, ci[info.uAxis], ci[info.vAxis], std::sqrt(100.0 - dz * dz), 1.0);
        EXPECT_NEAR(info.worldCoordinate, double(info.index) * kH, 1e-6); // the transform is single precision
    }
}

TEST(SliceImage, WorldPositionPicksTheNearestVoxelPlane)
{
    const auto grid = sphere();
    SliceImageOptions o;
    o.axis = SliceAxis::Y;
    o.world = 0.26; // index 2.6
    o.pixelsPerVoxel = 8;
    SliceImageInfo info;
    const RgbImage img = renderSlice(*grid, o, &info);
    EXPECT_EQ(info.index, 3);
    EXPECT_EQ(info.uAxis, 0);
    EXPECT_EQ(info.vAxis, 2);
    expectContourOnCircle(img, info, 0.0, 0.0, std::sqrt(100.0 - 9.0), 1.0);
}

TEST(SliceImage, AutomaticScaleKeepsTheSliceWithin1024Pixels)
{
    const auto grid = sphere();
    SliceImageInfo info;
    const RgbImage img = renderSlice(*grid, SliceImageOptions(), &info);
    EXPECT_EQ(info.pixelsPerVoxel, 1024 / 25);
    EXPECT_LE(25 * info.pixelsPerVoxel, 1024);
    EXPECT_GT(25 * (info.pixelsPerVoxel + 1), 1024);
    EXPECT_LT(img.width, 1100);
}

TEST(SliceImage, ErrorMapOfAnExactLevelSetIsZeroAndShowsAPerturbation)
{
    openvdb::initialize();
    const TriangleMesh mesh = makeIcosphere(Vec3d(0.0), 1.0, 3);
    MeshToLevelSetOptions mo;
    mo.voxelSize = 0.05;
    const auto grid = meshToLevelSet(mesh, mo); // exact distances in the band
    const ExactReference reference(mesh);
    SliceImageOptions o;
    o.reference = &reference;
    o.pixelsPerVoxel = 4;
    SliceImageInfo info;
    RgbImage img = renderSlice(*grid, o, &info);
    EXPECT_GT(info.errorVoxels, 500u);
    EXPECT_LT(info.maxError, 1e-4);
    const RgbImage::Rgb zero = sequentialColour(0.0);
    size_t zeroPixels = 0;
    for (int y = 0; y < img.height; ++y)
        for (int x = 0; x < img.width; ++x) {
            if (!insideSlice(info, x, y)) continue;
            const RgbImage::Rgb px = img.at(x, y);
            if (px == slice_colours::kErrorContour || px == slice_colours::kInactiveError) continue;
            ASSERT_EQ(px, zero) << x << ", " << y;
            ++zeroPixels;
        }
    EXPECT_GT(zeroPixels, 500u * 16u);

    // Perturb the active voxels of a small box by half a voxel: the map shows 0.5 there, 0 elsewhere.
    const auto bad = grid->deepCopy();
    const openvdb::CoordBBox box(openvdb::Coord(8, 8, -3), openvdb::Coord(20, 20, 3));
    for (auto it = bad->tree().beginValueOn(); it; ++it)
        if (box.isInside(it.getCoord())) it.setValue(*it + 0.5f * 0.05f);
    img = renderSlice(*bad, o, &info);
    EXPECT_NEAR(info.maxError, 0.5, 1e-3);
    EXPECT_TRUE(box.isInside(info.maxErrorVoxel)) << info.maxErrorVoxel;
    const RgbImage::Rgb half = sequentialColour(0.5);
    size_t inBox = 0, outside = 0;
    for (auto it = bad->tree().cbeginValueOn(); it; ++it) {
        const openvdb::Coord ijk = it.getCoord();
        if (ijk[2] != info.index) continue;
        const auto p = info.pixelOf(ijk);
        const RgbImage::Rgb px = img.at(p[0], p[1]);
        if (px == slice_colours::kErrorContour) continue;
        if (box.isInside(ijk)) {
            EXPECT_EQ(px, half) << ijk;
            ++inBox;
        } else {
            EXPECT_EQ(px, zero) << ijk;
            ++outside;
        }
    }
    EXPECT_GT(inBox, 10u);
    EXPECT_GT(outside, 100u);
}

TEST(SliceImage, PngRoundTripIsExactAndAtomic)
{
    const fs::path dir = levelforge_test::scratchDir("slice_png");
    const auto grid = sphere();
    SliceImageOptions o;
    o.axis = SliceAxis::X;
    const RgbImage img = renderSlice(*grid, o);
    const std::string path = (dir / "x.png").string();
    writePng(img, path);
    const RgbImage back = decodePng(path);
    EXPECT_EQ(back.width, img.width);
    EXPECT_EQ(back.height, img.height);
    EXPECT_TRUE(back.pixels == img.pixels);
    // no temporary file left next to it
    size_t files = 0;
    for (const auto& e : fs::directory_iterator(dir)) {
        (void)e;
        ++files;
    }
    EXPECT_EQ(files, 1u);
    // a missing folder: IoError naming the file, nothing created
    const std::string missing = (dir / "no" / "x.png").string();
    try {
        writePng(img, missing);
        ADD_FAILURE() << "no error";
    } catch (const IoError& e) {
        EXPECT_NE(std::string(e.what()).find(missing), std::string::npos) << e.what();
    }
    EXPECT_FALSE(fs::exists(missing));
    EXPECT_THROW(writePng(RgbImage(), path), InvalidArgumentError);
}

TEST(SliceImage, BadPositionsAndGrids)
{
    const auto grid = sphere();
    SliceImageOptions o;
    o.index = 13; // the band ends at 12
    EXPECT_THROW(renderSlice(*grid, o), InvalidArgumentError);
    o.index = -12;
    EXPECT_NO_THROW(renderSlice(*grid, o));
    o.world = 0.0;
    EXPECT_THROW(renderSlice(*grid, o), InvalidArgumentError); // both
    o.index.reset();
    o.world = 5.0;
    EXPECT_THROW(renderSlice(*grid, o), InvalidArgumentError);
    o.world = std::nan("");
    EXPECT_THROW(renderSlice(*grid, o), InvalidArgumentError);
    o.world.reset();
    o.pixelsPerVoxel = 65;
    EXPECT_THROW(renderSlice(*grid, o), InvalidArgumentError);
    o.pixelsPerVoxel = 0;
    auto empty = openvdb::FloatGrid::create(0.3f);
    empty->setGridClass(openvdb::GRID_LEVEL_SET);
    try {
        renderSlice(*empty, o);
        ADD_FAILURE() << "no error";
    } catch (const InvalidArgumentError& e) {
        EXPECT_NE(std::string(e.what()).find("no active values"), std::string::npos) << e.what();
    }
    EXPECT_THROW(sliceAxisFromString("w"), InvalidArgumentError);
}
