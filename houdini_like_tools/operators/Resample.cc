// SPDX-License-Identifier: Apache-2.0
// levelforge operator `resample`: the grids of a .vdb file onto another voxel size or onto the
// transform of a reference grid. Houdini: *VDB Resample*; vdb_tool: -resample; OpenVDB:
// tools::resampleToMatch (level sets: rebuilt exactly, levelset/RebuildLevelSet.h).
#include "Interrupt.h"
#include "Operator.h"
#include "OperatorIO.h"
#include "OperatorText.h"

#include <levelforge/core/Exceptions.h>
#include <levelforge/io/VdbIO.h>
#include <levelforge/levelset/ResampleGrid.h>

#include <openvdb/openvdb.h>

#include <chrono>
#include <ostream>
#include <string>
#include <vector>

namespace levelforge::ops {
namespace {

/// The transform of the grid @p name (empty: the first grid) of the reference @p path.
openvdb::math::Transform::Ptr referenceTransform(const OperatorArgs& args, const std::string& path,
                                                 const std::string& name)
{
    const openvdb::GridPtrVecPtr grids = readGridsInput(args, path);
    for (const auto& g : *grids)
        if (g && (name.empty() || g->getName() == name)) return g->transform().copy();
    if (!name.empty()) throw InvalidArgumentError("reference " + path + ": no grid named '" + name + "'");
    throw InvalidArgumentError("reference " + path + ": the file holds no grids, so there is no transform to match");
}

void cookResample(OperatorArgs& args)
{
    using Clock = std::chrono::steady_clock;
    const auto t0 = Clock::now();
    const std::string& input = args.input("input");
    const std::string& output = args.output("output");
    checkOutputTarget(args, output);
    if (!args.has("voxel-size") && !args.has("reference"))
        throw UsageError("resample: give the target: --voxel-size or --reference");
    ResampleGridOptions opt;
    opt.order = resampleOrderFromString(args.getString("order"));
    opt.levelSets = args.getString("level-sets") == "interpolate" ? LevelSetResample::Interpolate : LevelSetResample::Rebuild;

    openvdb::math::Transform::Ptr reference;
    if (args.has("reference"))
        reference = referenceTransform(args, args.getString("reference"),
                                       args.has("reference-grid") ? args.getString("reference-grid") : "");
    openvdb::GridPtrVecPtr grids = readGridsInput(args, input);
    const std::string only = args.has("grid-name") ? args.getString("grid-name") : "";
    std::vector<bool> selected(grids->size(), false);
    size_t count = 0;
    for (size_t i = 0; i < grids->size(); ++i) {
        const auto& g = (*grids)[i];
        if (!g || (!only.empty() && g->getName() != only)) continue;
        if (!only.empty() && !isResamplable(*g))
            throw InvalidArgumentError(input + ": grid '" + only + "' is of type " + g->valueType() +
                                       "; only float, double, vec3s and vec3d grids can be resampled");
        selected[i] = isResamplable(*g);
        count += selected[i] ? 1 : 0;
    }
    if (!only.empty() && count == 0) throw InvalidArgumentError(input + ": no grid named '" + only + "'");
    if (count == 0) throw InvalidArgumentError(input + ": no float, double, vec3s or vec3d grid to resample");

    CliProgress progress(10, !args.getBool("quiet"));
    opt.interrupter = &progress;
    openvdb::GridPtrVec result;
    std::vector<std::string> lines;
    uint64_t voxelsBefore = 0, voxelsAfter = 0;
    double outVoxel = 0.0;
    const auto t1 = Clock::now();
    for (size_t i = 0; i < grids->size(); ++i) {
        const openvdb::GridBase::Ptr& g = (*grids)[i];
        if (!selected[i]) {
            result.push_back(g);
            if (g && only.empty())
                lines.push_back("grid '" + g->getName() + "' (" + g->valueType() + "): written unchanged (not resampled)");
            continue;
        }
        const openvdb::math::Transform::Ptr target =
            reference ? reference : transformWithVoxelSize(g->transform(), args.getFloat("voxel-size"));
        std::string how;
        openvdb::GridBase::Ptr out = resampleGrid(*g, *target, opt, &how);
        voxelsBefore += g->activeVoxelCount();
        voxelsAfter += out->activeVoxelCount();
        outVoxel = out->voxelSize()[0];
        lines.push_back("grid '" + out->getName() + "': " + how + ", voxel size " + fmt("%g", g->voxelSize()[0]) + " -> " +
                        fmt("%g", outVoxel) + ", " + withThousands(g->activeVoxelCount()) + " -> " +
                        withThousands(out->activeVoxelCount()) + " active voxels");
        result.push_back(out);
    }
    const double seconds = secondsSince(t1);
    openvdb::MetaMap fileMeta;
    fileMeta.insertMeta("creator", openvdb::StringMetadata(generatorString()));
    writeGridsOutput(args, output, result, fileMeta);

    args.stat("grids_resampled", uint64_t(count));
    args.stat("voxel_size", outVoxel);
    args.stat("active_voxels_before", voxelsBefore);
    args.stat("active_voxels", voxelsAfter);
    args.stat("resample_seconds", seconds);
    args.stat("seconds", secondsSince(t0));
    std::ostream& os = args.out();
    os << "levelforge: wrote " << output << "\n";
    for (const std::string& l : lines) os << "  " << l << "\n";
    os << "  time: " << fmt("%.2f", seconds) << " s resample, " << fmt("%.2f", secondsSince(t0)) << " s total\n";
}

} // namespace

LEVELFORGE_REGISTER_OPERATOR(
    OperatorSpec("resample", "Resample grids to another voxel size or a reference transform (like VDB Resample)")
        .description(
            "Reads a .vdb file and resamples its float, double, vec3s and vec3d grids (all of them,\n"
            "as Houdini does, or only --grid-name) onto a new transform: the grid's own transform\n"
            "with voxel size --voxel-size (rotation and the position of voxel 0 kept), or the\n"
            "transform of a grid of --reference. Level sets are rebuilt (the zero iso-surface,\n"
            "then exact distances on the new transform; band width kept in voxels), like Houdini's\n"
            "\"Rebuild SDF\"; other grids are interpolated by OpenVDB's resampleToMatch at --order.\n"
            "Grids of other types are written unchanged. Written atomically: on failure no output\n"
            "file appears.")
        .input("input", ".vdb file with the grids to resample")
        .output("output", ".vdb file to write")
        .param(Param::floating("voxel-size", "Voxel Size", "New voxel edge length, in world units")
                   .range(0.0, 1e6, Bound::Exclusive, Bound::Inclusive)
                   .exclusiveWith("reference"))
        .param(Param::string("reference", "Reference VDB", ".vdb file whose grid's transform the output matches"))
        .param(Param::string("reference-grid", "Reference Grid",
                             "Grid of --reference whose transform is matched (default: its first grid)"))
        .param(Param::choice("order", "Interpolation",
                             "point: nearest voxel; linear: trilinear; quadratic: triquadratic (not used for "
                             "rebuilt level sets)",
                             {"point", "linear", "quadratic"})
                   .defaultValue("linear"))
        .param(Param::choice("level-sets", "Level Sets",
                             "rebuild: exact band on the new transform (Houdini's Rebuild SDF); interpolate: "
                             "like any other grid",
                             {"rebuild", "interpolate"})
                   .defaultValue("rebuild"))
        .param(Param::string("grid-name", "Grid Name", "Resample only this grid (default: every grid it can)"))
        .param(Param::flag("quiet", "Quiet", "Print no progress on stderr"))
        .example("levelforge resample bunny.vdb bunny_coarse.vdb --voxel-size 0.02")
        .example("levelforge resample smoke.vdb smoke_aligned.vdb --reference bunny.vdb --order quadratic")
        .cook(cookResample));

} // namespace levelforge::ops
