// SPDX-License-Identifier: Apache-2.0
// levelforge operator `mesh-to-sdf`: triangle mesh → signed distance .vdb, through the library's
// pipeline (pipeline/MeshToSdf.h). Houdini: *VDB from Polygons* (distance VDB); vdb_tool: mesh2ls.
#include "GridParams.h"
#include "Interrupt.h"
#include "Operator.h"
#include "OperatorIO.h"
#include "OperatorText.h"

#include <levelforge/core/Exceptions.h>
#include <levelforge/core/MeshValidation.h>
#include <levelforge/distributed/DistributedMeshToSdf.h>
#include <levelforge/io/MeshIO.h>
#include <levelforge/io/VdbIO.h>
#include <levelforge/pipeline/MeshToSdf.h>
#include <levelforge/reference/MeshShapes.h>

#include <openvdb/openvdb.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <iostream>
#include <ostream>
#include <string>

#include <unistd.h>

namespace levelforge::ops {
namespace {


/// --voxel-size / --voxel-count, --exterior-band / --interior-band (voxels or --world-units),
/// --grid-name.
GridParamSet meshGridParams()
{
    GridParamSet g;
    g.worldUnits = true;
    return g;
}

void printStats(std::ostream& os, const MeshToLevelSetStats& s)
{
    os << "statistics:\n"
       << "  triangles used:          " << withThousands(s.triangles) << " ("
       << withThousands(s.skippedDegenerate) << " degenerate skipped)\n"
       << "  hierarchy:               " << withThousands(s.hierarchyNodes) << " nodes, "
       << withThousands(s.clusters) << " clusters of <= 8 triangles\n"
       << "  candidate leaves:        " << withThousands(s.candidateLeaves) << " ("
       << withThousands(s.leafPasses) << " in one pass over their nearby triangles)\n"
       << "  candidate voxels:        " << withThousands(s.candidateVoxels) << "\n"
       << "  active voxels:           " << withThousands(s.activeVoxels) << "\n"
       << "  distance evaluations:    " << withThousands(s.distanceEvaluations) << " ("
       << fmt("%.2f", s.evaluationsPerActiveVoxel()) << " per active voxel)\n"
       << "  bound tests:             " << withThousands(s.boundTests) << " triangles, "
       << withThousands(s.nodeTests) << " boxes\n"
       << "  seconds: hierarchy " << fmt("%.3f", s.secondsHierarchy) << ", candidates "
       << fmt("%.3f", s.secondsCandidates) << ", distance " << fmt("%.3f", s.secondsDistance)
       << ", finish " << fmt("%.3f", s.secondsFinish) << "\n"
       << "  device:                  " << s.device << (s.deviceNote.empty() ? "" : " (" + s.deviceNote + ")") << "\n";
    if (s.deviceBatches)
        os << "  device work:             " << withThousands(s.deviceBatches) << " batches, "
           << withThousands(s.devicePairs) << " voxel-triangle pairs; up " << fmt("%.1f", double(s.deviceBytesUp) / 1048576.0)
           << " MiB, down " << fmt("%.1f", double(s.deviceBytesDown) / 1048576.0) << " MiB, peak device memory "
           << fmt("%.1f", double(s.devicePeakBytes) / 1048576.0) << " MiB; seconds: waiting "
           << fmt("%.3f", s.secondsDeviceWait) << ", staging copies " << fmt("%.3f", s.secondsDeviceCopy) << "\n";
}

void printScanStats(std::ostream& os, const TetScanStats& s)
{
    os << "statistics (scan conversion, shell " << toString(s.shell) << ", coverage " << toString(s.coverage)
       << (s.shell != ShellMethod::Obb && s.coverage == ShellCoverage::Complete ? " (eps-prism)" : "") << "):\n"
       << "  triangles used:          " << withThousands(s.triangles) << " ("
       << withThousands(s.skippedDegenerate) << " degenerate skipped)\n"
       << "  tetrahedra:              " << withThousands(s.tetrahedra) << " ("
       << fmt("%.2f", s.tetrahedraPerFace()) << " per face)\n"
       << "  cross-sections:          " << withThousands(s.crossSections) << "\n"
       << "  slabs / slab items:      " << withThousands(s.slabs) << " / " << withThousands(s.slabItems) << "\n"
       << "  voxels rasterized:       " << withThousands(s.voxelsRasterized) << " ("
       << fmt("%.2f", s.overlapFactor()) << " per active voxel)\n"
       << "  active voxels:           " << withThousands(s.activeVoxels) << "\n"
       << "  slab device:             " << s.device << (s.deviceNote.empty() ? "" : " (" + s.deviceNote + ")") << "\n"
       << "  seconds: shell " << fmt("%.3f", s.secondsShell) << ", sort " << fmt("%.3f", s.secondsSort)
       << ", sweep " << fmt("%.3f", s.secondsSweep) << ", fill " << fmt("%.3f", s.secondsFill)
       << ", finish " << fmt("%.3f", s.secondsFinish) << "\n";
}

/// The statistics both distributed outputs record; `stepKey` names the gather or the pieces'
/// write. Returns the slowest rank's seconds (for the summary line).
double recordDistributedStats(OperatorArgs& args, const TriangleMesh& mesh, const DistributedStats& ds,
                              const char* stepKey, double totalSeconds)
{
    double maxPeak = 0.0, maxSeconds = 0.0;
    for (int r = 0; r < ds.ranks; ++r) {
        maxPeak = std::max(maxPeak, ds.rankPeakMiB[size_t(r)]);
        maxSeconds = std::max(maxSeconds, ds.rankSeconds[size_t(r)]);
    }
    args.stat("exterior_band_voxels", double(ds.sdf.exteriorBandVoxels));
    args.stat("interior_band_voxels", double(ds.sdf.interiorBandVoxels));
    args.stat("triangles", uint64_t(mesh.triangleCount()));
    args.stat("sign", std::string(toString(ds.sdf.sign)));
    args.stat("ranks", int64_t(ds.ranks));
    args.stat("bricks", uint64_t(ds.bricks));
    args.stat("convert_seconds", ds.seconds);
    args.stat(stepKey, ds.secondsGather);
    args.stat("max_rank_seconds", maxSeconds);
    args.stat("max_rank_peak_mib", maxPeak);
    args.stat("total_seconds", totalSeconds);
    return maxSeconds;
}

/// `--report` of a distributed conversion: one line per rank (with its piece's size when the
/// ranks wrote pieces).
void printRankTable(std::ostream& out, const DistributedStats& ds, bool pieces)
{
    out << "  ranks: rank, bricks, estimated band voxels, triangles, active voxels, seconds, peak MiB (computed, "
           "end)"
        << (pieces ? ", piece MiB" : "") << "\n";
    for (int r = 0; r < ds.ranks; ++r) {
        out << "    " << r << ": " << withThousands(ds.rankBricks[size_t(r)]) << ", "
            << withThousands(uint64_t(ds.rankEstimate[size_t(r)])) << ", "
            << withThousands(ds.rankTriangles[size_t(r)]) << ", " << withThousands(ds.rankActiveVoxels[size_t(r)])
            << ", " << fmt("%.2f", ds.rankSeconds[size_t(r)]) << ", " << fmt("%.1f", ds.rankPartPeakMiB[size_t(r)])
            << ", " << fmt("%.1f", ds.rankPeakMiB[size_t(r)]);
        if (pieces) out << ", " << fmt("%.1f", double(ds.rankBytes[size_t(r)]) / 1048576.0);
        out << "\n";
    }
}

/// `--distributed --distributed-output per-rank`, on rank 0: what the ranks wrote.
void printPieces(OperatorArgs& args, const TriangleMesh& mesh, const MeshToSdfOptions& options,
                 const DistributedStats& ds, const std::string& output, const std::string& manifest, int64_t brick,
                 double totalSeconds)
{
    std::ostream& out = args.out();
    const int ranks = ds.ranks;
    double mib = 0.0;
    uint64_t active = 0;
    for (int r = 0; r < ranks; ++r) {
        mib += double(ds.rankBytes[size_t(r)]) / 1048576.0;
        active += ds.rankActiveVoxels[size_t(r)];
    }
    args.stat("voxel_size", ds.sdf.voxelSize);
    args.stat("band_active_voxels", active);
    const double maxSeconds = recordDistributedStats(args, mesh, ds, "write_seconds", totalSeconds);
    out << "levelforge: wrote " << manifest << " and " << ranks << (ranks == 1 ? " piece (" : " pieces (")
        << pieceFileName(output, 0) << (ranks > 1 ? " ... " + pieceFileName(output, ranks - 1) : std::string())
        << ", " << fmt("%.1f", mib) << " MiB); make " << output << " with: levelforge merge " << manifest << " "
        << output << "\n"
        << "  grid '" << options.gridName << "': voxel size " << fmt("%.6g", ds.sdf.voxelSize) << " (world units), "
        << withThousands(active) << " band voxels (unfinished: no flood fill" << (options.fillInterior ? ", no fill" : "")
        << ")\n"
        << "  band: " << fmt("%g", ds.sdf.exteriorBandVoxels) << " voxels outside, "
        << fmt("%g", ds.sdf.interiorBandVoxels) << " voxels inside\n"
        << "  mesh: " << withThousands(mesh.triangleCount()) << " triangles, " << withThousands(mesh.vertexCount())
        << " vertices\n"
        << "  sign: " << toString(ds.sdf.sign) << (options.fillInterior ? ", interior filled by the merge" : "") << "\n"
        << "  distributed: " << ranks << (ranks == 1 ? " rank, " : " ranks, ") << withThousands(ds.bricks)
        << " bricks of " << brick << "^3 voxels; one file per rank\n"
        << "  time: " << fmt("%.2f", ds.seconds) << " s conversion (bricks " << fmt("%.2f", ds.secondsDecompose)
        << " s, slowest rank " << fmt("%.2f", maxSeconds) << " s, writing " << fmt("%.2f", ds.secondsGather)
        << " s), " << fmt("%.2f", totalSeconds) << " s total\n";
    if (args.getBool("report")) printRankTable(out, ds, /*pieces=*/true);
}

/// `--distributed`: one conversion on every rank of `mpirun` (distributed/DistributedMeshToSdf.h).
/// Every rank reads the mesh and computes its bricks; rank 0 gathers, writes and prints. Each step
/// that can fail on one rank alone runs under runOnAllRanks(), so that every rank stops with the
/// same error; the other ranks print nothing (rank 0 prints the one error line).
void cookDistributed(OperatorArgs& args)
{
    using Clock = std::chrono::steady_clock;
    const auto t0 = Clock::now();
    // One conversion per mpirun: frames (cooked side by side with --jobs, in any order per rank)
    // would mix their collectives; MPI is called from the process's main thread only.
    if (args.frame())
        throw UsageError("--distributed converts one mesh per mpirun, not a --frames sequence (run mpirun once per "
                         "frame, or share the frames out with --task-index / --task-count)");
    if (gettid() != getpid())
        throw UsageError("--distributed runs on the process's main thread only (not in a parallel pipeline step)");
    const int rank = distributedRank(); // built without MPI: the error says how to get it
    const int ranks = distributedSize();
    const bool root = rank == 0;
    if (!root) {
        for (std::ostream* os : {&args.out(), &args.err(), static_cast<std::ostream*>(&std::cout),
                                 static_cast<std::ostream*>(&std::cerr)})
            os->setstate(std::ios::badbit);
    }
    const std::string& input = args.input("mesh");
    const std::string& output = args.output("output");
    const bool quiet = args.getBool("quiet");
    const bool report = args.getBool("report");
    std::ostream& out = args.out();
    std::ostream& err = args.err();
    const int64_t brick = args.getInt("brick-size");
    int brickLog2 = 3;
    while ((int64_t(1) << brickLog2) < brick) ++brickLog2;
    if ((int64_t(1) << brickLog2) != brick)
        throw UsageError("invalid value " + std::to_string(brick) + " for --brick-size: a power of two from 8 to 4096");
    const bool perRank = args.getString("distributed-output") == "per-rank";
    if (isMemoryName(output))
        throw UsageError("--distributed writes a .vdb file (rank 0 gathers the grid) or one per rank, not the in-memory "
                         "slot " + output);
    if (perRank && output == "/dev/null")
        throw UsageError("--distributed-output per-rank writes files next to the output: give a .vdb path, not /dev/null");
    if (args.isSet("reference"))
        throw UsageError("--distributed supports no --reference yet (docs/distributed.md)");

    runOnAllRanks([&] {
        if (perRank) {
            checkOutputTarget(args, pieceFileName(output, rank));
            if (root) checkOutputTarget(args, manifestFileName(output));
        } else if (root) {
            checkOutputTarget(args, output);
        }
    });
    TriangleMesh mesh;
    MeshReport validation;
    MeshToSdfOptions options;
    CliProgress progress(10, root && !quiet);
    runOnAllRanks([&] {
        MeshReadInfo info;
        mesh = readMeshInput(args, input, &info);
        if (info.droppedFaces > 0)
            err << "levelforge: warning: " << input << ": " << info.droppedFaces
                << " faces with fewer than three distinct corners were dropped\n";
        if (info.fanFallbacks > 0)
            err << "levelforge: warning: " << input << ": " << info.fanFallbacks
                << " polygons could not be ear-clipped and were fan-triangulated\n";
        validation = validateMesh(mesh);
        if (report) out << validation.summary() << "\n";
        for (const std::string& warning : validation.warnings()) err << "levelforge: warning: " << warning << "\n";
        readGridParams(args, options);
        if (args.isSet("fog-grid")) options.fogGridName = args.getString("fog-grid");
        if (args.isSet("primitive-index-grid")) options.primitiveIndexGridName = args.getString("primitive-index-grid");
        if (args.isSet("attribute")) options.attributes.push_back(args.getString("attribute"));
        options.sign = signModeFromString(args.getString("sign"));
        options.fillInterior = args.getBool("fill-interior");
        options.windingAccuracy = args.getFloat("winding-accuracy");
        options.device = parseComputeDevice(args.getString("device"));
        options.validation = &validation;
        options.method = bandMethodFromString(args.getString("method"));
        options.expansion = expansionFromString(args.getString("expansion"));
        options.exactBandVoxels = args.getFloat("exact-band");
        options.source = mesh.source.empty() ? input : mesh.source;
        options.interrupter = &progress; // drawn by rank 0 only; Ctrl-C stops every rank
        checkDistributable(mesh, options);
        if (!validation.closed() && options.sign == SignMode::Pseudonormal)
            err << "levelforge: warning: " << options.source
                << ": the mesh is not closed; inside/outside is the pseudonormal's verdict and may be "
                   "wrong away from the surface\n";
    });

    DistributedStats ds;
    if (perRank) {
        const std::string manifest = distributedMeshToSdfPieces(mesh, options, output, brickLog2, &ds);
        if (root) printPieces(args, mesh, options, ds, output, manifest, brick, secondsSince(t0));
        return;
    }
    const openvdb::FloatGrid::Ptr grid = distributedMeshToSdf(mesh, options, brickLog2, &ds);
    runOnAllRanks([&] {
        if (!root) return;
        openvdb::MetaMap fileMeta;
        fileMeta.insertMeta("creator", openvdb::StringMetadata(generatorString()));
        writeGridsOutput(args, output, {grid}, fileMeta);
    });
    if (!root) return;
    const double totalSeconds = secondsSince(t0);
    const double voxelSize = grid->voxelSize()[0];
    double gatheredMiB = 0.0;
    for (int r = 1; r < ranks; ++r) gatheredMiB += double(ds.rankBytes[size_t(r)]) / 1048576.0;
    args.stat("voxel_size", voxelSize);
    args.stat("active_voxels", uint64_t(grid->activeVoxelCount()));
    const double maxSeconds = recordDistributedStats(args, mesh, ds, "gather_seconds", totalSeconds);
    out << "levelforge: wrote " << output << "\n"
        << "  grid '" << grid->getName() << "': voxel size " << fmt("%.6g", voxelSize)
        << " (world units), " << withThousands(grid->activeVoxelCount()) << " active voxels\n"
        << "  band: " << fmt("%g", ds.sdf.exteriorBandVoxels) << " voxels outside, "
        << fmt("%g", ds.sdf.interiorBandVoxels) << " voxels inside\n"
        << "  mesh: " << withThousands(mesh.triangleCount()) << " triangles, "
        << withThousands(mesh.vertexCount()) << " vertices\n"
        << "  sign: " << toString(ds.sdf.sign) << " (" << ds.sdf.signReason << ")"
        << (options.fillInterior ? ", interior filled" : "") << "\n"
        << "  distributed: " << ranks << (ranks == 1 ? " rank, " : " ranks, ") << withThousands(ds.bricks)
        << " bricks of " << brick << "^3 voxels; gathered " << fmt("%.1f", gatheredMiB)
        << " MiB to rank 0\n"
        << "  time: " << fmt("%.2f", ds.seconds) << " s conversion (bricks " << fmt("%.2f", ds.secondsDecompose)
        << " s, slowest rank " << fmt("%.2f", maxSeconds)
        << " s, gather " << fmt("%.2f", ds.secondsGather) << " s, finish " << fmt("%.2f", ds.secondsFinish)
        << " s), " << fmt("%.2f", totalSeconds) << " s total\n";
    if (report) {
        printRankTable(out, ds, /*pieces=*/false);
        if (options.fillInterior)
            out << "  fill interior: " << withThousands(ds.sdf.filledVoxels) << " voxels activated (tiles by volume)\n";
    }
}

void cookMeshToSdf(OperatorArgs& args)
{
    if (args.isSet("distributed-output") && !args.getBool("distributed"))
        throw UsageError("--distributed-output is an option of --distributed (under mpirun)");
    if (args.getBool("distributed")) {
        cookDistributed(args);
        return;
    }
    using Clock = std::chrono::steady_clock;
    const auto t0 = Clock::now();
    const std::string& input = args.input("mesh");
    const std::string& output = args.output("output");
    const bool quiet = args.getBool("quiet");
    const bool report = args.getBool("report");
    std::ostream& out = args.out();
    std::ostream& err = args.err();

    // Fail fast, before any work, when the output cannot be written or the reference is bad.
    checkOutputTarget(args, output);
    ReferenceGrid reference;
    const bool haveReference = args.isSet("reference");
    if (haveReference) reference = readReferenceGrid(args.getString("reference"));

    // --attribute: the names, comma-separated ("Cd,N"); the reader keeps only those
    MeshReadOptions readOptions;
    if (args.isSet("attribute")) {
        const std::string& list = args.getString("attribute");
        size_t start = 0;
        while (start <= list.size()) {
            const size_t comma = std::min(list.find(',', start), list.size());
            std::string name = list.substr(start, comma - start);
            name.erase(0, name.find_first_not_of(" \t"));
            name.erase(name.find_last_not_of(" \t") + 1);
            if (name.empty())
                throw UsageError("invalid value '" + list + "' for --attribute: an empty attribute name");
            readOptions.attributes.push_back(name);
            start = comma + 1;
        }
    }
    MeshReadInfo info;
    TriangleMesh mesh;
    if (readOptions.attributes.empty()) {
        mesh = readMeshInput(args, input, &info);
    } else {
        mesh = readMeshInput(args, input, readOptions, info);
    }
    if (info.droppedFaces > 0) {
        err << "levelforge: warning: " << input << ": " << info.droppedFaces
            << " faces with fewer than three distinct corners were dropped\n";
    }
    if (info.fanFallbacks > 0) {
        err << "levelforge: warning: " << input << ": " << info.fanFallbacks
            << " polygons could not be ear-clipped and were fan-triangulated\n";
    }
    const MeshReport validation = validateMesh(mesh);
    if (report) out << validation.summary() << "\n";
    for (const std::string& warning : validation.warnings()) {
        err << "levelforge: warning: " << warning << "\n";
    }
    MeshToSdfOptions options;
    readGridParams(args, options);
    if (args.isSet("fog-grid")) options.fogGridName = args.getString("fog-grid");
    if (args.isSet("primitive-index-grid")) options.primitiveIndexGridName = args.getString("primitive-index-grid");
    options.attributes = readOptions.attributes; // a builtin mesh has none: the pipeline says so
    if (haveReference) {
        // the reference's transform, and its band widths unless given here
        options.transform = reference.transform;
        const double toUnits = options.units == WidthUnits::World ? reference.voxelSize : 1.0;
        if (!args.isSet("exterior-band") && reference.exteriorBandVoxels > 0.0)
            options.exteriorWidth = reference.exteriorBandVoxels * toUnits;
        if (!args.isSet("interior-band") && reference.interiorBandVoxels > 0.0)
            options.interiorWidth = reference.interiorBandVoxels * toUnits;
    }
    options.sign = signModeFromString(args.getString("sign"));
    options.fillInterior = args.getBool("fill-interior");
    options.windingAccuracy = args.getFloat("winding-accuracy");
    options.device = parseComputeDevice(args.getString("device"));
    options.validation = &validation;
    const bool pseudonormalOnOpen = !validation.closed() &&
        (options.sign == SignMode::Pseudonormal ||
         (options.sign == SignMode::Auto && args.getString("method") == "scan"));
    if (pseudonormalOnOpen) {
        err << "levelforge: warning: " << (mesh.source.empty() ? input : mesh.source)
            << ": the mesh is not closed; inside/outside is the pseudonormal's verdict and may be "
               "wrong away from the surface (--sign winding signs it by the winding number)\n";
    }
    options.method = bandMethodFromString(args.getString("method"));
    options.expansion = expansionFromString(args.getString("expansion"));
    options.exactBandVoxels = args.getFloat("exact-band");
    options.shell = shellMethodFromString(args.getString("shell"));
    options.coverage = shellCoverageFromString(args.getString("shell-coverage"));
    options.conservative = args.getBool("conservative");
    options.source = mesh.source.empty() ? input : mesh.source;
    CliProgress progress(10, !quiet);
    options.interrupter = &progress;

    MeshToSdfStats stats;
    const MeshToSdfGrids grids = meshToSdfGrids(mesh, options, &stats);
    const openvdb::FloatGrid::Ptr grid = grids.sdf;
    const double convertSeconds = stats.seconds;

    openvdb::MetaMap fileMeta;
    fileMeta.insertMeta("creator", openvdb::StringMetadata(generatorString()));
    writeGridsOutput(args, output, grids.all(), fileMeta); // every grid in one file, atomically
    const double totalSeconds = secondsSince(t0);

    const double voxelSize = grid->voxelSize()[0];
    args.stat("voxel_size", voxelSize);
    args.stat("active_voxels", uint64_t(grid->activeVoxelCount()));
    args.stat("exterior_band_voxels", double(stats.exteriorBandVoxels));
    args.stat("interior_band_voxels", double(stats.interiorBandVoxels));
    args.stat("triangles", uint64_t(mesh.triangleCount()));
    args.stat("sign", std::string(toString(stats.sign)));
    args.stat("convert_seconds", convertSeconds);
    args.stat("total_seconds", totalSeconds);
    out << "levelforge: wrote " << output << "\n"
        << "  grid '" << grid->getName() << "': voxel size " << fmt("%.6g", voxelSize)
        << " (world units), " << withThousands(grid->activeVoxelCount()) << " active voxels\n"
        << "  band: " << fmt("%g", stats.exteriorBandVoxels) << " voxels outside, "
        << fmt("%g", stats.interiorBandVoxels) << " voxels inside\n";
    if (haveReference)
        out << "  transform: from reference " << reference.path << " (grid '" << reference.name << "')\n";
    if (grids.fog)
        out << "  fog grid '" << grids.fog->getName() << "': " << withThousands(grids.fog->activeVoxelCount())
            << " active voxels (tiles by volume)\n";
    if (grids.primitiveIndex)
        out << "  primitive index grid '" << grids.primitiveIndex->getName() << "': "
            << withThousands(grids.primitiveIndex->activeVoxelCount()) << " active voxels\n";
    for (const openvdb::GridBase::Ptr& a : grids.attributes)
        out << "  attribute grid '" << a->getName() << "' (" << a->valueType() << "): "
            << withThousands(a->activeVoxelCount()) << " active voxels\n";
    out
        << "  mesh: " << withThousands(mesh.triangleCount()) << " triangles, "
        << withThousands(mesh.vertexCount()) << " vertices\n"
        << "  sign: " << toString(stats.sign) << " (" << stats.signReason << ")"
        << (options.fillInterior ? ", interior filled" : "") << "\n"
        << "  time: " << fmt("%.2f", convertSeconds) << " s conversion, "
        << fmt("%.2f", totalSeconds) << " s total\n";
    for (const std::string* note : {&stats.band.deviceNote, &stats.scan.deviceNote})
        if (!note->empty() && args.isSet("device")) err << "levelforge: warning: " << *note << "\n";
    if (report && options.method == BandMethod::Chang) printStats(out, stats.band);
    if (report && stats.sign == SignMode::Winding && options.method == BandMethod::Chang) {
        const MeshToLevelSetStats& b = stats.band;
        out << "  winding number: " << withThousands(b.windingEvaluations) << " evaluations for "
            << withThousands(b.windingGroups) << " groups of voxels and tiles ("
            << withThousands(b.windingIndividual) << " evaluated alone), " << withThousands(b.currentEdges)
            << " boundary-current edges, " << withThousands(b.insideTiles) << " inside tiles; build "
            << fmt("%.3f", b.secondsWinding) << " s\n";
    }
    if (report && options.fillInterior)
        out << "  fill interior: " << withThousands(stats.filledVoxels) << " voxels activated (tiles by volume)\n";
    if (report && options.method == BandMethod::Scan) printScanStats(out, stats.scan);
}

} // namespace

LEVELFORGE_REGISTER_OPERATOR(
    OperatorSpec("mesh-to-sdf",
                 "Convert a triangle mesh to an exact narrow-band signed distance level set "
                 "(like VDB from Polygons)")
        .description(
            "Reads a mesh (OBJ, PLY, STL, OFF, ... or builtin:torus-knot, builtin:sphere,\n"
            "builtin:box), checks it, computes the exact signed distance of every voxel in the\n"
            "band (Chang et al. 2008) and writes a level-set FloatGrid to a .vdb file (Blosc,\n"
            "written atomically: on failure no output file appears). The sign (--sign auto):\n"
            "angle-weighted pseudonormals for closed, consistently oriented meshes, the\n"
            "generalized winding number (|w| > 1/2 is inside; fast winding number, Barill et\n"
            "al. 2018) for open, broken or self-intersecting ones; --sign unsigned writes the\n"
            "unsigned distance (not a level set). Give --voxel-size or --voxel-count, not both.")
        .input("mesh", "Triangle mesh file, or builtin:torus-knot | builtin:sphere | builtin:box")
        .output("output", ".vdb file to write")
        .params(gridParams(meshGridParams()))
        .param(Param::choice("expansion", "Expansion",
                             "none/exact: exact distances in the whole band; sweep: exact in "
                             "--exact-band, then fast sweeping (first-order) to the full band; "
                             "vector: exact in --exact-band with its closest points, then the "
                             "8-pass VCVDT (Satherley-Jones) to the full band",
                             {"none", "sweep", "vector", "exact"})
                   .defaultValue("none"))
        .param(Param::floating("exact-band", "Exact Band Voxels",
                               "Half-width of the exact band computed before sweeping, in voxels")
                   .defaultValue(3.0)
                   .range(1.0, 1000.0))
        .param(Param::choice("method", "Method",
                             "chang: exact band (Chang et al. 2008); scan: T4 scan conversion of "
                             "tetrahedral shells (Erleben-Dohlmann), see --shell",
                             {"chang", "scan"})
                   .defaultValue("chang"))
        .param(Param::choice("shell", "Shell",
                             "Tetrahedral shell for --method scan (Erleben-Dohlmann 3.3-3.5): the "
                             "oriented box (obb), or the pseudonormal-family hulls (pseudonormal, thin, "
                             "offset), which --shell-coverage complete turns into the face's eps-prism",
                             {"pseudonormal", "thin", "offset", "obb"})
                   .defaultValue("obb"))
        .param(Param::choice("shell-coverage", "Shell Coverage",
                             "complete: every shell contains the band-width neighbourhood of its face, "
                             "so the band is exact with no missing voxel; paper: the paper's hulls as "
                             "built (pseudonormal, thin, offset then miss voxels near the band edge)",
                             {"complete", "paper"})
                   .defaultValue("complete"))
        .param(Param::flag("conservative", "Conservative Rasterization",
                           "--method scan: a voxel is covered when its cell, not only its centre, "
                           "meets a tetrahedron (more rasterized voxels; closes sub-voxel gaps of "
                           "paper shells)"))
        .param(Param::choice("sign", "Sign",
                             "auto: pseudonormal when the mesh is closed, consistently oriented and no part "
                             "is inside out (or with --method scan or --expansion sweep), winding "
                             "otherwise; pseudonormal: the angle-weighted pseudonormal of the closest "
                             "feature (exact for closed meshes); winding: inside where the generalized "
                             "winding number |w| > 1/2 (holes, cracks, interpenetrating or inverted parts; "
                             "Houdini's Preserve Holes; not with --method scan or --expansion sweep); "
                             "unsigned: the unsigned distance of any surface (grid class unknown, not a "
                             "level set; band = --exterior-band)",
                             {"auto", "pseudonormal", "winding", "unsigned"})
                   .defaultValue("auto"))
        .param(Param::choice("device", "Compute Device",
                             "Where --method chang's per-voxel search (and --method scan's dense slabs) runs: cpu; vulkan (a Vulkan device "
                             "with 64-bit floats, see 'levelforge devices'; an error when there is none); "
                             "auto: a discrete GPU when the band is large, else the CPU. The grids are "
                             "bit-identical on every device",
                             {"auto", "cpu", "vulkan"})
                   .defaultValue("auto"))
        .param(Param::flag("fill-interior", "Fill Interior",
                           "Every voxel inside the surface is active and negative: exact distances in "
                           "the band, -background deeper (active tiles where a whole tile is inside). "
                           "Not with --sign unsigned"))
        .param(Param::floating("winding-accuracy", "Winding Accuracy",
                               "--sign winding: the fast winding number's beta (clusters farther than "
                               "beta times their radius use their expansion; larger: more exact, slower)")
                   .defaultValue(2.0)
                   .range(1.0, 100.0, Bound::Exclusive))
        .param(Param::string("fog-grid", "Fog Grid",
                             "Also write a fog (density) grid of this name (Houdini's Build Fog): 1 inside "
                             "beyond the interior band, ramping linearly to 0 across it "
                             "(clamp(-distance / interior band width, 0, 1)), 0 and inactive outside. Not "
                             "with --sign unsigned"))
        .param(Param::string("reference", "Reference VDB",
                             "Take the transform (voxel size, offset, orientation) from the first float grid "
                             "of this .vdb file, so the grids line up voxel for voxel, and its band widths "
                             "(levelforge metadata, else background / voxel size of a level set) unless "
                             "--exterior-band / --interior-band are given. Its transform must be linear with "
                             "a uniform scale")
                   .exclusiveWith("voxel-size")
                   .exclusiveWith("voxel-count"))
        .param(Param::string("primitive-index-grid", "Primitive Index Grid",
                             "Also write an Int32 grid of this name holding, for every active voxel, the "
                             "0-based index of the closest input face (the polygon before triangulation, "
                             "in file order); background -1. Needs --method chang, --expansion none and no "
                             "--fill-interior"))
        .param(Param::string("attribute", "Attributes",
                             "Also write the mesh's per-vertex attributes (repeat the option, or comma-separate: Cd,N,uv), each "
                             "to a grid of the same name: a vector grid (vec3s) for Cd (colour: OBJ 'v x y z r "
                             "g b', PLY red/green/blue), N (normal: OBJ vn, PLY nx/ny/nz) and uv (OBJ vt, PLY "
                             "u/v or s/t; w = 0), a float grid for any other PLY vertex property by its name. "
                             "Each active voxel holds the barycentric interpolation of the corner values at "
                             "its exact closest point on the surface (OBJ vt/vn per face corner: seams are "
                             "kept). Needs --method chang, --expansion none and no --fill-interior")
                    .repeat())
        .param(Param::flag("distributed", "Distributed (MPI)",
                           "Run as one conversion on every rank of mpirun (mpirun -n 4 levelforge mesh-to-sdf "
                           "--distributed ...): the index space is cut into bricks of --brick-size voxels "
                           "balanced by estimated band voxels, each rank computes its bricks, rank 0 gathers "
                           "and writes one .vdb, bit-identical to the single-process output. Supports --method "
                           "chang, --expansion none and the pseudonormal or unsigned sign (auto on a closed "
                           "mesh), with or without --fill-interior (docs/distributed.md). Needs levelforge "
                           "built with MPI (libopenmpi-dev)"))
        .param(Param::choice("distributed-output", "Distributed Output",
                             "--distributed: gather: rank 0 gathers every rank's leaves and writes the one .vdb "
                             "(rank 0 holds the whole grid); per-rank: each rank writes its own leaves, unfinished, "
                             "to OUTPUT's name with .rankNNNN before the extension (out.rank0003.vdb), and rank 0 a "
                             "manifest, OUTPUT.manifest.json; 'levelforge merge OUTPUT.manifest.json OUTPUT' then "
                             "makes the same .vdb as gather (no rank holds more than its share)",
                             {"gather", "per-rank"})
                   .defaultValue("gather"))
        .param(Param::integer("brick-size", "Brick Size",
                              "--distributed: width of the bricks the index space is cut into, in voxels (a "
                              "power of two; 128 = the level-1 internal nodes of a float tree)")
                   .defaultValue(128)
                   .range(8, 4096))
        .param(Param::flag("quiet", "Quiet", "Print no progress on stderr"))
        .param(Param::flag("report", "Report",
                           "Print the mesh validation summary and conversion statistics"))
        .example("levelforge mesh-to-sdf bunny.obj bunny.vdb --voxel-size 0.01")
        .example("levelforge mesh-to-sdf builtin:torus-knot knot.vdb --voxel-count 200 "
                 "--exterior-band 5 --interior-band 5")
        .example("levelforge mesh-to-sdf bunny.obj bunny.vdb --exterior-band 60 --expansion sweep")
        .example("levelforge mesh-to-sdf bunny.obj bunny.vdb --exterior-band 60 --expansion vector")
        .example("levelforge mesh-to-sdf scan.obj scan.vdb --voxel-count 512 --sign winding --fill-interior")
        .example("levelforge mesh-to-sdf cloth.obj cloth_udf.vdb --voxel-size 0.01 --sign unsigned")
        .example("levelforge mesh-to-sdf bunny.obj bunny.vdb --voxel-size 0.01 --fog-grid density "
                 "--primitive-index-grid primitive")
        .example("levelforge mesh-to-sdf prop.obj prop.vdb --reference set.vdb")
        .example("levelforge mesh-to-sdf scan.ply scan.vdb --voxel-size 0.01 --attribute Cd,N")
        .example("mpirun -n 4 levelforge mesh-to-sdf statue.obj statue.vdb --voxel-count 4096 --distributed")
        .example("mpirun -n 4 levelforge mesh-to-sdf statue.obj statue.vdb --voxel-count 4096 --distributed "
                 "--distributed-output per-rank")
        .cook(cookMeshToSdf));

} // namespace levelforge::ops
