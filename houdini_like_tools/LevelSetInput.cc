// SPDX-License-Identifier: Apache-2.0
#include "LevelSetInput.h"

#include <levelforge/core/Exceptions.h>

namespace levelforge::ops {

openvdb::FloatGrid::Ptr pickLevelSet(const openvdb::GridPtrVec& grids, const std::string& path,
                                     const std::string& name)
{
    for (const auto& g : grids) {
        auto f = openvdb::gridPtrCast<openvdb::FloatGrid>(g);
        if (!f) continue;
        if (name.empty() ? f->getGridClass() == openvdb::GRID_LEVEL_SET : f->getName() == name) return f;
    }
    if (!name.empty()) throw InvalidArgumentError(path + ": no float grid named '" + name + "'");
    throw InvalidArgumentError(path + ": no float level-set grid (class GRID_LEVEL_SET) found");
}

} // namespace levelforge::ops
