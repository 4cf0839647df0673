// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief The generalized winding number of a triangle mesh, fast: a tree of triangle clusters
///        whose far field is a multipole (dipole) expansion and whose near field is summed
///        exactly; and the signing of a level set's inactive region by it.
///
/// Papers:
///  - A. Jacobson, L. Kavan, O. Sorkine-Hornung, "Robust Inside-Outside Segmentation using
///    Generalized Winding Numbers", SIGGRAPH 2013: w(q) = (1/4π) Σ_t Ω_t(q), the signed solid
///    angles of the triangles seen from q. w = 1 inside and 0 outside a closed, consistently
///    oriented surface (−1 inside an inverted one, k inside k nested layers); for open, broken,
///    self-intersecting or non-manifold meshes it varies smoothly off the surface and jumps by
///    exactly 1 across it, and |w| > 1/2 is a robust "inside".
///  - G. Barill, N. Dickson, R. Schmidt, D. Levin, A. Jacobson, "Fast Winding Numbers for Soups
///    and Clouds", SIGGRAPH 2018: a cluster of triangles seen from far away acts as a dipole
///    distribution: with K(x) = (x − q)/|x − q|³ and the cluster centre p̃ (area-weighted
///    centroid), Ω = Σ_t ∫_t n_t·K dA ≈ N·K(p̃) + Σ_ij M_ij ∂_j K_i(p̃) + ½ Σ_ijk C_ijk ∂_j∂_k K_i(p̃),
///    with N = Σ a_t n_t (the vector area), M_ij = Σ a_t n_ti (c_t − p̃)_j and
///    C_ijk = Σ_t n_ti ∫_t (x − p̃)_j (x − p̃)_k dA (exact triangle moments, not point samples).
///    A cluster is expanded when |q − p̃| > β ρ (ρ: the cluster's radius about p̃); otherwise its
///    children are visited, and the triangles of a leaf cluster are summed exactly. β is the
///    accuracy parameter (FastWindingNumberOptions::accuracy, default 2 as in the paper).
///
/// The exact solid angle of a triangle is Van Oosterom and Strackee's formula (IEEE TBME 1983):
/// tan(Ω/2) = a·(b×c) / (|a||b||c| + (a·b)|c| + (b·c)|a| + (c·a)|b|), a, b, c the corners
/// relative to q, evaluated with atan2.
///
/// What is exact and what is approximate:
///  - the near field (every leaf cluster within β ρ of the query) is summed exactly in double
///    precision; the far field is the truncated expansion. Its truncation error is bounded
///    rigorously by evaluate()'s errorBound: for a cluster of area A at distance D, t = ρ/D and
///    m = order + 1, |ΔΩ| ≤ A/D² · (t^(m−1) (m − (m−1) t)/(1 − t)² + ½ t^(m−1)/(1 − t)) (the
///    Legendre series of 1/|x − q| and |∇(r^l P_l)| ≤ √(l(l+1)) r^(l−1)); the bound is loose
///    (it assumes every term adds up in the worst direction). Measured error at the defaults
///    (β = 2, order 3) on the test meshes: below 1e-2, typically 2e-3 (docs/algorithm.md,
///    "Sign modes");
///  - gradientBound() is a rigorous upper bound of |∇w| over a box, from the Biot–Savart law:
///    off the surface, ∇w is the magnetic field (divided by the current) of the mesh's boundary
///    curve, each undirected edge carrying the current (uses a→b) − (uses b→a), vertices at
///    exactly the same position counted as one (the coincident edges of an unwelded seam carry
///    opposite currents whose fields cancel exactly). For a closed,
///    consistently oriented mesh every current is 0 and w is piecewise constant; otherwise
///    |∇w(q)| ≤ (1/4π) Σ_e |I_e| min(L_e/δ_e², π/δ_e), δ_e the distance from q to edge e;
///  - gradient() is exact (the closed-form field of each straight edge), hessianBound() a
///    rigorous bound (|∇(r/|r|³)| <= 2/|r|³); together they give w(x) = w(c) + ∇w(c)·(x − c) ± ½
///    |x − c|² H along any path that crosses no surface (and across it, plus the signed crossings);
///  - degenerate (zero-area) triangles are left out, as meshToLevelSet() leaves them out.
///
/// Evaluation is const, thread-safe and deterministic (a fixed traversal order); construction
/// is parallel (TBB) and gives the same tree for any thread count.
#pragma once

#include <levelforge/core/TriangleMesh.h>

#include <openvdb/openvdb.h>
#include <openvdb/util/NullInterrupter.h>

#include <cstdint>
#include <limits>
#include <memory>
#include <vector>

namespace levelforge {

/// @brief Settings of the fast winding number.
struct FastWindingNumberOptions
{
    /// Barill et al.'s β: a cluster is replaced by its expansion when the query is farther than
    /// β times the cluster's radius from the cluster's centre (> 1; larger: more exact, slower).
    double accuracy = 2.0;
    /// Terms of the far-field expansion: 1 the dipole (vector area) only, 2 adds the first-order
    /// term (M), 3 the second-order term (C) too (the paper's and libigl's default, there called
    /// expansion order 2). The error falls as (ρ/D)^(order + 2).
    int order = 3;
    /// Triangles per leaf cluster (1 to 64).
    uint32_t leafSize = 8;
    /// Triangles per leaf cluster when the mesh has no boundary current (closed and consistently
    /// oriented, or every open edge cancelled), 0 to 64; 0: leafSize. There w is piecewise
    /// constant and a conversion makes only a few estimates (one per region between surface
    /// crossings), so a coarser tree, cheaper to build, costs nothing; meshToLevelSet() uses 64.
    uint32_t leafSizeWithoutCurrent = 0;
};

/// @brief Signed solid angle of triangle (a, b, c) seen from p (Van Oosterom–Strackee):
///        positive when p lies behind the triangle (on the side its counter-clockwise normal
///        points away from), in (−2π, 2π); 0 when p lies in the triangle's plane.
/// @param[in] a  first corner
/// @param[in] b  second corner
/// @param[in] c  third corner
/// @param[in] p  the point it is seen from
/// @return the solid angle, steradians
double triangleSolidAngle(const Vec3d& a, const Vec3d& b, const Vec3d& c, const Vec3d& p);

/// @brief The fast winding number of one mesh, for many queries (see the file comment).
class FastWindingNumber
{
public:
    /// @brief An evaluation with its truncation bound and work counters.
    struct Estimate
    {
        double value = 0.0;        ///< the winding number estimate
        double errorBound = 0.0;   ///< rigorous bound of |value − w| from truncation (rounding aside)
        uint32_t exactTriangles = 0; ///< triangles summed exactly
        uint32_t expansions = 0;     ///< clusters replaced by their expansion
    };

    /// @brief Builds the cluster tree and the boundary-current edges of @p mesh.
    ///
    /// Keeps no reference to @p mesh (the triangles are copied in leaf order).
    /// @param[in] mesh     the surface, world units (a usable mesh: indices in range, finite
    ///                     coordinates); may be open, broken, non-manifold, a soup
    /// @param[in] options  accuracy (β), expansion order, leaf size
    /// @throws InvalidArgumentError accuracy not > 1, order not in [1, 3], leafSize not in [1, 64],
    ///         leafSizeWithoutCurrent above 64
    explicit FastWindingNumber(const TriangleMesh& mesh, const FastWindingNumberOptions& options = {});
    ~FastWindingNumber();
    FastWindingNumber(FastWindingNumber&&) noexcept;
    FastWindingNumber& operator=(FastWindingNumber&&) noexcept;

    /// @brief The winding number estimate at @p p (world units).
    double operator()(const Vec3d& p) const;
    /// @brief The same estimate at @p p with its truncation bound and work counters (slower).
    Estimate evaluate(const Vec3d& p) const;
    /// @brief Estimates at @p count points close together (e.g. the voxels of a block), in one
    ///        traversal: a cluster is expanded only when it is far (β ρ) from every point, so
    ///        each value is at least as accurate as operator()'s, and each cluster's data are
    ///        read once for all points (several times faster per point than operator()).
    /// @param[in]  points  the query points, world units
    /// @param[in]  count   how many
    /// @param[out] values  the estimates, in the same order
    void evaluate(const Vec3d* points, size_t count, double* values) const;
    /// @brief The exact winding number, by summing every triangle's solid angle (O(F); tests).
    double exact(const Vec3d& p) const;

    /// @brief Upper bound of |∇w| over the box [lo, hi] (world units; the result in 1/world
    ///        units), by the Biot–Savart law over the boundary-current edges.
    /// @return 0 when the mesh has no boundary current (closed and consistently oriented, or
    ///         every open edge cancelled), +infinity when such an edge touches the box
    double gradientBound(const Vec3d& lo, const Vec3d& hi) const;

    /// @brief The exact gradient of w at @p p (world units; the result in 1/world units), off
    ///        the surface's boundary curve: the Biot–Savart field of the boundary-current edges
    ///        (exact per segment, O(currentEdges())). Zero for a mesh without boundary current.
    ///        Smooth across the surface (w jumps there, its gradient does not).
    Vec3d gradient(const Vec3d& p) const;
    /// @brief ∇w at @p p in O(log) time: boundary-current edges far from @p p (a subtree of the
    ///        edge tree farther than twice its box diagonal) as one current element at the box
    ///        centre; @p errorBound receives a rigorous bound of |result − gradient(p)| (the
    ///        terms' variation over each box, |∇(r/|r|³)| <= 2/|r|³; 1/world units).
    Vec3d gradient(const Vec3d& p, double& errorBound) const;

    /// @brief Upper bound of the operator norm of the Hessian of w over the box [lo, hi] (world
    ///        units; the result in 1/world units²): (1/4π) Σ_e |I_e| min(2 L_e/δ_e³, 4/δ_e²).
    /// @return 0 without boundary current, +infinity when such an edge touches the box
    double hessianBound(const Vec3d& lo, const Vec3d& hi) const;

    /// @brief Undirected edges with a nonzero net current (boundary, inconsistently oriented or
    ///        unbalanced non-manifold edges).
    uint64_t currentEdges() const;
    /// @brief Triangles used (the non-degenerate ones).
    uint64_t triangles() const;
    /// @brief Nodes of the cluster tree.
    uint64_t nodes() const;
    /// @brief Bytes held.
    size_t memoryBytes() const;
    /// @brief The options it was built with.
    const FastWindingNumberOptions& options() const;

private:
    friend struct FastWindingNumberAccess;
    struct Impl;
    std::unique_ptr<Impl> mImpl;
};

/// @brief The fast winding number of @p mesh at each of @p points (world units), in parallel.
/// @param[in] mesh     the surface (see FastWindingNumber)
/// @param[in] points   query points, world units
/// @param[in] options  accuracy, order, leaf size
/// @return w at each point, in the order given
/// @throws InvalidArgumentError bad options
std::vector<double> fastWindingNumbers(const TriangleMesh& mesh, const std::vector<Vec3d>& points,
                                       const FastWindingNumberOptions& options = {});

/// @brief What signInactiveByWindingNumber() did.
struct WindingSignStats
{
    uint64_t evaluations = 0;       ///< winding number evaluations
    uint64_t components = 0;        ///< connected groups of inactive tiles / voxels signed by one evaluation
    uint64_t individual = 0;        ///< tiles or voxels that needed their own evaluation
    uint64_t insideTiles = 0;       ///< tiles set inside (any level)
    uint64_t insideVoxels = 0;      ///< inactive leaf voxels set inside
    uint64_t leavesCreated = 0;     ///< tiles split into leaves because their sign changes inside
};

/// @brief Gives every inactive value of a narrow-band level set (tiles at every level and
///        inactive voxels of leaves) the sign of the winding number: −background where
///        |w| > 1/2, +background elsewhere. The replacement of OpenVDB's signedFloodFill for
///        open and broken meshes.
///
/// Precondition: every voxel whose centre is closer than 1 voxel to the surface is active (the
/// level set's band is at least 1 voxel wide on both sides, exact there). Then an inactive tile
/// holds no surface, and neither does the segment between two face-adjacent inactive voxels or
/// tiles, so w along it changes by at most its length times gradientBound() (no jump): within
/// each node, face-connected groups of inactive tiles (and, within each leaf, of inactive
/// voxels) are signed from one evaluation at a representative and a bound over the hops from
/// it; a tile or voxel the bound cannot decide gets its own evaluation, and a tile whose sign
/// may change inside is split (down to voxels). The sign is exact wherever ||w| − 1/2| exceeds
/// the estimate's error plus kWindingTolerance; nearer to 1/2 it is the estimate's verdict.
/// Regions outside the mesh's bounding box (no node of the tree there) stay outside.
/// Active values are not changed. Deterministic, parallel over nodes.
/// @param[in,out] grid   the level set (GRID_LEVEL_SET, world-unit values, linear transform)
/// @param[in]     fwn    the fast winding number of the mesh the grid was made from (the same
///                       world units)
/// @param[in]     meshBounds  the mesh's bounding box, world units
/// @param[out]    stats  optional counters
/// @param[in]     interrupter  optional; polled by work done. When it asks to stop,
///                       InterruptedError is thrown and the grid is left partly signed.
void signInactiveByWindingNumber(openvdb::FloatGrid& grid, const FastWindingNumber& fwn, const BBoxd& meshBounds,
                                 WindingSignStats* stats = nullptr,
                                 openvdb::util::NullInterrupter* interrupter = nullptr);

/// The margin (in winding number) by which a value carried from an estimate (by a bound or a
/// first-order model) must stay away from ±1/2 to be decided without an estimate of its own: it
/// absorbs the error of the estimate it was carried from (measured below 1e-2, typically 2e-3,
/// at the default accuracy).
constexpr double kWindingTolerance = 0.02;

} // namespace levelforge
