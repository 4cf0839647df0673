// SPDX-License-Identifier: Apache-2.0
// Mean / Gaussian / median / mean-curvature / Laplacian smoothing of a level set with OpenVDB's
// LevelSetFilter. See levelset/SmoothLevelSet.h.
#include <levelforge/levelset/SmoothLevelSet.h>

#include <levelforge/core/Exceptions.h>

#include "levelset/LevelSetFilterInternal.h"

#include <openvdb/tools/LevelSetFilter.h>

#include <cmath>
#include <sstream>

namespace levelforge {

SmoothFilter smoothFilterFromString(const std::string& name)
{
    if (name == "mean") return SmoothFilter::Mean;
    if (name == "gaussian") return SmoothFilter::Gaussian;
    if (name == "median") return SmoothFilter::Median;
    if (name == "mean-curvature") return SmoothFilter::MeanCurvature;
    if (name == "laplacian") return SmoothFilter::Laplacian;
    throw InvalidArgumentError("unknown smoothing filter '" + name +
                               "' (mean, gaussian, median, mean-curvature, laplacian)");
}

const char* toString(SmoothFilter filter)
{
    switch (filter) {
    case SmoothFilter::Mean: return "mean";
    case SmoothFilter::Gaussian: return "gaussian";
    case SmoothFilter::Median: return "median";
    case SmoothFilter::MeanCurvature: return "mean-curvature";
    case SmoothFilter::Laplacian: return "laplacian";
    }
    return "?";
}

openvdb::FloatGrid::Ptr smoothLevelSet(const openvdb::FloatGrid& levelSet, const SmoothLevelSetOptions& options)
{
    levelset_internal::requireFilterableLevelSet(levelSet, "smooth");
    if (options.iterations < 1 || options.iterations > 1000)
        throw InvalidArgumentError("smooth: iterations must be 1 to 1000, got " + std::to_string(options.iterations));
    if (options.radius < 1 || options.radius > 32)
        throw InvalidArgumentError("smooth: the filter radius must be 1 to 32 voxels, got " +
                                   std::to_string(options.radius));

    openvdb::FloatGrid::Ptr out = levelSet.deepCopy();
    levelset_internal::FilterPoller poller;
    poller.user = options.interrupter;
    using Filter = openvdb::tools::LevelSetFilter<openvdb::FloatGrid, openvdb::FloatGrid, openvdb::util::NullInterrupter>;
    Filter filter(*out, &poller);
    const int n = options.iterations, r = options.radius;
    for (int i = 0; i < n; ++i) {
        poller.base = 100 * i / n;
        poller.span = 100 * (i + 1) / n - poller.base;
        switch (options.filter) {
        case SmoothFilter::Mean: filter.mean(r); break;
        case SmoothFilter::Gaussian: filter.gaussian(r); break;
        case SmoothFilter::Median: filter.median(r); break;
        case SmoothFilter::MeanCurvature: filter.meanCurvature(); break;
        case SmoothFilter::Laplacian: filter.laplacian(); break;
        }
        if (poller.stopped || (options.interrupter && options.interrupter->wasInterrupted(100 * (i + 1) / n)))
            throw InterruptedError("smooth: interrupted");
    }
    return out;
}

} // namespace levelforge
