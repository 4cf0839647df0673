// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief A scalar VDB grid (fog, density, CT/MRI stored sparsely, another tool's level set)
/// to a signed distance level set without ever allocating its dense bounding box.
///
/// Paper: R. Satherley, M. W. Jones, "Vector-City Vector Distance Transform", CVIU 82 (2001):
/// §4.1–4.2 (the sub-voxel accurate shell: each cell of 8 samples split into 6 tetrahedra, the
/// interpolated iso-surface as 1–2 triangles per tetrahedron, exact closest-point vectors in a
/// shell around it) and §4.3 (the shell propagated by the 8-pass VCVDT), here on VDB topology:
///
///  1. cells: the cells (8 samples) whose corners lie on both sides of the iso-value are found
///     among the leaves of the input tree and along the faces of its tiles whose side differs from
///     the background's (nowhere else can a constant tree region hold a crossing), one voxel
///     dilated; their triangles are the interpolated surface (src/detail/IsoSurfaceCells.h, the same
///     triangulation as the dense SubvoxelShell.h), a triangle soup in index space × voxel size;
///  2. exact shell: the exact distance to that surface in a band of 1.5 voxels (VCVDT8 with a
///     band wider than 3 voxels; up to 3 voxels the whole band is exact, which costs no more than
///     the 1.5-voxel shell and the widening; the dense
///     path's shell R is the 26-neighbourhood of the surface voxels, the same reach) with the
///     exact closest points and triangles, each voxel signed by its own sample's side of the
///     iso-value (the voxel centres are the samples, so this is the inside flag of Eq. 2 — no
///     pseudonormal is trusted on the unoriented soup), re-flood-filled. An exact band of at most
///     3 voxels is searched over the surface cells around each voxel, as the dense shell does (no
///     triangle hierarchy; the same values, bit for bit), recording the closest points and the
///     welded soup's triangle indices when step 3 follows; wider exact bands (Exact beyond 3
///     voxels) use meshToLevelSetWithClosestPoints (Chang et al. 2008) on the welded soup;
///  3. widening: to the requested widths with the sparse 8-pass VCVDT over the dilated VDB
///     topology (docs/expansion.md, through expandLevelSet with ExpansionMethod::Vector and the
///     exact closest points and triangles of step 2). With VolumeDistanceMethod::Exact the exact
///     band of step 2 already has the requested widths and step 3 is skipped.
///
/// What is exact and what is approximate: the surface is the piecewise-linear interpolation of the
/// samples (as in the dense sub-voxel path); distances to it are exact (double, stored as float)
/// in the exact band and, with Exact, everywhere; beyond the exact band the VCVDT values are
/// distances to a point of the surface (never below the exact distance) refined to the exact
/// distance to a nearby triangle (docs/expansion.md: mean < 1e-3 voxel, max < 0.1 voxel in the
/// tests). Signs are the samples' inside flags. Memory follows the band (plus the triangle soup of
/// the surface), not the bounding box: a grid with a 10⁵-voxel-wide empty gap converts like a
/// compact one.
#pragma once

#include <levelforge/mesh/MeshToLevelSet.h>
#include <levelforge/volume/VolumeToLevelSet.h>

#include <openvdb/openvdb.h>

#include <cstdint>

namespace levelforge {

/// @brief What sparseVolumeToLevelSet() did.
struct SparseVolumeToLevelSetStats
{
    uint64_t candidateCells = 0;  ///< cells examined (leaf and tile-face cells, dilated)
    uint64_t surfaceCells = 0;    ///< cells the iso-surface crosses
    uint64_t triangles = 0;       ///< triangles of the interpolated surface
    uint64_t exactVoxels = 0;     ///< voxels of the exact band (step 2)
    uint64_t activeVoxels = 0;    ///< voxels of the result
    double exactBand = 0.0;       ///< half-width of the exact band, voxels
    bool widened = false;         ///< step 3 ran (VCVDT8 with a width beyond the exact band)
    bool cellSearch = false;      ///< the exact band came from the search over the surface cells
                                  ///< (exact bands of at most 3 voxels, with the closest points
                                  ///< and triangles when step 3 widens it; `exact` unused)
    MeshToLevelSetStats exact;    ///< the exact band's converter (stage times, evaluations)
    double secondsSurface = 0, secondsExact = 0, secondsWiden = 0;
};

/// @brief Converts a scalar grid to a level set as described above.
///
/// Uses from `options`: iso, insideBelow, method (VCVDT8: exact band of 1.5 voxels then the
/// sparse VCVDT, or the whole band exact when no width exceeds 3 voxels; Exact: the exact band at the full widths — its cost grows with the
/// triangles within reach of each voxel, so wide exact bands on finely sampled surfaces are
/// slow), exteriorWidth / interiorWidth (in `units`, voxels by default), fillInterior (with
/// either method the inside beyond the exact band comes from the sparse VCVDT), gridName,
/// maxVoxels (limit on the band's voxels), interrupter; `subvoxel` must be true. The result has
/// the input's transform. Throws InvalidArgumentError (another method, binary classification,
/// non-uniform or non-linear transform, non-finite values — naming the voxel —, no surface at
/// this iso-value), ResourceLimitError (band larger than maxVoxels), InterruptedError.
/// @param[in]  field    the scalar grid: a linear transform with uniform, axis-aligned voxels;
///                      finite values everywhere (voxels, tiles, background); the voxel size
///                      comes from it
/// @param[in]  options  iso, insideBelow, method (VCVDT8 or Exact), subvoxel (true),
///                      exteriorWidth / interiorWidth (in GridSpec units: voxels by default; at
///                      most 1e5 voxels), fillInterior, gridName, maxVoxels, interrupter;
///                      voxelSize and voxelCount must stay 0
/// @param[out] stats    optional: cell, triangle and voxel counts, the exact band's converter
///                      statistics, stage times
/// @return a GRID_LEVEL_SET FloatGrid named options.gridName with the input's transform;
///         values in world units, negative inside
/// @throws InvalidArgumentError another method, binary classification, voxelSize or voxelCount
///         set, a band width not positive, non-uniform or non-linear transform, non-finite
///         values (naming the voxel or tile), no surface at this iso-value
/// @throws ResourceLimitError band larger than maxVoxels, or an iso-surface with more triangles
///         than 32-bit indices allow
/// @throws InterruptedError the interrupter asked to stop
openvdb::FloatGrid::Ptr sparseVolumeToLevelSet(const openvdb::FloatGrid& field, const VolumeToLevelSetOptions& options,
                                               SparseVolumeToLevelSetStats* stats = nullptr);

} // namespace levelforge
