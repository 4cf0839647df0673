// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Private to the chamfer transforms (and their white-box tests): the neighbourhood and
///        the step weights of each chamfer mask.
#pragma once

#include <levelforge/volume/ChamferDistanceTransform.h>

#include <openvdb/Types.h>

#include <cstdint>
#include <vector>

namespace levelforge::chamfer_internal {

/// One step of a chamfer mask, in voxels.
struct Step
{
    int8_t x, y, z;
};

/// The full (symmetric) neighbourhood of a metric, in a fixed order (z, y, x from -2 to 2).
std::vector<Step> neighbourhood(ChamferMetric metric);

/// Weight of one mask step, world units (see ChamferDistanceTransform.h).
double stepWeight(ChamferMetric metric, const Step& step, const openvdb::Vec3d& spacing);

} // namespace levelforge::chamfer_internal
