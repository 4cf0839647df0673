// SPDX-License-Identifier: Apache-2.0
// levelforge operator `expand`: widen (or narrow) the band of a level set by fast sweeping.
// Houdini: *VDB Activate SDF* / *VDB Reshape SDF* (dilate); OpenVDB: tools::dilateSdf.
#include "Interrupt.h"
#include "LevelSetInput.h"
#include "Operator.h"
#include "OperatorIO.h"
#include "OperatorText.h"

#include <levelforge/core/Exceptions.h>
#include <levelforge/expand/ExpandLevelSet.h>
#include <levelforge/io/VdbIO.h>

#include <openvdb/openvdb.h>

#include <chrono>
#include <cstdio>
#include <ostream>
#include <string>

namespace levelforge::ops {
namespace {

const char* const kMethod = "zhao2005-fast-sweeping";
const char* const kVectorMethod = "satherley-jones-vcvdt8";

void cookExpand(OperatorArgs& args)
{
    using Clock = std::chrono::steady_clock;
    const auto t0 = Clock::now();
    const std::string& input = args.input("input");
    const std::string& output = args.output("output");
    checkOutputTarget(args, output);

    openvdb::GridPtrVecPtr grids;
    grids = readGridsInput(args, input);
    openvdb::FloatGrid::Ptr grid =
        pickLevelSet(*grids, input, args.has("grid-name") ? args.getString("grid-name") : "");

    ExpandLevelSetOptions opt;
    opt.exteriorWidth = args.getFloat("exterior-width");
    opt.interiorWidth = args.getFloat("interior-width");
    opt.units = args.getBool("world-units") ? WidthUnits::World : WidthUnits::Voxels;
    opt.fillInterior = args.getBool("fill-interior");
    opt.domain = args.getString("domain") == "bbox" ? ExpansionDomain::BoundingBox
                                                    : ExpansionDomain::Band;
    opt.boundingBoxMargin = args.getFloat("bbox-margin");
    opt.tolerance = args.getFloat("tolerance");
    opt.maxIterations = static_cast<int>(args.getInt("max-iterations"));
    const bool vector = args.getString("method") == "vector";
    opt.method = vector ? ExpansionMethod::Vector : ExpansionMethod::Sweep;
    CliProgress progress(10, !args.getBool("quiet"));
    opt.interrupter = &progress;

    ExpandLevelSetStats st;
    const auto t1 = Clock::now();
    openvdb::FloatGrid::Ptr out = expandLevelSet(*grid, opt, &st);
    const double seconds = secondsSince(t1);

    const double h = out->voxelSize()[0];
    const double bg = out->background() / h;
    const bool box = opt.domain == ExpansionDomain::BoundingBox;
    const double ext = box ? bg : opt.widthInVoxels(opt.exteriorWidth, h);
    const double in = (box || opt.fillInterior) ? bg : opt.widthInVoxels(opt.interiorWidth, h);
    stampLevelSetMetadata(*out, ext, in, input, vector ? kVectorMethod : kMethod);
    writeGridsReplacing(args, output, *grids, grid, out);

    args.stat("input_band_voxels", uint64_t(st.frozenVoxels));
    args.stat("active_voxels", uint64_t(out->activeVoxelCount()));
    args.stat("exterior_band_voxels", ext);
    args.stat("interior_band_voxels", in);
    std::ostream& os = args.out();
    os << "levelforge: wrote " << output << "\n"
       << "  grid '" << out->getName() << "': " << withThousands(st.frozenVoxels)
       << " voxels in the input band, " << withThousands(out->activeVoxelCount())
       << " active voxels now\n"
       << "  band: " << fmt("%g", ext) << " voxels outside, " << fmt("%g", in)
       << " voxels inside (plus a coverage margin, see docs/expansion.md)\n";
    if (vector) {
        os << "  vectors: 8-pass VCVDT from " << withThousands(st.frozenVoxels)
           << " shell voxels (closest points estimated from phi and grad phi), "
           << withThousands(st.unreachedVoxels) << " unreached\n";
    } else {
        os << "  sweeps: " << withThousands(st.leafUpdates) << " leaf passes (at most "
           << st.iterations << " per leaf), " << withThousands(st.voxelUpdates) << " voxel updates, "
           << (st.converged ? "largest change not passed on " + fmt("%.3g", st.maxChange) + " voxels"
                            : std::string("not converged"))
           << "\n";
    }
    os << "  time: " << fmt("%.2f", seconds) << " s expansion (topology "
       << fmt("%.2f", st.secondsTopology) << (vector ? ", vectors " : ", sweeps ") << fmt("%.2f", st.secondsSweep)
       << "), " << fmt("%.2f", secondsSince(t0))
       << " s total\n";
    if (!vector && !st.converged) {
        args.err() << "levelforge: warning: the sweeps did not converge to " << opt.tolerance
                   << " voxels in " << opt.maxIterations << " passes per leaf\n";
    }
}

} // namespace

LEVELFORGE_REGISTER_OPERATOR(
    OperatorSpec("expand",
                 "Widen the band of a level set by fast sweeping or vector propagation (like VDB "
                 "Activate SDF / VDB Reshape SDF dilate)")
        .description(
            "Reads a .vdb level set, keeps its band as the exact boundary condition, activates\n"
            "every voxel whose distance is within the new widths (Euclidean-complete), gives\n"
            "the new voxels their sign, and solves |grad phi| = 1 on them by fast sweeping\n"
            "(Zhao 2005; first-order Godunov, 8 orderings, sparse VDB topology only) or, with\n"
            "--method vector, propagates closest-point vectors by the 8-pass VCVDT\n"
            "(Satherley-Jones 2001) over the same sparse topology. Other grids of the file are\n"
            "copied unchanged. Values of new voxels approximate the distance (see\n"
            "docs/expansion.md).")
        .input("input", ".vdb file with a level set")
        .output("output", ".vdb file to write")
        .param(Param::floating("exterior-width", "Exterior Band",
                               "Half-width of the band outside the surface, in voxels "
                               "(world units with --world-units)")
                   .defaultValue(20.0)
                   .range(0.0, 100000.0, Bound::Exclusive, Bound::Inclusive))
        .param(Param::floating("interior-width", "Interior Band",
                               "Half-width of the band inside the surface, in voxels "
                               "(world units with --world-units)")
                   .defaultValue(20.0)
                   .range(0.0, 100000.0, Bound::Exclusive, Bound::Inclusive)
                   .exclusiveWith("fill-interior"))
        .param(Param::flag("world-units", "Use World Space Units",
                           "Read the widths and the bounding-box margin in world units"))
        .param(Param::flag("fill-interior", "Fill Interior",
                           "Activate every voxel inside the surface")
                   .exclusiveWith("interior-width"))
        .param(Param::choice("domain", "Domain",
                             "band: the widths around the surface; bbox: every voxel of the "
                             "input's bounding box grown by --bbox-margin",
                             {"band", "bbox"})
                   .defaultValue("band"))
        .param(Param::floating("bbox-margin", "Bounding Box Margin",
                               "Margin around the bounding box for --domain bbox, in voxels")
                   .defaultValue(10.0)
                   .range(0.0, 100000.0))
        .param(Param::choice("method", "Method",
                             "Expansion method: sweep = fast sweeping (Zhao, first-order); vector = "
                             "closest-point vectors by the 8-pass VCVDT (Satherley-Jones), shell "
                             "vectors estimated from phi and grad phi",
                             {"sweep", "vector"})
                   .defaultValue("sweep"))
        .param(Param::floating("tolerance", "Tolerance",
                               "Changes of at most this (voxels) are not passed on to the "
                               "neighbours; the sweeps stop when no larger change is pending")
                   .defaultValue(1e-4)
                   .range(0.0, 1.0, Bound::Exclusive, Bound::Inclusive))
        .param(Param::integer("max-iterations", "Max Iterations",
                              "Sweep each leaf node (until it has no dirty voxel) at most this "
                              "many times")
                   .defaultValue(50)
                   .range(1, 10000))
        .param(Param::string("grid-name", "Grid Name",
                             "Level set to expand (default: the first float level set)"))
        .param(Param::flag("quiet", "Quiet", "Print no progress on stderr"))
        .example("levelforge expand bunny.vdb bunny_wide.vdb --exterior-width 20 "
                 "--interior-width 20")
        .example("levelforge expand bunny.vdb bunny_solid.vdb --exterior-width 5 --fill-interior")
        .example("levelforge expand bunny.vdb bunny_wide.vdb --exterior-width 60 --method vector")
        .cook(cookExpand));

} // namespace levelforge::ops
