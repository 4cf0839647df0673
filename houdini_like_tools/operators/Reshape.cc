// SPDX-License-Identifier: Apache-2.0
// levelforge operator `reshape`: dilate, erode, open or close a level set by an offset.
// Houdini: *VDB Reshape SDF*; vdb_tool: -dilate / -erode / -open / -close; OpenVDB:
// tools::LevelSetFilter::offset.
#include "Interrupt.h"
#include "LevelSetInput.h"
#include "Operator.h"
#include "OperatorIO.h"
#include "OperatorText.h"

#include <levelforge/core/Exceptions.h>
#include <levelforge/io/VdbIO.h>
#include <levelforge/levelset/ReshapeLevelSet.h>

#include <openvdb/openvdb.h>

#include <chrono>
#include <ostream>
#include <string>

namespace levelforge::ops {
namespace {

void cookReshape(OperatorArgs& args)
{
    using Clock = std::chrono::steady_clock;
    const auto t0 = Clock::now();
    const std::string& input = args.input("input");
    const std::string& output = args.output("output");
    checkOutputTarget(args, output);
    ReshapeOptions opt;
    opt.operation = reshapeOperationFromString(args.getString("op"));
    opt.offset = args.getFloat("offset");
    opt.worldUnits = args.getBool("world-units");

    openvdb::GridPtrVecPtr grids;
    grids = readGridsInput(args, input);
    openvdb::FloatGrid::Ptr grid = pickLevelSet(*grids, input, args.has("grid-name") ? args.getString("grid-name") : "");
    CliProgress progress(10, !args.getBool("quiet"));
    opt.interrupter = &progress;
    const auto t1 = Clock::now();
    openvdb::FloatGrid::Ptr out = reshapeLevelSet(*grid, opt);
    const double seconds = secondsSince(t1);

    writeGridsReplacing(args, output, *grids, grid, out);

    const double h = out->voxelSize()[0];
    const double r = opt.worldUnits ? opt.offset / h : opt.offset;
    args.stat("offset_voxels", r);
    args.stat("active_voxels_before", uint64_t(grid->activeVoxelCount()));
    args.stat("active_voxels", uint64_t(out->activeVoxelCount()));
    args.stat("reshape_seconds", seconds);
    args.out() << "levelforge: wrote " << output << "\n"
               << "  grid '" << out->getName() << "': " << args.getString("op") << " by " << fmt("%g", r)
               << " voxels (" << fmt("%g", r * h) << " world units); " << withThousands(grid->activeVoxelCount())
               << " active voxels before, " << withThousands(out->activeVoxelCount()) << " after\n"
               << "  time: " << fmt("%.2f", seconds) << " s reshape, " << fmt("%.2f", secondsSince(t0)) << " s total\n";
}

} // namespace

LEVELFORGE_REGISTER_OPERATOR(
    OperatorSpec("reshape", "Dilate, erode, open or close a level set by an offset (like VDB Reshape SDF)")
        .description(
            "Reads a .vdb level set and moves its surface by --offset: dilate grows it, erode\n"
            "shrinks it, open (erode, then dilate) removes features thinner than twice the\n"
            "offset, close (dilate, then erode) fills gaps narrower than twice the offset.\n"
            "OpenVDB's LevelSetFilter::offset: steps of at most half a voxel, the narrow band\n"
            "rebuilt after each (first order; the band width is kept). Other grids of the file\n"
            "are written unchanged. Written atomically: on failure no output file appears.")
        .input("input", ".vdb file with a level set")
        .output("output", ".vdb file to write")
        .param(Param::choice("op", "Operation",
                             "dilate: grow by the offset; erode: shrink; open: erode then dilate; close: "
                             "dilate then erode",
                             {"dilate", "erode", "open", "close"})
                   .defaultValue("dilate"))
        .param(Param::floating("offset", "Offset", "How far the surface moves, in voxels (see --world-units)")
                   .defaultValue(1.0)
                   .range(0.0, 10000.0, Bound::Exclusive, Bound::Inclusive))
        .param(Param::flag("world-units", "Use World Space Units", "Read --offset in world units"))
        .param(Param::string("grid-name", "Grid Name", "Level set to reshape (default: the first float level set)"))
        .param(Param::flag("quiet", "Quiet", "Print no progress on stderr"))
        .example("levelforge reshape bunny.vdb bunny_fat.vdb --op dilate --offset 2")
        .example("levelforge reshape scan.vdb scan_clean.vdb --op open --offset 1.5")
        .cook(cookReshape));

} // namespace levelforge::ops
