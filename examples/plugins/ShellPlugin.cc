// SPDX-License-Identifier: Apache-2.0
// An example plugin operator for the `levelforge` program: `shell` turns a solid level set into
// a hollow shell of a given thickness, centred on the surface: φ' = |φ| − t/2.
//
// Build: a MODULE library linked against levelforge (see the levelforge_shell_plugin target in
// houdini_like_tools/CMakeLists.txt); load it with
//     levelforge --plugin libshell.so shell solid.vdb hollow.vdb --thickness 2
// or put it in a directory listed in LEVELFORGE_OPERATOR_PATH.
//
// Exactness: where φ is the exact signed distance to the surface S and |φ| < the band, |φ| is the
// exact unsigned distance to S, and |φ| − t/2 is the exact signed distance to the shell's two
// offset surfaces wherever the closest point of the shell lies on the offset of the same surface
// point (away from the medial axis of S, i.e. where S's curvature radius exceeds t/2). The
// narrow band of the result is the input's band less t/2 on each side.
#include <OperatorPlugin.h>
#include <OperatorText.h>

#include <levelforge/core/Exceptions.h>
#include <levelforge/core/Metadata.h>
#include <levelforge/io/VdbIO.h>

#include <openvdb/openvdb.h>
#include <openvdb/tools/ValueTransformer.h>

#include <cmath>
#include <ostream>
#include <string>

namespace {

using namespace levelforge::ops;

void cookShell(OperatorArgs& args)
{
    const std::string& input = args.input("input");
    const std::string& output = args.output("output");
    checkOutputTarget(args, output);
    const openvdb::GridPtrVecPtr grids = readGridsInput(args, input);
    openvdb::FloatGrid::Ptr grid;
    for (const auto& g : *grids) {
        if (g->isType<openvdb::FloatGrid>() && g->getGridClass() == openvdb::GRID_LEVEL_SET) {
            grid = openvdb::gridPtrCast<openvdb::FloatGrid>(g);
            break;
        }
    }
    if (!grid) throw levelforge::InvalidArgumentError("'" + input + "' has no float level set");
    const double h = grid->voxelSize()[0];
    const double band = double(grid->background()) / h; // voxels
    const double half = 0.5 * (args.getBool("world-units") ? args.getFloat("thickness") / h : args.getFloat("thickness"));
    if (!(half < band - 1.0)) {
        throw levelforge::InvalidArgumentError("shell: a thickness of " + fmt("%g", 2 * half) +
                                               " voxels needs a band wider than " + fmt("%g", half + 1) +
                                               " voxels; '" + input + "' has " + fmt("%g", band));
    }
    const float halfWorld = float(half * h);
    openvdb::FloatGrid::Ptr out = grid->deepCopy();
    // every value, tiles included: far inside (-w) becomes outside the shell (w - t/2)
    openvdb::tools::foreach(out->beginValueAll(), [halfWorld](const openvdb::FloatGrid::ValueAllIter& it) {
        it.setValue(std::abs(*it) - halfWorld);
    });
    out->tree().root().setBackground(grid->background() - halfWorld, /*updateChildNodes=*/false);
    const float newBand = float(band - half);
    out->insertMeta(levelforge::meta::kExteriorBandVoxels, openvdb::FloatMetadata(newBand));
    out->insertMeta(levelforge::meta::kInteriorBandVoxels, openvdb::FloatMetadata(newBand));
    openvdb::MetaMap fileMeta;
    fileMeta.insertMeta("creator", openvdb::StringMetadata(levelforge::generatorString() + " shell plugin"));
    writeGridsOutput(args, output, openvdb::GridPtrVec{out}, fileMeta);
    args.stat("thickness_voxels", 2 * half);
    args.stat("active_voxels", uint64_t(out->activeVoxelCount()));
    args.out() << "levelforge: wrote " << output << "\n  shell of " << fmt("%g", 2 * half) << " voxels around '"
               << grid->getName() << "'; band " << fmt("%g", double(newBand)) << " voxels\n";
}

void registerOperators(OperatorRegistry& registry)
{
    registry.add(OperatorSpec("shell", "Hollow a level set into a shell of a given thickness (example plugin)")
                     .description("phi' = |phi| - thickness/2: the shell of the given thickness centred on the\n"
                                  "surface. An example of a plugin operator (examples/plugins/ShellPlugin.cc).")
                     .input("input", ".vdb file with a level set")
                     .output("output", ".vdb file to write")
                     .param(Param::floating("thickness", "Thickness", "Shell thickness, in voxels (see --world-units)")
                                .defaultValue(2.0)
                                .range(0.0, 10000.0, Bound::Exclusive, Bound::Inclusive))
                     .param(Param::flag("world-units", "Use World Space Units", "Read --thickness in world units"))
                     .example("levelforge --plugin libshell.so shell solid.vdb hollow.vdb --thickness 2")
                     .cook(cookShell));
}

} // namespace

LEVELFORGE_OPERATOR_PLUGIN("shell-example", registerOperators)
