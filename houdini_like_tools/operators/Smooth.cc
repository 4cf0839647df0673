// SPDX-License-Identifier: Apache-2.0
// levelforge operator `smooth`: mean, Gaussian, median, mean-curvature or Laplacian smoothing of
// a level set. Houdini: *VDB Smooth SDF*; vdb_tool: -mean / -gauss / -median; OpenVDB:
// tools::LevelSetFilter.
#include "Interrupt.h"
#include "LevelSetInput.h"
#include "Operator.h"
#include "OperatorIO.h"
#include "OperatorText.h"

#include <levelforge/core/Exceptions.h>
#include <levelforge/io/VdbIO.h>
#include <levelforge/levelset/SmoothLevelSet.h>

#include <openvdb/openvdb.h>

#include <chrono>
#include <ostream>
#include <string>

namespace levelforge::ops {
namespace {

void cookSmooth(OperatorArgs& args)
{
    using Clock = std::chrono::steady_clock;
    const auto t0 = Clock::now();
    const std::string& input = args.input("input");
    const std::string& output = args.output("output");
    checkOutputTarget(args, output);
    SmoothLevelSetOptions opt;
    opt.filter = smoothFilterFromString(args.getString("filter"));
    opt.iterations = int(args.getInt("iterations"));
    opt.radius = int(args.getInt("radius"));

    openvdb::GridPtrVecPtr grids = readGridsInput(args, input);
    openvdb::FloatGrid::Ptr grid = pickLevelSet(*grids, input, args.has("grid-name") ? args.getString("grid-name") : "");
    CliProgress progress(10, !args.getBool("quiet"));
    opt.interrupter = &progress;
    const auto t1 = Clock::now();
    openvdb::FloatGrid::Ptr out = smoothLevelSet(*grid, opt);
    const double seconds = secondsSince(t1);

    writeGridsReplacing(args, output, *grids, grid, out);

    const bool usesRadius = opt.filter == SmoothFilter::Mean || opt.filter == SmoothFilter::Gaussian ||
                            opt.filter == SmoothFilter::Median;
    const uint64_t before = grid->activeVoxelCount(), after = out->activeVoxelCount();
    args.stat("filter", toString(opt.filter));
    args.stat("iterations", opt.iterations);
    args.stat("radius", opt.radius);
    args.stat("active_voxels_before", before);
    args.stat("active_voxels", after);
    args.stat("smooth_seconds", seconds);
    args.stat("seconds", secondsSince(t0));
    args.out() << "levelforge: wrote " << output << "\n"
               << "  grid '" << out->getName() << "': " << toString(opt.filter) << " x" << opt.iterations
               << (usesRadius ? " (radius " + std::to_string(opt.radius) + " voxels)" : std::string()) << "; "
               << withThousands(before) << " active voxels before, " << withThousands(after) << " after\n"
               << "  time: " << fmt("%.2f", seconds) << " s smooth, " << fmt("%.2f", secondsSince(t0)) << " s total\n";
}

} // namespace

LEVELFORGE_REGISTER_OPERATOR(
    OperatorSpec("smooth", "Smooth a level set: mean, Gaussian, median or curvature flow (like VDB Smooth SDF)")
        .description(
            "Reads a .vdb level set and smooths its surface with OpenVDB's LevelSetFilter: mean,\n"
            "gaussian and median filter the (2r+1)^3 voxels around each voxel, mean-curvature and\n"
            "laplacian take one step of the flow per iteration (--radius unused). After each\n"
            "iteration the narrow band is rebuilt (|grad phi| = 1, first order), so the result is a\n"
            "level set with the input's band width. Smoothing shrinks convex parts by a fraction\n"
            "of a voxel per iteration and rounds corners. Other grids of the file are written\n"
            "unchanged. Written atomically: on failure no output file appears.")
        .input("input", ".vdb file with a level set")
        .output("output", ".vdb file to write")
        .param(Param::choice("filter", "Operation",
                             "mean: box average; gaussian: approximate Gaussian (4 box passes); median: box "
                             "median; mean-curvature: curvature flow; laplacian: Laplacian flow",
                             {"mean", "gaussian", "median", "mean-curvature", "laplacian"})
                   .defaultValue("mean"))
        .param(Param::integer("iterations", "Iterations", "Passes of the filter")
                   .defaultValue(1)
                   .range(1, 1000))
        .param(Param::integer("radius", "Filter Voxel Radius",
                              "Filter radius r, in voxels: the box is (2r+1)^3 voxels (mean, gaussian, median)")
                   .defaultValue(1)
                   .range(1, 32))
        .param(Param::string("grid-name", "Grid Name", "Level set to smooth (default: the first float level set)"))
        .param(Param::flag("quiet", "Quiet", "Print no progress on stderr"))
        .example("levelforge smooth scan.vdb scan_smooth.vdb --filter gaussian --iterations 2")
        .example("levelforge smooth bunny.vdb bunny_median.vdb --filter median --radius 2")
        .cook(cookSmooth));

} // namespace levelforge::ops
