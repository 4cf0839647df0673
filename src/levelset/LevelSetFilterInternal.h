// SPDX-License-Identifier: Apache-2.0
// levelset/ private: what reshapeLevelSet() and smoothLevelSet() share around OpenVDB's
// LevelSetFilter: the input check and the interrupter that maps the filter's polls to a share of
// the caller's 0–100 progress.
#pragma once

#include <levelforge/core/Exceptions.h>

#include <openvdb/openvdb.h>
#include <openvdb/util/NullInterrupter.h>

#include <atomic>
#include <cmath>
#include <sstream>
#include <string>

namespace levelforge::levelset_internal {

/// @brief Checks that @p levelSet can go through LevelSetFilter: a level set with uniform voxels
///        and a band of at least 2 voxels on each side (the tracker's stencil).
/// @param[in] what  the operation, first word of every message ("reshape", "smooth")
/// @return the voxel size
/// @throws InvalidArgumentError naming the operation, the grid and the problem
inline double requireFilterableLevelSet(const openvdb::FloatGrid& levelSet, const char* what)
{
    const std::string grid = std::string(what) + ": grid '" + levelSet.getName() + "'";
    if (levelSet.getGridClass() != openvdb::GRID_LEVEL_SET)
        throw InvalidArgumentError(grid + " is not a level set (class GRID_LEVEL_SET)");
    if (!levelSet.hasUniformVoxels()) throw InvalidArgumentError(grid + " has non-uniform voxels");
    const double h = levelSet.voxelSize()[0];
    const double band = std::abs(double(levelSet.background())) / h;
    if (!(band >= 2.0)) {
        std::ostringstream os;
        os << grid << " has a band of " << band << " voxels; the level-set tracker needs at least 2 on each side";
        throw InvalidArgumentError(os.str());
    }
    return h;
}

/// Forwards the filter's polls (from its worker threads) to the caller's interrupter, as the
/// share [base, base + span] of 0–100, and remembers a stop.
struct FilterPoller : openvdb::util::NullInterrupter
{
    openvdb::util::NullInterrupter* user = nullptr;
    int base = 0, span = 100;
    std::atomic<bool> stopped{false};
    bool wasInterrupted(int percent = -1) override
    {
        if (!user || stopped.load(std::memory_order_relaxed)) return stopped.load(std::memory_order_relaxed);
        const int p = percent < 0 ? -1 : base + span * percent / 100;
        if (user->wasInterrupted(p)) stopped.store(true);
        return stopped.load(std::memory_order_relaxed);
    }
};

} // namespace levelforge::levelset_internal
