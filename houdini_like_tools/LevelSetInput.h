// SPDX-License-Identifier: Apache-2.0
// The level set an operator works on: the float grid of a given name, or the first float grid
// of class GRID_LEVEL_SET of a .vdb file (operators `expand`, `reshape`).
#pragma once

#include <openvdb/openvdb.h>

#include <string>

namespace levelforge::ops {

/// @brief The grid named @p name, or (empty name) the first float level set of @p grids.
/// @param[in] grids  the grids read from @p path
/// @param[in] path   the file, for the message
/// @param[in] name   a grid name, or empty
/// @throws InvalidArgumentError no such float grid, or no float level set
openvdb::FloatGrid::Ptr pickLevelSet(const openvdb::GridPtrVec& grids, const std::string& path,
                                     const std::string& name);

} // namespace levelforge::ops
