// SPDX-License-Identifier: Apache-2.0
// levelforge operator `sample`: the signed distance of an ADF or a level set at a world point.
#include "Operator.h"
#include "OperatorIO.h"
#include "Interrupt.h"

#include <levelforge/adf/AdaptiveDistanceField.h>
#include <levelforge/core/Exceptions.h>
#include <levelforge/io/VdbIO.h>

#include <openvdb/openvdb.h>
#include <openvdb/tools/Interpolation.h>

#include <cmath>
#include <cstdio>
#include <ostream>
#include <string>

namespace levelforge::ops {
namespace {

double parseCoordinate(const std::string& text, const char* axis)
{
    size_t used = 0;
    double v = 0;
    try {
        v = std::stod(text, &used);
    } catch (const std::exception&) {
        used = 0;
    }
    if (used != text.size() || !std::isfinite(v))
        throw UsageError(std::string("invalid ") + axis + " coordinate '" + text + "': must be a finite number (world units)");
    return v;
}

void cookSample(OperatorArgs& args)
{
    const std::string& path = args.input("vdb");
    const Vec3d p(parseCoordinate(args.input("x"), "x"), parseCoordinate(args.input("y"), "y"),
                  parseCoordinate(args.input("z"), "z"));
    const std::string name = args.isSet("grid") ? args.getString("grid") : std::string();
    openvdb::GridPtrVecPtr grids;
    grids = readGridsInput(args, path);
    openvdb::FloatGrid::Ptr grid;
    for (const auto& g : *grids)
        if (g->isType<openvdb::FloatGrid>() && (name.empty() || g->getName() == name)) {
            grid = openvdb::gridPtrCast<openvdb::FloatGrid>(g);
            break;
        }
    if (!grid) throw IoError(path + ": no float grid" + (name.empty() ? std::string() : " named '" + name + "'"));
    char buf[128];
    std::snprintf(buf, sizeof(buf), "(%.9g, %.9g, %.9g)", p[0], p[1], p[2]);
    std::ostream& out = args.out();
    double d;
    if (isAdaptiveDistanceField(*grid)) {
        const AdaptiveDistanceField adf(grid);
        d = adf.distance(p);
        const int level = adf.level(p);
        out << buf << " grid '" << grid->getName() << "' (ADF, "
            << (level >= 0 ? "cell " + std::to_string(kAdfCellSize[level]) + "^3" : std::string("outside the domain"))
            << ") distance: ";
    } else {
        d = openvdb::tools::GridSampler<openvdb::FloatGrid, openvdb::tools::BoxSampler>(*grid).wsSample(p);
        out << buf << " grid '" << grid->getName() << "' ("
            << openvdb::GridBase::gridClassToString(grid->getGridClass()) << ", trilinear) distance: ";
    }
    std::snprintf(buf, sizeof(buf), "%.9g", d);
    out << buf << "\n";
}

} // namespace

LEVELFORGE_REGISTER_OPERATOR(
    OperatorSpec("sample", "Print the signed distance of an ADF or a level set at a world point")
        .description(
            "Reads the first float grid of the file (or --grid). An ADF (levelforge:adf\n"
            "metadata) is reconstructed continuously across its levels; any other grid is sampled\n"
            "trilinearly (openvdb::tools::BoxSampler). The distance, in world units, is the last\n"
            "token of the printed line.")
        .input("vdb", ".vdb file with an ADF or a level set")
        .input("x", "x coordinate, world units")
        .input("y", "y coordinate, world units")
        .input("z", "z coordinate, world units")
        .param(Param::string("grid", "Grid", "Name of the grid to sample (default: the first float grid)"))
        .example("levelforge sample bunny_adf.vdb 0.1 0.2 -0.05")
        .cook(cookSample));

} // namespace levelforge::ops
