// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Microtriangle voxelization (Chang, Cha, Ihm, CGF 2008, §3.1 and §3.3).
///
/// Finds every cell a triangle overlaps. Coordinates are in *cell space*: cell (i,j,k) is the
/// unit cube [i,i+1)×[j,j+1)×[k,k+1) (meshToLevelSet maps voxel ijk's cell there by
/// q = p/voxelSize + 0.5). A triangle whose AABB is longer than one cell, d_T > 1, is split into
/// ceil(d_T)² microtriangles (each edge into ceil(d_T) segments), so each microtriangle fits in a
/// unit box and spans at most 2 cells per axis. Then:
///   * vertex scan: the cell of every microtriangle vertex is reported;
///   * I = Ix+Iy+Iz (Iα = 1 when the three vertices share the α cell index):
///       I = 3, 2 (cases 1, 2): nothing more — all cells already hold a vertex;
///       I = 1 (case 3): the 2×2 cells in the plane of the two varying axes — the ones holding no
///         vertex are tested by a 2-D separating-axis test of the projected microtriangle;
///       I = 0 (case 4): the 2×2×2 cube — cells holding no vertex get the Akenine-Möller
///         triangle–box test (plane + 9 edge axes; the AABB axes pass by construction);
///   * white microtriangles are processed with all cases, black ones (which share all their
///     edges with white ones) only with case 4, as in §3.3.
/// Exactness: the reported set contains every cell whose interior the triangle meets. The
/// separating tests are closed with a tolerance of 1e-9 cell, so cells the triangle merely
/// touches (or misses by less than that) may be reported too; that only adds list entries.
#pragma once

#include <levelforge/core/TriangleMesh.h>

#include <openvdb/math/Coord.h>

#include <array>
#include <cstdint>
#include <vector>

namespace levelforge {

/// @brief What voxelizeTriangle() did, summed over the triangles it was given.
struct VoxelizerCounters
{
    uint64_t microtriangles = 0;
    std::array<uint64_t, 4> cases{}; ///< microtriangles with I = 3, 2, 1, 0 (cases 1..4)
    uint64_t boxTests = 0;           ///< 2-D and 3-D separating-axis tests run
    /// @brief Adds another set of counters to these (merging per-thread counters).
    /// @param[in] o  the counters to add
    void add(const VoxelizerCounters& o)
    {
        microtriangles += o.microtriangles;
        for (int k = 0; k < 4; ++k) cases[k] += o.cases[k];
        boxTests += o.boxTests;
    }
};

/// @brief Appends the cells (cell space) overlapped by triangle (a, b, c) to `cells`, each once,
///        in a deterministic order (vertex scan, then cells found by the case 3/4 tests).
///
/// A cell already found is never tested again. `counters` may be null. Thread-safe (scratch
/// memory is thread-local).
/// @param[in]     a         first corner, cell space
/// @param[in]     b         second corner, cell space
/// @param[in]     c         third corner, cell space
/// @param[in,out] cells     receives the overlapped cells, appended after its current contents
///                          (which are neither read nor deduplicated against)
/// @param[in,out] counters  optional: this triangle's microtriangles, cases and box tests are
///                          added to it
void voxelizeTriangle(const Vec3d& a, const Vec3d& b, const Vec3d& c,
                      std::vector<openvdb::math::Coord>& cells, VoxelizerCounters* counters = nullptr);

/// @brief Akenine-Möller triangle / axis-aligned box overlap test (all 13 axes).
///
/// The box is [center - half, center + half]; `tolerance` > 0 makes the test conservative
/// (reports overlap when the separation is at most `tolerance`), < 0 makes it strict.
/// @param[in] center     box centre
/// @param[in] half       box half-extents along x, y, z
/// @param[in] a          first corner of the triangle (same units as the box)
/// @param[in] b          second corner of the triangle
/// @param[in] c          third corner of the triangle
/// @param[in] tolerance  separation still counted as overlap (same units); 0: touching counts
/// @return true when the triangle and the box overlap (within @p tolerance)
bool triangleBoxOverlap(const Vec3d& center, const Vec3d& half, const Vec3d& a, const Vec3d& b,
                        const Vec3d& c, double tolerance = 0.0);

} // namespace levelforge
