// SPDX-License-Identifier: Apache-2.0
// levelforge operator `mesh-to-adf`: triangle mesh → adaptively sampled distance field (.vdb).
// Yin, Liu, Wu 2011 on the VDB tile hierarchy (AdaptiveDistanceField.h).
#include "GridParams.h"
#include "Interrupt.h"
#include "Operator.h"
#include "OperatorIO.h"
#include "OperatorText.h"

#include <levelforge/adf/AdaptiveDistanceField.h>
#include <levelforge/core/Exceptions.h>
#include <levelforge/io/MeshIO.h>
#include <levelforge/reference/MeshShapes.h>
#include <levelforge/core/MeshValidation.h>
#include <levelforge/io/VdbIO.h>

#include <openvdb/openvdb.h>

#include <chrono>
#include <cstdio>
#include <ostream>
#include <string>

namespace levelforge::ops {
namespace {

/// The ADF covers a padded domain, not a band: no band widths; the finest voxel size.
GridParamSet adfGridParams()
{
    GridParamSet g;
    g.voxelSizeHelp = "Finest voxel edge length, in world units";
    g.voxelCountHelp = "Finest voxels along the longest axis of the mesh bounding box (the paper's "
                       "resolution); used when --voxel-size is not given";
    g.bands = false;
    g.gridName = "adf";
    g.maxVoxels = double(uint64_t(64) << 30); // the library's default for ADFs
    return g;
}

void cookMeshToAdf(OperatorArgs& args)
{
    const auto t0 = std::chrono::steady_clock::now();
    const std::string& input = args.input("mesh");
    const std::string& output = args.output("output");
    std::ostream& out = args.out();
    checkOutputTarget(args, output);
    const TriangleMesh mesh = readMeshInput(args, input);
    const MeshReport validation = validateMesh(mesh);
    if (!validation.closed())
        args.err() << "levelforge: warning: " << input
                   << ": the mesh is not closed; the ADF's sign is the pseudonormal's verdict and may be wrong\n";

    AdaptiveDistanceFieldOptions opt;
    readGridParams(args, opt);
    opt.toleranceVoxels = args.getFloat("tolerance");
    opt.paddingVoxels = args.getFloat("padding");
    opt.computeBounds = !args.getBool("no-bounds");
    opt.boundStride = int(args.getInt("bound-stride"));
    CliProgress progress(10, !args.getBool("quiet"));
    opt.interrupter = &progress;
    AdaptiveDistanceFieldStats s;
    const AdaptiveDistanceField adf = meshToAdaptiveDistanceField(mesh, opt, &s);
    auto grid = openvdb::ConstPtrCast<openvdb::FloatGrid>(adf.grid());
    openvdb::MetaMap fileMeta;
    fileMeta.insertMeta("creator", openvdb::StringMetadata(generatorString()));
    writeGridsOutput(args, output, openvdb::GridPtrVec{grid}, fileMeta);
    const double total = secondsSince(t0);

    args.stat("finest_voxel_size", double(s.voxelSize));
    args.stat("cells", uint64_t(grid->activeVoxelCount()));
    args.stat("total_seconds", total);
    out << "levelforge: wrote " << output << "\n"
        << "  ADF '" << grid->getName() << "': finest voxel " << fmt("%.6g", s.voxelSize) << " (world units), domain "
        << adf.indexDomain().min() << " -> " << adf.indexDomain().max() << "\n"
        << "  samples: type-1 " << s.type1 << ", type-2 " << s.type2 << ", type-3 " << s.type3 << ", constrained "
        << s.hanging << "; " << s.leaves << " leaves, " << s.level1Tiles << " level-1 tiles, " << s.level2Tiles
        << " level-2 tiles\n"
        << "  memory: " << fmt("%.2f", double(s.memoryBytes) / 1e6) << " MB (" << fmt("%.1f", 100.0 * double(s.memoryBytes) / (4.0 * double(s.domainVoxels)))
        << " % of a dense float grid of the domain)\n";
    if (opt.computeBounds) {
        out << "  stated error bound per level (voxels" << (opt.boundStride > 1 ? ", finest level on every " + std::to_string(opt.boundStride) + "th cell" : std::string()) << "):";
        for (int l = 0; l < kAdfLevels; ++l)
            if (s.levelBoundVoxels[size_t(l)] >= 0)
                out << " cell " << kAdfCellSize[l] << ": " << fmt("%.3f", s.levelBoundVoxels[size_t(l)]) << ";";
        out << "\n";
    }
    if (opt.toleranceVoxels > 0) out << "  refinement: " << s.refinedTiles << " tiles subdivided\n";
    out << "  time: " << fmt("%.2f", s.secondsTotal()) << " s conversion, " << fmt("%.2f", total) << " s total\n";
    if (args.getBool("report"))
        out << "  seconds: voxelize " << fmt("%.3f", s.secondsVoxelize) << ", octree " << fmt("%.3f", s.secondsOctree)
            << ", type-1 " << fmt("%.3f", s.secondsType1) << ", type-2 " << fmt("%.3f", s.secondsType2) << ", type-3 "
            << fmt("%.3f", s.secondsType3) << ", constrained " << fmt("%.3f", s.secondsFinish) << ", bounds "
            << fmt("%.3f", s.secondsBounds) << "\n";
}

} // namespace

LEVELFORGE_REGISTER_OPERATOR(
    OperatorSpec("mesh-to-adf", "Convert a triangle mesh to an adaptively sampled distance field (Yin et al. 2011)")
        .description(
            "Samples the signed distance of a mesh on the VDB tile hierarchy: exact samples at\n"
            "the corners of cells the surface crosses (type-1), approximate ones further out\n"
            "(type-2 in leaves, type-3 in 8^3 and 128^3 tiles), and writes one FloatGrid marked\n"
            "as an ADF (metadata levelforge:adf). Queries (levelforge sample) reconstruct a\n"
            "continuous field; `levelforge csg` combines ADFs. Give --voxel-size or --voxel-count.")
        .input("mesh", "Triangle mesh file, or builtin:torus-knot | builtin:sphere | builtin:box")
        .output("output", ".vdb file to write")
        .params(gridParams(adfGridParams()))
        .param(Param::floating("tolerance", "Tolerance",
                               "Refinement (Frisken): subdivide tiles whose reconstruction deviates more than "
                               "this at a test point, in voxels; 0 = the paper's fixed sampling")
                   .defaultValue(0.0)
                   .range(0.0, 1000.0))
        .param(Param::floating("padding", "Padding", "Margin of the domain around the mesh, in voxels (at least 9 is used)")
                   .defaultValue(8.0)
                   .range(0.0, 100000.0))
        .param(Param::flag("no-bounds", "No Bounds", "Skip computing the stated error bound per level (faster)"))
        .param(Param::integer("bound-stride", "Bound Stride",
                              "Check every N-th finest cell for the stated bound (1 = all: a proof for every "
                              "level; N > 1: the finest level's bound is measured on a subset)")
                   .defaultValue(8)
                   .range(1, 1000))
        .param(Param::flag("quiet", "Quiet", "Print no progress on stderr"))
        .param(Param::flag("report", "Report", "Print the time of every stage"))
        .example("levelforge mesh-to-adf bunny.obj bunny_adf.vdb --voxel-count 512")
        .example("levelforge mesh-to-adf builtin:sphere sphere_adf.vdb --voxel-size 0.02 --tolerance 0.5")
        .cook(cookMeshToAdf));

} // namespace levelforge::ops
