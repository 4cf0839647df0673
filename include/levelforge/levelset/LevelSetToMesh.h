// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Polygonize the isosurface of a level set or fog volume into a triangle mesh (Houdini:
///        *Convert VDB* to polygons, "Isovalue" and "Adaptivity"; vdb_tool: -ls2mesh).
///
/// Algorithm: OpenVDB's openvdb::tools::volumeToMesh (Museth, "VDB", ACM TOG 2013; a dual
/// contouring of the sparse tree, one vertex per cell the isosurface crosses, placed at the
/// average of the cell's edge crossings; with adaptivity > 0, regions that are nearly flat merge
/// cells into larger polygons). levelforge adds only what a triangle mesh needs: the quads are
/// split into two triangles along their 0-2 diagonal (OpenVDB's own and levelforge's reader's
/// rule, so a quad mesh written by vdb_tool and read back by levelforge gives the same
/// triangles), triangles with a repeated corner are dropped, vertices no polygon uses are
/// removed, and the winding follows TriangleMesh's convention (counter-clockwise seen from
/// outside, so signedVolume() > 0 and mesh-to-sdf of the result is negative inside).
///
/// Orientation: OpenVDB winds the polygons of a level set (GRID_LEVEL_SET, inside where the
/// value is below the isovalue) clockwise seen from outside, and inverts the orientation for any
/// other grid class (a fog volume: inside where the value is above the isovalue); both are
/// reversed here, so the result is outward oriented for both.
///
/// What is exact and what is approximate: the edge crossings are found by linear interpolation of
/// the grid values along voxel edges, exact for a plane sampled exactly; each vertex is the
/// average of its cell's crossings, so a curved surface is approximated to second order in the
/// voxel size h (measured on a sphere of radius 20 voxels sampled exactly: every vertex within
/// 0.02 h of the sphere). Adaptivity trades accuracy for fewer polygons, and OpenVDB's threshold is
/// steep (measured on the same sphere: adaptivity 0.01 keeps a quarter of the triangles, every
/// vertex within 0.04 h, volume 0.7 % short; 0.05 keeps 6 %, within 0.1 h, 2.5 % short; 0.2 and
/// above keep 1.5 %, within 0.4 h, 10 % short, the large flat facets cutting the curve). The mesh is
/// closed where the isosurface lies inside the grid's active values; it is open where the
/// surface leaves them (a band clipped by a box, a fog volume cut by its bounding box).
/// OpenVDB's volumeToMesh takes no interrupter: the interrupter is polled before it starts and
/// while the polygons are converted after it.
#pragma once

#include <levelforge/core/TriangleMesh.h>

#include <openvdb/openvdb.h>
#include <openvdb/util/NullInterrupter.h>

#include <cstdint>

namespace levelforge {

/// @brief Options of levelSetToMesh().
struct LevelSetToMeshOptions
{
    /// The isovalue, in the grid's value units: world units for a level set (0: the zero
    /// crossing; > 0 a surface further out), a density for a fog volume (0.5 is the usual one).
    double isovalue = 0.0;
    /// 0: uniform, one polygon per crossed cell; up to 1: merge nearly flat regions into fewer,
    /// larger polygons (OpenVDB's adaptivity threshold).
    double adaptivity = 0.0;
    /// OpenVDB's option: move vertices of triangles whose orientation disagrees with their
    /// neighbours' (only with adaptivity > 0). On by default, as in OpenVDB and Houdini.
    bool relaxDisorientedTriangles = true;
    /// Polled before and after volumeToMesh (progress 0, 50–100); true throws InterruptedError.
    openvdb::util::NullInterrupter* interrupter = nullptr;
};

/// @brief What levelSetToMesh() made.
struct LevelSetToMeshStats
{
    uint64_t quads = 0;              ///< quads OpenVDB produced (each split into two triangles)
    uint64_t openvdbTriangles = 0;   ///< triangles OpenVDB produced (adaptive meshing)
    uint64_t degenerateDropped = 0;  ///< triangles dropped because two corners were the same vertex
    uint64_t unusedVerticesDropped = 0; ///< OpenVDB points no polygon used
};

/// @brief The isosurface of @p grid at options.isovalue as an outward-oriented triangle mesh in
///        world units (see the file comment).
/// @param[in]  grid     a float grid: a level set, a fog volume, or another scalar field (read as
///                      OpenVDB reads it: inside where the value is below the isovalue for a
///                      GRID_LEVEL_SET, above it otherwise)
/// @param[in]  options  isovalue, adaptivity, interrupter
/// @param[out] stats    optional: the polygon counts
/// @return the mesh (empty when the isosurface does not cross the grid's values); `source` says
///         which grid and isovalue it came from
/// @throws InvalidArgumentError the isovalue is not finite, or the adaptivity is not in [0, 1]
/// @throws InterruptedError the interrupter asked to stop
TriangleMesh levelSetToMesh(const openvdb::FloatGrid& grid, const LevelSetToMeshOptions& options,
                            LevelSetToMeshStats* stats = nullptr);

} // namespace levelforge
