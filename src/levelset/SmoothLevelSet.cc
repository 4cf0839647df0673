// SPDX-License-Identifier: Apache-2.0
// Mean / Gaussian / median / mean-curvature / Laplacian smoothing of a level set with OpenVDB's
// LevelSetFilter. See levelset/SmoothLevelSet.h.
#include <levelforge/levelset/SmoothLevelSet.h>

#include <levelforge/core/Exceptions.h>

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

namespace {

/// Forwards the filter's polls to the caller's interrupter, remembering a stop.
struct Poller : openvdb::util::NullInterrupter
{
    openvdb::util::NullInterrupter* user = nullptr;
    int base = 0, span = 100; // this iteration's share of 0–100
    bool stopped = false;
    bool wasInterrupted(int percent = -1) override
    {
        if (!user || stopped) return stopped;
        const int p = percent < 0 ? -1 : base + span * percent / 100;
        stopped = user->wasInterrupted(p);
        return stopped;
    }
};

} // namespace

openvdb::FloatGrid::Ptr smoothLevelSet(const openvdb::FloatGrid& levelSet, const SmoothLevelSetOptions& options)
{
    if (levelSet.getGridClass() != openvdb::GRID_LEVEL_SET)
        throw InvalidArgumentError("smooth: grid '" + levelSet.getName() + "' is not a level set (class GRID_LEVEL_SET)");
    if (!levelSet.hasUniformVoxels())
        throw InvalidArgumentError("smooth: grid '" + levelSet.getName() + "' has non-uniform voxels");
    const double h = levelSet.voxelSize()[0];
    const double band = std::abs(double(levelSet.background())) / h;
    if (!(band >= 2.0)) {
        std::ostringstream os;
        os << "smooth: grid '" << levelSet.getName() << "' has a band of " << band
           << " voxels; the level-set tracker needs at least 2 on each side";
        throw InvalidArgumentError(os.str());
    }
    if (options.iterations < 1 || options.iterations > 1000)
        throw InvalidArgumentError("smooth: iterations must be 1 to 1000, got " + std::to_string(options.iterations));
    if (options.radius < 1 || options.radius > 32)
        throw InvalidArgumentError("smooth: the filter radius must be 1 to 32 voxels, got " +
                                   std::to_string(options.radius));

    openvdb::FloatGrid::Ptr out = levelSet.deepCopy();
    Poller poller;
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
