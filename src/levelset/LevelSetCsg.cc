// SPDX-License-Identifier: Apache-2.0
// CSG operations by name, and CSG of two level sets with openvdb::tools::csg*Copy. See
// core/CsgOperation.h and levelset/LevelSetCsg.h.
#include <levelforge/levelset/LevelSetCsg.h>

#include <levelforge/core/CsgOperation.h>
#include <levelforge/core/Exceptions.h>

#include <openvdb/tools/Composite.h>

#include <string>

namespace levelforge {

CsgOperation csgOperationFromString(const std::string& name)
{
    if (name == "union") return CsgOperation::Union;
    if (name == "intersection") return CsgOperation::Intersection;
    if (name == "difference") return CsgOperation::Difference;
    throw InvalidArgumentError("unknown CSG operation '" + name + "' (expected union, intersection or difference)");
}

const char* csgOperationName(CsgOperation op)
{
    switch (op) {
    case CsgOperation::Union: return "union";
    case CsgOperation::Intersection: return "intersection";
    case CsgOperation::Difference: return "difference";
    }
    return "union";
}

openvdb::FloatGrid::Ptr csgLevelSets(const openvdb::FloatGrid& a, const openvdb::FloatGrid& b, CsgOperation op)
{
    if (a.transform() != b.transform())
        throw InvalidArgumentError("CSG of level sets '" + a.getName() + "' and '" + b.getName() +
                                   "': the grids have different transforms; resample one onto the other first");
    for (const openvdb::FloatGrid* g : {&a, &b})
        if (g->getGridClass() != openvdb::GRID_LEVEL_SET)
            throw InvalidArgumentError("CSG: grid '" + g->getName() + "' is not a level set (class " +
                                       openvdb::GridBase::gridClassToString(g->getGridClass()) + ")");
    openvdb::FloatGrid::Ptr out;
    switch (op) {
    case CsgOperation::Union: out = openvdb::tools::csgUnionCopy(a, b); break;
    case CsgOperation::Intersection: out = openvdb::tools::csgIntersectionCopy(a, b); break;
    case CsgOperation::Difference: out = openvdb::tools::csgDifferenceCopy(a, b); break;
    }
    out->setGridClass(openvdb::GRID_LEVEL_SET);
    out->setName(a.getName());
    return out;
}

} // namespace levelforge
