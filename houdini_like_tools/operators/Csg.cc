// SPDX-License-Identifier: Apache-2.0
// levelforge operator `csg`: union, intersection or difference of two ADFs or two level sets
// (Yin et al. Figure 10; Houdini: VDB Combine in SDF mode).
#include "Operator.h"
#include "OperatorIO.h"
#include "Interrupt.h"

#include <levelforge/adf/AdaptiveDistanceField.h>
#include <levelforge/core/Exceptions.h>
#include <levelforge/io/VdbIO.h>

#include <openvdb/openvdb.h>

#include <ostream>
#include <string>

namespace levelforge::ops {
namespace {

/// The first FloatGrid of a .vdb file (or the one named `name`).
openvdb::FloatGrid::Ptr firstFloatGrid(const OperatorArgs& args, const std::string& path, const std::string& name)
{
    openvdb::GridPtrVecPtr grids;
    grids = readGridsInput(args, path);
    for (const auto& g : *grids) {
        if (!g->isType<openvdb::FloatGrid>()) continue;
        if (!name.empty() && g->getName() != name) continue;
        return openvdb::gridPtrCast<openvdb::FloatGrid>(g);
    }
    throw IoError(path + ": no float grid" + (name.empty() ? std::string() : " named '" + name + "'"));
}

double bandVoxels(const openvdb::FloatGrid& g)
{
    return double(g.background()) / g.voxelSize()[0];
}

void cookCsg(OperatorArgs& args)
{
    const std::string& pathA = args.input("a");
    const std::string& pathB = args.input("b");
    const std::string& output = args.output("output");
    checkOutputTarget(args, output);
    const CsgOperation op = csgOperationFromString(args.getString("op"));
    const std::string gridName = args.isSet("grid") ? args.getString("grid") : std::string();
    openvdb::FloatGrid::Ptr a = firstFloatGrid(args, pathA, gridName), b = firstFloatGrid(args, pathB, gridName);
    const bool adfA = isAdaptiveDistanceField(*a), adfB = isAdaptiveDistanceField(*b);
    openvdb::FloatGrid::Ptr result;
    std::string kind;
    if (adfA && adfB && a->transform() == b->transform() && !args.getBool("level-set")) {
        result = openvdb::ConstPtrCast<openvdb::FloatGrid>(
            csgAdaptiveDistanceFields(AdaptiveDistanceField(a), AdaptiveDistanceField(b), op).grid());
        kind = "ADF";
    } else {
        // level sets: an ADF input is resampled to a level set of the other input's band (or --band)
        const double band = args.isSet("band") ? args.getFloat("band")
                          : (!adfA ? bandVoxels(*a) : (!adfB ? bandVoxels(*b) : args.getFloat("band")));
        if (adfA) a = adaptiveDistanceFieldToLevelSet(AdaptiveDistanceField(a), band);
        if (adfB) b = adaptiveDistanceFieldToLevelSet(AdaptiveDistanceField(b), band);
        result = csgLevelSets(*a, *b, op);
        kind = "level set";
    }
    openvdb::MetaMap fileMeta;
    fileMeta.insertMeta("creator", openvdb::StringMetadata(generatorString()));
    writeGridsOutput(args, output, openvdb::GridPtrVec{result}, fileMeta);
    args.stat("kind", kind);
    args.stat("active_voxels", uint64_t(result->activeVoxelCount()));
    args.out() << "levelforge: wrote " << output << " (" << kind << " '" << result->getName() << "', "
               << args.getString("op") << " of " << pathA << " and " << pathB << ")\n";
}

} // namespace

LEVELFORGE_REGISTER_OPERATOR(
    OperatorSpec("csg", "Union, intersection or difference of two ADFs or two level sets")
        .description(
            "Reads the first float grid of each file. Two ADFs with the same transform give an\n"
            "ADF (cells: the finer of the two; samples: min/max of the two reconstructions).\n"
            "Otherwise the result is a level set (openvdb::tools::csg*Copy); an ADF input is first\n"
            "resampled to a level set with the other input's band (or --band). Both inputs must\n"
            "have the same voxel size.")
        .input("a", ".vdb file with the first ADF or level set")
        .input("b", ".vdb file with the second ADF or level set")
        .output("output", ".vdb file to write")
        .param(Param::choice("op", "Operation", "union: min(a, b); intersection: max(a, b); difference: max(a, -b)",
                             {"union", "intersection", "difference"})
                   .defaultValue("union"))
        .param(Param::string("grid", "Grid", "Use the float grid of this name in both files (default: the first)"))
        .param(Param::flag("level-set", "Level Set", "Write a level set even when both inputs are ADFs"))
        .param(Param::floating("band", "Band Voxels",
                               "Half-width, in voxels, of the level sets resampled from ADF inputs")
                   .defaultValue(3.0)
                   .range(0.0, 10000.0, Bound::Exclusive, Bound::Inclusive))
        .example("levelforge csg a.vdb b.vdb --op difference out.vdb")
        .cook(cookCsg));

} // namespace levelforge::ops
