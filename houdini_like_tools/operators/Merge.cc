// SPDX-License-Identifier: Apache-2.0
// levelforge operator `merge`: the per-rank pieces of `mesh-to-sdf --distributed
// --distributed-output per-rank` (a manifest and one .vdb per rank) → the one finished .vdb, equal
// to the single-process conversion bit for bit (distributed/DistributedMeshToSdf.h,
// mergeBrickPieces()). Needs no MPI.
#include "Interrupt.h"
#include "Operator.h"
#include "OperatorIO.h"
#include "OperatorText.h"

#include <levelforge/distributed/DistributedMeshToSdf.h>
#include <levelforge/io/VdbIO.h>

#include <openvdb/openvdb.h>

#include <chrono>
#include <ostream>
#include <string>

namespace levelforge::ops {
namespace {

void cookMerge(OperatorArgs& args)
{
    const auto t0 = std::chrono::steady_clock::now();
    const std::string& manifest = args.input("manifest");
    const std::string& output = args.output("output");
    if (isMemoryName(manifest))
        throw UsageError("merge reads a manifest file (OUTPUT.manifest.json), not the in-memory slot " + manifest);
    checkOutputTarget(args, output); // before any piece is read
    CliProgress progress(10, !args.getBool("quiet"));
    MergeOptions options;
    options.interrupter = &progress;
    MergeStats stats;
    progress.start("merge");
    const openvdb::FloatGrid::Ptr grid = mergeBrickPieces(manifest, options, &stats);
    progress.end();
    openvdb::MetaMap fileMeta;
    fileMeta.insertMeta("creator", openvdb::StringMetadata(generatorString()));
    writeGridsOutput(args, output, {grid}, fileMeta);
    const double seconds = secondsSince(t0);
    args.stat("pieces", int64_t(stats.pieces));
    args.stat("leaves", stats.leaves);
    args.stat("active_voxels", uint64_t(grid->activeVoxelCount()));
    args.stat("filled_voxels", stats.filledVoxels);
    args.stat("read_seconds", stats.secondsRead);
    args.stat("finish_seconds", stats.secondsFinish);
    args.stat("total_seconds", seconds);
    std::ostream& out = args.out();
    out << "levelforge: wrote " << output << "\n"
        << "  grid '" << grid->getName() << "': voxel size " << fmt("%.6g", grid->voxelSize()[0]) << " (world units), "
        << withThousands(grid->activeVoxelCount()) << " active voxels\n"
        << "  merged: " << stats.pieces << (stats.pieces == 1 ? " piece, " : " pieces, ") << withThousands(stats.leaves)
        << " leaves, " << fmt("%.1f", double(stats.bytesRead) / 1048576.0) << " MiB read\n"
        << "  time: read " << fmt("%.2f", stats.secondsRead) << " s, finish " << fmt("%.2f", stats.secondsFinish)
        << " s, " << fmt("%.2f", seconds) << " s total\n";
    if (args.getBool("report") && stats.filledVoxels)
        out << "  fill interior: " << withThousands(stats.filledVoxels) << " voxels activated (tiles by volume)\n";
}

} // namespace

LEVELFORGE_REGISTER_OPERATOR(
    OperatorSpec("merge", "Merge the per-rank pieces of a distributed conversion into one .vdb")
        .description(
            "Reads the manifest that 'mesh-to-sdf --distributed --distributed-output per-rank'\n"
            "wrote (OUTPUT.manifest.json) and its pieces (one .vdb per rank, unfinished), one at a\n"
            "time, each checked against the manifest (its run, rank, transform, background, sign,\n"
            "leaf and voxel counts, bricks); moves their leaves into one tree and finishes it as\n"
            "the gathering run does (signed flood fill, --fill-interior, the same metadata). The\n"
            "result equals the single-process mesh-to-sdf output bit for bit. Needs no MPI; the\n"
            "pieces are found next to the manifest. Written atomically: on failure no output.")
        .input("manifest", "Manifest of the pieces (OUTPUT.manifest.json)")
        .output("output", ".vdb file to write")
        .param(Param::flag("quiet", "Quiet", "Print no progress on stderr"))
        .param(Param::flag("report", "Report", "Print the interior fill's count too"))
        .example("mpirun -n 4 levelforge mesh-to-sdf statue.obj statue.vdb --voxel-count 4096 --distributed "
                 "--distributed-output per-rank")
        .example("levelforge merge statue.vdb.manifest.json statue.vdb")
        .cook(cookMerge));

} // namespace levelforge::ops
