// SPDX-License-Identifier: Apache-2.0
// levelforge operator `slice`: a colour-coded PNG of one axis-aligned slice of a level set (the
// signed distance with its zero contour), or a heat map of its error against the exact distance
// to a mesh. Houdini: *Volume Slice*; OpenVDB and vdb_tool have no such tool.
#include "Interrupt.h"
#include "LevelSetInput.h"
#include "Operator.h"
#include "OperatorIO.h"
#include "OperatorText.h"

#include <levelforge/core/Exceptions.h>
#include <levelforge/levelset/SliceImage.h>
#include <levelforge/reference/ExactReference.h>

#include <openvdb/openvdb.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <memory>
#include <ostream>
#include <string>

namespace levelforge::ops {
namespace {

/// Refuses, before any work, an output that is not a .png file.
void checkPngOutput(const std::string& path)
{
    if (isMemoryName(path))
        throw UsageError("slice writes a PNG file; '" + path + "' names an in-memory grid slot");
    std::string lower = path;
    std::transform(lower.begin(), lower.end(), lower.begin(), [](unsigned char c) { return char(std::tolower(c)); });
    const size_t slash = lower.find_last_of('/');
    const std::string name = slash == std::string::npos ? lower : lower.substr(slash + 1);
    if (name.size() < 5 || name.compare(name.size() - 4, 4, ".png") != 0) {
        const size_t dot = name.find_last_of('.');
        throw UsageError("cannot write image '" + path + "': unknown extension '" +
                         (dot == std::string::npos ? std::string() : path.substr(path.size() - (name.size() - dot))) +
                         "' (slice writes .png)");
    }
}

std::string coordText(const openvdb::Coord& c)
{
    return "(" + std::to_string(c[0]) + ", " + std::to_string(c[1]) + ", " + std::to_string(c[2]) + ")";
}

void cookSlice(OperatorArgs& args)
{
    const auto t0 = std::chrono::steady_clock::now();
    const std::string& input = args.input("input");
    const std::string& output = args.output("output");
    checkPngOutput(output);
    checkOutputTarget(args, output);

    SliceImageOptions opt;
    opt.axis = sliceAxisFromString(args.getString("axis"));
    if (args.has("index")) opt.index = args.getInt("index");
    if (args.has("world")) opt.world = args.getFloat("world");
    opt.pixelsPerVoxel = args.has("pixels-per-voxel") ? int(args.getInt("pixels-per-voxel")) : 0;
    opt.units = args.getString("units") == "world" ? SliceUnits::World : SliceUnits::Voxels;
    opt.errorScale = args.getFloat("error-scale");

    const openvdb::GridPtrVecPtr grids = readGridsInput(args, input);
    const openvdb::FloatGrid::Ptr grid =
        pickLevelSet(*grids, input, args.has("grid-name") ? args.getString("grid-name") : "");
    std::unique_ptr<TriangleMesh> mesh;
    std::unique_ptr<ExactReference> reference;
    const std::string meshName = args.has("error-against") ? args.getString("error-against") : "";
    if (!meshName.empty()) {
        mesh = std::make_unique<TriangleMesh>(readMeshInput(args, meshName));
        reference = std::make_unique<ExactReference>(*mesh);
        opt.reference = reference.get();
    }
    CliProgress progress(10, !args.getBool("quiet"));
    opt.interrupter = &progress;

    const auto t1 = std::chrono::steady_clock::now();
    SliceImageInfo info;
    RgbImage image;
    try {
        image = renderSlice(*grid, opt, &info);
    } catch (const InvalidArgumentError& e) {
        throw InvalidArgumentError(input + ": " + e.what());
    }
    const double seconds = secondsSince(t1);
    writePng(image, output);

    const double h = grid->voxelSize()[0];
    const char* axis = toString(opt.axis);
    const int64_t nu = info.uMax - info.uMin + 1, nv = info.vMax - info.vMin + 1;
    args.stat("index", info.index);
    args.stat("world", info.worldCoordinate);
    args.stat("width", image.width);
    args.stat("height", image.height);
    args.stat("pixels_per_voxel", info.pixelsPerVoxel);
    args.stat("active_voxels", info.activeVoxels);
    args.stat("contour_pixels", info.contourPixels);
    args.out() << "levelforge: wrote " << output << "\n"
               << "  grid '" << grid->getName() << "': slice " << axis << " = " << info.index << " (world "
               << fmt("%g", info.worldCoordinate) << "), " << nu << " x " << nv << " voxels at "
               << info.pixelsPerVoxel << " px per voxel, image " << image.width << " x " << image.height << "\n"
               << "  " << withThousands(info.activeVoxels) << " active voxels in the slice, zero contour "
               << withThousands(info.contourPixels) << " px";
    if (!reference) {
        args.out() << ", colours saturate at +/-" << fmt("%g", info.saturation / h) << " voxels ("
                   << fmt("%g", info.saturation) << " world units)\n";
    } else {
        args.stat("max_error_voxels", info.maxError);
        args.stat("mean_error_voxels", info.meanError);
        args.stat("compared_voxels", info.errorVoxels);
        args.out() << "\n  error against " << mesh->source << ": max " << fmt("%.4g", info.maxError)
                   << " voxels at " << coordText(info.maxErrorVoxel) << ", mean " << fmt("%.4g", info.meanError)
                   << " voxels over " << withThousands(info.errorVoxels) << " active voxels (colours saturate at "
                   << fmt("%g", opt.errorScale) << " voxels)\n";
    }
    args.stat("seconds", secondsSince(t0));
    args.out() << "  time: " << fmt("%.2f", seconds) << " s render, " << fmt("%.2f", secondsSince(t0))
               << " s total\n";
}

} // namespace

LEVELFORGE_REGISTER_OPERATOR(
    OperatorSpec("slice", "Picture of one slice of a level set, or of its error against a mesh (PNG)")
        .description(
            "Writes a PNG of one axis-aligned slice through the active bounding box of a level\n"
            "set: the signed distance in a diverging colour map (blue inside, white at 0, red\n"
            "outside, saturating at the band width), inactive values as a flat tone of their sign,\n"
            "the zero contour as a black line (from the bilinear interpolation of the voxel\n"
            "values), and a legend with tick labels. With --error-against MESH: a heat map of\n"
            "|phi - exact signed distance to MESH| in voxels at each active voxel, and the largest\n"
            "and mean error printed. Images: x slices show (y, z), y slices (x, z), z slices\n"
            "(x, y), the second axis pointing up. Written atomically.")
        .input("input", ".vdb file with a level set")
        .output("output", ".png file to write")
        .param(Param::choice("axis", "Axis", "The axis the slice is perpendicular to", {"x", "y", "z"})
                   .defaultValue("z"))
        .param(Param::integer("index", "Slice Index",
                              "Index coordinate of the slice along --axis, voxels (default: the middle of the "
                              "active bounding box)")
                   .exclusiveWith("world"))
        .param(Param::floating("world", "Slice Position",
                               "World coordinate of the slice along --axis, world units (the nearest voxel "
                               "plane is taken)"))
        .param(Param::integer("pixels-per-voxel", "Pixels per Voxel",
                              "Edge of each voxel's square in the image, pixels (default: the largest that keeps "
                              "the slice within 1024 pixels)")
                   .range(1, 64))
        .param(Param::choice("units", "Legend Units", "Units of the distance legend: voxels or world units",
                             {"voxels", "world"})
                   .defaultValue("voxels"))
        .param(Param::string("error-against", "Error Against",
                             "Mesh file or builtin:shape: draw |phi - exact signed distance| in voxels instead"))
        .param(Param::floating("error-scale", "Error Scale",
                               "Error at which the heat map saturates, voxels (with --error-against)")
                   .defaultValue(1.0)
                   .range(0.0, 1000.0, Bound::Exclusive, Bound::Inclusive))
        .param(Param::string("grid-name", "Grid Name", "Float grid to slice (default: the first float level set)"))
        .param(Param::flag("quiet", "Quiet", "Print no progress on stderr"))
        .example("levelforge slice bunny.vdb bunny_z.png --axis z")
        .example("levelforge slice bunny.vdb bunny_x.png --axis x --world 0.1 --pixels-per-voxel 4")
        .example("levelforge slice bunny.vdb bunny_err.png --error-against bunny.obj --error-scale 0.5")
        .cook(cookSlice));

} // namespace levelforge::ops
