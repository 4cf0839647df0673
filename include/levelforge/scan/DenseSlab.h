// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Dense slabs: the unit of work a scan-conversion backend computes.
///
/// T4 scan conversion (Erleben & Dohlmann, "Scan Conversion of Signed Distance Fields";
/// TetScanConversion.h) slices tetrahedral shells with the z-planes of the grid. The sweep groups
/// the resulting convex cross-sections by dense slab — a box of voxels, z-range x xy-rectangle,
/// aligned to VDB leaf boundaries — and hands each slab with its items to a SlabBackend, which
/// fills the slab's distances. The slab is then scattered back into the sparse FloatGrid.
///
/// Contract of a backend (what a GPU twin must reproduce):
///   * coverage: voxel (i, j, z) of the slab is covered by an item on plane z iff its centre
///     (i, j) lies in the closed convex polygon (exact scanline spans with a 1e-7 voxel outward
///     tolerance; no enlargement of the polygon). This is exact point sampling of the shell, so
///     no voxel centre inside a shell is missed (no aliasing).
///   * value: for every covered voxel, the exact closest point on the item's triangle
///     (closestPointOnTriangle, world coordinates, voxel centre = index * voxelSize) and the sign
///     of dot(p - c, n) with n the pseudonormal of the closest feature (vertex, edge or face); the
///     slab keeps the item with the smallest distance, ties broken by the smaller triangle index,
///     so the result does not depend on the item order or the number of threads.
///   * the CPU backend compares squared distances in double precision and stores double distances
///     (the band test -interior < d/h < exterior is made on them, then they are stored as float,
///     exactly like the Chang path); a float GPU backend agrees within float rounding.
#pragma once

#include <levelforge/core/PseudoNormals.h>
#include <levelforge/core/TriangleMesh.h>

#include <openvdb/openvdb.h>

#include <array>
#include <cstdint>
#include <limits>
#include <vector>

namespace levelforge {

/// @brief A convex cross-section of one tetrahedron on the plane z (index space: voxel centres
///        at integer coordinates), tagged with the triangle whose distance it evaluates.
struct CrossSection
{
    static constexpr int kMaxVertices = 16;
    uint32_t triangle = 0;
    int32_t z = 0;
    uint32_t count = 0;         ///< 1..16 vertices (3 or 4 for a plane slice; up to 16 for a
                                ///< conservative cell footprint, TetScanOptions::conservative)
    std::array<double, kMaxVertices> x{}, y{}; ///< polygon vertices in order (either orientation)
};

/// @brief Per-triangle data a backend needs, flat (GPU-friendly), world units.
struct SlabTriangles
{
    double voxelSize = 1.0;
    std::vector<Vec3d> corners; ///< 3 per triangle
    std::vector<Vec3d> normals; ///< 7 per triangle, in TriangleFeature order (face, v0, v1, v2, e01, e12, e20)

    /// @brief Gathers the corners and the 7 pseudonormals of every triangle of @p mesh.
    /// @param[in] mesh       the mesh, world units (degenerate triangles included: zero normals)
    /// @param[in] normals    the pseudonormals of @p mesh
    /// @param[in] voxelSize  voxel edge length, world units (> 0): voxel centre = index * voxelSize
    /// @return the flat arrays, indexed by triangle id (3 corners, 7 normals per triangle)
    static SlabTriangles build(const TriangleMesh& mesh, const PseudoNormals& normals, double voxelSize);
};

/// @brief A dense box of voxels.
///
/// Index of voxel (x, y, z): ((x - x0) * dimY + (y - y0)) * dimZ + (z - z0).
struct DenseSlab
{
    static constexpr uint32_t kNone = ~0u;
    openvdb::CoordBBox box;
    std::vector<double> dist;   ///< signed distance, world units; +inf where nothing covered it
                                ///< (double so that band membership is decided before rounding;
                                ///< a float backend writes its float values here)
    std::vector<uint32_t> tri;  ///< triangle that produced dist, kNone where uncovered
    uint64_t rasterized = 0;    ///< (voxel, item) evaluations performed by fill()

    /// @brief Resizes the slab to box @p b and clears it: every dist +inf, every tri kNone,
    ///        rasterized 0.
    /// @param[in] b  the slab's box, index space (inclusive bounds)
    void reset(const openvdb::CoordBBox& b);
    size_t size() const { return dist.size(); }
    /// @brief The position of voxel @p c in `dist` and `tri`. Not bounds-checked.
    /// @param[in] c  a voxel inside `box`, index space
    /// @return ((x - x0) * dimY + (y - y0)) * dimZ + (z - z0)
    size_t index(const openvdb::Coord& c) const
    {
        const openvdb::Coord d = box.dim();
        return (size_t(c.x() - box.min().x()) * size_t(d.y()) + size_t(c.y() - box.min().y())) * size_t(d.z()) +
               size_t(c.z() - box.min().z());
    }
};

/// @brief Rasterization helper shared by backends: the closed x-interval [xl, xr] of the convex
///        polygon on the row y (with tolerance tol).
///
/// False if the row misses the polygon.
/// @param[in]  cs   the cross-section (index space)
/// @param[in]  y    the row, index space (a voxel centre's y)
/// @param[in]  tol  how far outside an edge's y-range the row may lie and still meet the edge
///                  (voxels; the CPU backend uses 1e-7)
/// @param[out] xl   left end of the interval, index space
/// @param[out] xr   right end of the interval, index space
/// @return true when the row meets the polygon (then xl <= xr)
bool crossSectionSpan(const CrossSection& cs, double y, double tol, double& xl, double& xr);

/// @brief One slab of a batch handed to SlabBackend::fillBatch().
struct SlabJob
{
    DenseSlab* slab = nullptr;          ///< reset to its box
    const CrossSection* items = nullptr; ///< the cross-sections touching it (index space)
    size_t count = 0;                    ///< number of items
};

/// @brief Fills dense slabs.
///
/// fill() is called concurrently for different slabs and must be thread-safe. The scan
/// conversion hands slabs over in batches of up to preferredBatch() through fillBatch(); a
/// backend that dispatches to a device overrides both.
class SlabBackend
{
public:
    virtual ~SlabBackend() = default;
    /// @brief Fills every slab of a batch, each by the contract of fill(). The default calls
    ///        fill() for each job, in parallel (TBB).
    /// @param[in,out] jobs  the slabs (each reset to its box) and their items
    /// @param[in]     n     number of jobs
    /// @param[in]     tris  corners and pseudonormals of the triangles the items refer to (the
    ///                      same object for every call of one conversion)
    virtual void fillBatch(const SlabJob* jobs, size_t n, const SlabTriangles& tris) const;
    /// @brief How many slabs the caller should hand to fillBatch() at once (default 64).
    virtual size_t preferredBatch() const { return 64; }
    /// @brief A short name of the backend, for messages and statistics (e.g. "cpu").
    virtual const char* name() const = 0;
    /// @brief Fills @p slab by the backend contract (see the file comment).
    ///
    /// `slab` has been reset to its box; items all have z inside the box.
    /// @param[in,out] slab   reset to its box on entry; receives dist, tri and rasterized
    /// @param[in]     items  the cross-sections touching the slab (index space)
    /// @param[in]     count  number of @p items
    /// @param[in]     tris   corners and pseudonormals of the triangles the items refer to
    virtual void fill(DenseSlab& slab, const CrossSection* items, size_t count, const SlabTriangles& tris) const = 0;
};

/// @brief The reference backend: serial within a slab (slabs run in parallel under TBB).
class CpuSlabBackend : public SlabBackend
{
public:
    /// @brief "cpu".
    const char* name() const override { return "cpu"; }
    /// @brief Fills @p slab exactly by the backend contract, in double precision.
    /// @param[in,out] slab   reset to its box on entry; receives dist, tri and rasterized
    /// @param[in]     items  the cross-sections touching the slab (index space); items with
    ///                       z outside the box or no vertices are skipped
    /// @param[in]     count  number of @p items
    /// @param[in]     tris   corners and pseudonormals of the triangles the items refer to
    void fill(DenseSlab& slab, const CrossSection* items, size_t count, const SlabTriangles& tris) const override;
};

} // namespace levelforge
