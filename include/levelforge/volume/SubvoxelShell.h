// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Sub-voxel accurate shell of closest-point vectors around the iso-surface of a scalar
///        volume, the seeds of the vector distance transforms.
///
/// Paper: R. Satherley and M. W. Jones, "Vector-City Vector Distance Transform", Computer Vision
/// and Image Understanding 82 (2001), §4.1–4.2.
///
/// The interpolated surface: every cell of 8 samples is split into 6 tetrahedra around its main
/// diagonal (Kuhn/Freudenthal; neighbouring cells agree on their shared faces, so the surface is
/// closed and without the ambiguities of Marching Cubes, as §4.1 says of Payne and Toga's
/// method); in each tetrahedron the samples >= iso are inside, and the surface is the 1 triangle
/// (1 or 3 corners inside) or 2 triangles (2 inside) through the edge crossings found by linear
/// interpolation. Vertices are in world space, so anisotropic spacing is exact.
///
/// The shell R (§4.2): every inside voxel with an outside 26-neighbour, plus its 26-neighbours.
/// Each voxel of R gets the vector to its closest point on the triangulated surface (exact: the
/// cells are searched in growing windows until no unvisited cell can hold a closer point) and
/// the inside flag (f >= iso). All other voxels get +inf, ready for vectorDistanceTransform().
///
/// Exact: the closest points of the shell voxels on the piecewise-linear surface (double
/// precision, stored as float offsets). Approximate: the surface itself (linear interpolation in
/// tetrahedra of the sampled field), and everything the vector transform later propagates.
#pragma once

#include <levelforge/core/DenseVolume.h>
#include <levelforge/core/TriangleMesh.h>
#include <levelforge/volume/VectorDistanceTransform.h>

#include <openvdb/util/NullInterrupter.h>

#include <cstdint>

namespace levelforge {

/// Options of the sub-voxel shell.
struct SubvoxelShellOptions
{
    /// Iso-value τ of Eq. 2: samples >= iso are inside the object (negative distances).
    float iso = 0.0f;
    /// Inside is f <= iso instead (e.g. a level set or a dark object on a bright background).
    bool insideBelow = false;
    /// Optional interruption; not owned.
    openvdb::util::NullInterrupter* interrupter = nullptr;
};

/// What subvoxelShell() found.
struct SubvoxelShellStats
{
    uint64_t surfaceCells = 0;   ///< cells the surface passes through
    uint64_t triangles = 0;      ///< triangles of the interpolated surface
    uint64_t shellVoxels = 0;    ///< |R|
    uint64_t insideVoxels = 0;   ///< voxels with the inside flag
    double seconds = 0;          ///< wall time of subvoxelShell()
};

/// @brief The inside flag of every sample.
/// @param[in] field    the sampled field
/// @param[in] options  iso, insideBelow
/// @return 1 where the sample is inside (f >= iso, or f <= iso with insideBelow), else 0; same
///         dims, spacing, origin.
/// @throws InvalidArgumentError (empty volume, bad spacing, size mismatch).
MaskVolume insideFlags(const ScalarVolume& field, const SubvoxelShellOptions& options);

/// @brief The triangulated interpolated surface.
/// @param[in] field    the sampled field (at least 2 samples along each axis)
/// @param[in] options  iso, insideBelow
/// @return one triangle soup in world coordinates, 3 points per triangle (not consistently
///         oriented).
/// @throws InvalidArgumentError (empty volume, fewer than 2 samples along an axis, bad spacing,
///         NaN samples).
TriangleMesh isoSurfaceTriangles(const ScalarVolume& field, const SubvoxelShellOptions& options);

/// @brief The shell R of exact closest-point vectors (see the file comment).
/// @param[in]  field    the sampled field (at least 2 samples along each axis)
/// @param[in]  options  iso, insideBelow, interrupter
/// @param[out] stats    optional: surface cells, triangles, shell and inside voxels, time
/// @return closest-point vectors in voxel units (d2 in world units²) on R, +inf elsewhere; same
///         dims, spacing, origin.
/// @throws InvalidArgumentError (empty volume, fewer than 2 samples along an axis, bad spacing,
///         NaN samples);
/// @throws InterruptedError.
VectorVolume subvoxelShell(const ScalarVolume& field, const SubvoxelShellOptions& options,
                           SubvoxelShellStats* stats = nullptr);

} // namespace levelforge
