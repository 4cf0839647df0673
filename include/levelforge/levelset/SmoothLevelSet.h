// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Smoothing of a narrow-band level set: mean, Gaussian, median, mean-curvature flow or
///        Laplacian flow (Houdini: *VDB Smooth SDF*; vdb_tool: -mean, -gauss, -median).
///
/// Algorithm: OpenVDB's openvdb::tools::LevelSetFilter (Museth, "VDB", ACM TOG 2013), nothing
/// reimplemented. Each iteration filters the values of the active band and then the
/// LevelSetTracker rebuilds the band (renormalization towards |∇φ| = 1, re-activation of the
/// band), so the result is a valid level set with the input's band width:
///   - Mean: the average over the (2r+1)³ box of voxels around each voxel (separable, three
///     1-D passes);
///   - Gaussian: OpenVDB's approximate Gaussian of radius r: the box filter applied four times
///     (with the band rebuilt after each), a kernel of standard deviation √(4r(r+1)/3) voxels
///     (1.6 for r = 1);
///   - Median: the median of the (2r+1)³ box (robust to isolated spikes, keeps sharp edges
///     better than the mean);
///   - MeanCurvature: one explicit step of mean-curvature flow, φ_t = κ |∇φ| (second-order
///     central differences; the radius is not used);
///   - Laplacian: one explicit step of the Laplacian flow φ_t = Δφ (the radius is not used).
///
/// What is exact and what is approximate: the filters are exact evaluations of their discrete
/// stencils on the stored values; the renormalization after each iteration is first order. Any
/// smoothing moves the surface: convex parts shrink, concave parts grow (a sphere of radius R
/// voxels shrinks by about r(r+1)/(3R) voxels per mean iteration of radius r; measured in
/// tests/levelset/TestSmoothLevelSet.cc, with the other filters). Sharp corners get rounded:
/// that is the point. The input is not modified; the result keeps its transform, name,
/// background and metadata.
#pragma once

#include <openvdb/openvdb.h>
#include <openvdb/util/NullInterrupter.h>

#include <string>

namespace levelforge {

/// The filter of smoothLevelSet() (Houdini's "Operation").
enum class SmoothFilter
{
    Mean,          ///< box average of radius r
    Gaussian,      ///< approximate Gaussian of radius r
    Median,        ///< box median of radius r
    MeanCurvature, ///< one step of mean-curvature flow per iteration (radius unused)
    Laplacian      ///< one step of Laplacian flow per iteration (radius unused)
};

/// "mean" / "gaussian" / "median" / "mean-curvature" / "laplacian"; throws InvalidArgumentError
/// otherwise.
SmoothFilter smoothFilterFromString(const std::string& name);
/// The name smoothFilterFromString() reads.
const char* toString(SmoothFilter filter);

/// @brief Options of smoothLevelSet().
struct SmoothLevelSetOptions
{
    SmoothFilter filter = SmoothFilter::Mean;
    /// How many times the filter is applied (Houdini's "Iterations"), 1 – 1000.
    int iterations = 1;
    /// Filter radius r in voxels (Houdini's "Filter Voxel Radius"): the box is (2r+1)³ voxels,
    /// 1 – 32. Mean, Gaussian and Median only.
    int radius = 1;
    /// Polled by the filter (progress 0–100 over all iterations); a true answer throws
    /// InterruptedError.
    openvdb::util::NullInterrupter* interrupter = nullptr;
};

/// @brief Smooths a narrow-band level set (see the file comment).
/// @param[in] levelSet  a level set (GRID_LEVEL_SET, uniform voxels, band at least 2 voxels on
///                      each side: the tracker needs the stencil)
/// @param[in] options   filter, iterations, radius, interrupter
/// @return a new level set on the same transform, with the same band width
/// @throws InvalidArgumentError not a level set, non-uniform voxels, a band under 2 voxels,
///         iterations outside 1 – 1000 or a radius outside 1 – 32
/// @throws InterruptedError the interrupter asked to stop
openvdb::FloatGrid::Ptr smoothLevelSet(const openvdb::FloatGrid& levelSet, const SmoothLevelSetOptions& options);

} // namespace levelforge
