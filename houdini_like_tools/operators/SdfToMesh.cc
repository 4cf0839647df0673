// SPDX-License-Identifier: Apache-2.0
// levelforge operator `sdf-to-mesh`: the isosurface of a level set or fog volume as a triangle
// mesh. Houdini: *Convert VDB* to polygons (Isovalue, Adaptivity); vdb_tool: -ls2mesh; OpenVDB:
// tools::volumeToMesh.
#include "Interrupt.h"
#include "Operator.h"
#include "OperatorIO.h"
#include "OperatorText.h"

#include <levelforge/core/Exceptions.h>
#include <levelforge/levelset/LevelSetToMesh.h>

#include <openvdb/openvdb.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <ostream>
#include <string>

namespace levelforge::ops {
namespace {

/// The grid to mesh: the float grid named @p name, else the first float level set, else the
/// first float fog volume.
openvdb::FloatGrid::Ptr pickSurfaceGrid(const openvdb::GridPtrVec& grids, const std::string& path,
                                        const std::string& name)
{
    if (!name.empty()) {
        for (const auto& g : grids)
            if (auto f = openvdb::gridPtrCast<openvdb::FloatGrid>(g); f && f->getName() == name) return f;
        throw InvalidArgumentError(path + ": no float grid named '" + name + "'");
    }
    for (const openvdb::GridClass cls : {openvdb::GRID_LEVEL_SET, openvdb::GRID_FOG_VOLUME})
        for (const auto& g : grids)
            if (auto f = openvdb::gridPtrCast<openvdb::FloatGrid>(g); f && f->getGridClass() == cls) return f;
    throw InvalidArgumentError(path + ": no float level set or fog volume (grid class GRID_LEVEL_SET or "
                                      "GRID_FOG_VOLUME) found; name another float grid with --grid-name");
}

/// Refuses, before any work, an output file whose extension writeMesh() does not write.
void checkMeshExtension(const std::string& path)
{
    if (isMemoryName(path)) return;
    const size_t dot = path.find_last_of('.');
    const size_t slash = path.find_last_of('/');
    std::string ext = (dot == std::string::npos || (slash != std::string::npos && dot < slash)) ? "" : path.substr(dot);
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
    if (ext != ".obj" && ext != ".ply" && ext != ".stl" && ext != ".off") {
        throw UsageError("cannot write mesh file '" + path + "': unknown extension '" + ext +
                         "' (sdf-to-mesh writes .obj, .ply, .stl or .off)");
    }
}

void cookSdfToMesh(OperatorArgs& args)
{
    const auto t0 = std::chrono::steady_clock::now();
    const std::string& input = args.input("input");
    const std::string& output = args.output("output");
    checkMeshExtension(output);
    checkOutputTarget(args, output);

    const openvdb::GridPtrVecPtr grids = readGridsInput(args, input);
    const openvdb::FloatGrid::Ptr grid =
        pickSurfaceGrid(*grids, input, args.has("grid-name") ? args.getString("grid-name") : "");
    const bool fog = grid->getGridClass() != openvdb::GRID_LEVEL_SET;
    LevelSetToMeshOptions opt;
    opt.isovalue = args.has("iso") ? args.getFloat("iso") : (fog ? 0.5 : 0.0);
    opt.adaptivity = args.getFloat("adaptivity");
    CliProgress progress(10, !args.getBool("quiet"));
    opt.interrupter = &progress;

    const auto t1 = std::chrono::steady_clock::now();
    LevelSetToMeshStats stats;
    const TriangleMesh mesh = levelSetToMesh(*grid, opt, &stats);
    const double seconds = secondsSince(t1);
    if (mesh.empty()) {
        throw InvalidArgumentError(input + ": grid '" + grid->getName() + "' has no surface at isovalue " +
                                   fmt("%g", opt.isovalue) + " (" + withThousands(grid->activeVoxelCount()) +
                                   " active voxels); nothing written");
    }
    writeMeshOutput(args, mesh, output);

    const double h = grid->voxelSize()[0];
    args.stat("vertices", uint64_t(mesh.vertexCount()));
    args.stat("triangles", uint64_t(mesh.triangleCount()));
    args.stat("quads", stats.quads);
    args.stat("isovalue", opt.isovalue);
    args.stat("adaptivity", opt.adaptivity);
    args.stat("active_voxels", uint64_t(grid->activeVoxelCount()));
    args.stat("mesh_seconds", seconds);
    args.stat("seconds", secondsSince(t0));
    args.out() << "levelforge: wrote " << output << "\n"
               << "  grid '" << grid->getName() << "' (" << (fog ? "fog volume" : "level set") << ", voxel size "
               << fmt("%g", h) << ", " << withThousands(grid->activeVoxelCount()) << " active voxels): isovalue "
               << fmt("%g", opt.isovalue) << (fog ? "" : " world units") << " (" << fmt("%g", opt.isovalue / h)
               << " voxels), adaptivity " << fmt("%g", opt.adaptivity) << "\n"
               << "  mesh: " << withThousands(mesh.vertexCount()) << " vertices, "
               << withThousands(mesh.triangleCount()) << " triangles (" << withThousands(stats.quads)
               << " quads split, " << withThousands(stats.openvdbTriangles) << " triangles from OpenVDB)\n"
               << "  time: " << fmt("%.2f", seconds) << " s meshing, " << fmt("%.2f", secondsSince(t0))
               << " s total\n";
}

} // namespace

LEVELFORGE_REGISTER_OPERATOR(
    OperatorSpec("sdf-to-mesh", "Polygonize a level set or fog volume into a triangle mesh (like Convert VDB)")
        .description(
            "Reads a .vdb file and writes the isosurface of a float grid as a triangle mesh\n"
            "(.obj, .ply, .stl or .off, by the extension). OpenVDB's volumeToMesh (dual\n"
            "contouring of the sparse tree; adaptivity merges nearly flat regions into larger\n"
            "polygons); quads are split along their 0-2 diagonal and every triangle is wound\n"
            "counter-clockwise seen from outside, so mesh-to-sdf of the result is negative\n"
            "inside. The grid: --grid-name, else the first float level set, else the first float\n"
            "fog volume. Vertices are within a few hundredths of a voxel of the surface of an\n"
            "exact SDF at adaptivity 0 (see docs/meshing-and-slices.md). Written atomically: on\n"
            "failure no output file appears.")
        .input("input", ".vdb file with a level set or fog volume")
        .output("output", "mesh file to write: .obj, .ply, .stl or .off")
        .param(Param::floating("iso", "Isovalue",
                               "The surface to extract, in the grid's value units: world units for a level set "
                               "(default 0), density for a fog volume (default 0.5)"))
        .param(Param::floating("adaptivity", "Adaptivity",
                               "0: one polygon per crossed voxel; up to 1: fewer, larger polygons where the "
                               "surface is flat (unitless)")
                   .defaultValue(0.0)
                   .range(0.0, 1.0))
        .param(Param::string("grid-name", "Grid Name",
                             "Float grid to mesh (default: the first float level set, else the first fog volume)"))
        .param(Param::flag("quiet", "Quiet", "Print no progress on stderr"))
        .example("levelforge sdf-to-mesh bunny.vdb bunny.obj")
        .example("levelforge sdf-to-mesh bunny.vdb bunny_low.ply --adaptivity 0.5 --iso 0.01")
        .example("levelforge sdf-to-mesh smoke.vdb smoke.obj --grid-name density --iso 0.5")
        .cook(cookSdfToMesh));

} // namespace levelforge::ops
