// SPDX-License-Identifier: Apache-2.0
// Dilate / erode / open / close of a level set with OpenVDB's LevelSetFilter. See
// levelset/ReshapeLevelSet.h.
#include <levelforge/levelset/ReshapeLevelSet.h>

#include <levelforge/core/Exceptions.h>

#include "levelset/LevelSetFilterInternal.h"

#include <openvdb/tools/LevelSetFilter.h>

#include <cmath>
#include <sstream>

namespace levelforge {

ReshapeOperation reshapeOperationFromString(const std::string& name)
{
    if (name == "dilate") return ReshapeOperation::Dilate;
    if (name == "erode") return ReshapeOperation::Erode;
    if (name == "open") return ReshapeOperation::Open;
    if (name == "close") return ReshapeOperation::Close;
    throw InvalidArgumentError("unknown reshape operation '" + name + "' (dilate, erode, open, close)");
}

openvdb::FloatGrid::Ptr reshapeLevelSet(const openvdb::FloatGrid& levelSet, const ReshapeOptions& options)
{
    const double h = levelset_internal::requireFilterableLevelSet(levelSet, "reshape");
    const double r = options.worldUnits ? options.offset / h : options.offset; // voxels
    if (!std::isfinite(r) || !(r > 0.0) || r > 10000.0) {
        std::ostringstream os;
        os << "reshape: the offset must be a positive number of at most 10000 voxels, got " << options.offset
           << (options.worldUnits ? " world units (" + std::to_string(r) + " voxels)" : std::string(" voxels"));
        throw InvalidArgumentError(os.str());
    }
    openvdb::FloatGrid::Ptr out = levelSet.deepCopy();
    levelset_internal::FilterPoller poller;
    poller.user = options.interrupter;
    using Filter = openvdb::tools::LevelSetFilter<openvdb::FloatGrid, openvdb::FloatGrid, openvdb::util::NullInterrupter>;
    Filter filter(*out, &poller);
    const float world = float(r * h);
    // LevelSetFilter::offset(v) adds v: positive erodes
    const auto pass = [&](float v, int base, int span) {
        poller.base = base;
        poller.span = span;
        filter.offset(v);
        if (poller.stopped) throw InterruptedError("reshape: interrupted");
    };
    switch (options.operation) {
    case ReshapeOperation::Dilate: pass(-world, 0, 100); break;
    case ReshapeOperation::Erode: pass(world, 0, 100); break;
    case ReshapeOperation::Open: pass(world, 0, 50); pass(-world, 50, 50); break;
    case ReshapeOperation::Close: pass(-world, 0, 50); pass(world, 50, 50); break;
    }
    return out;
}

} // namespace levelforge
