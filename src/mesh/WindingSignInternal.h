// SPDX-License-Identifier: Apache-2.0
// Private helpers of the winding-number sign (mesh/FastWindingNumber.h): the verdict of an
// estimate with an error bound, breadth-first components on the 8³ / 16³ / 32³ grids of VDB
// nodes, and the tile pass shared by meshToLevelSet() and signInactiveByWindingNumber().
#pragma once

#include <levelforge/mesh/FastWindingNumber.h>

#include <openvdb/openvdb.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <vector>

namespace levelforge {
/// Private access to the fast winding number's triangles (leaf order).
struct FastWindingNumberAccess
{
    /// Leaf-order indices of the triangles whose bounding box meets [lo, hi] (world units).
    static void gather(const FastWindingNumber& f, const Vec3d& lo, const Vec3d& hi, std::vector<uint32_t>& out);
    /// The 9 coordinates (a, b, c) of triangle i (leaf order).
    static const double* triangle(const FastWindingNumber& f, uint32_t i);
    /// hessianBound() over [lo, hi] (world units) from the boundary-current edges that do not
    /// meet [skipLo, skipHi] only.
    static double hessianBoundBeyond(const FastWindingNumber& f, const Vec3d& lo, const Vec3d& hi, const Vec3d& skipLo,
                                     const Vec3d& skipHi);
    /// ∇w at q of the straight current element a → b carrying signedCurrent (Biot–Savart, 1/4π
    /// included; the convention of FastWindingNumber::gradient()).
    static Vec3d edgeGradient(const Vec3d& a, const Vec3d& b, double signedCurrent, const Vec3d& q);
    /// Bound of the operator norm of ∇∇w over [lo, hi] from the element a → b carrying
    /// ±current (+infinity when it meets the box).
    static double edgeHessianBound(const Vec3d& a, const Vec3d& b, double current, const Vec3d& lo, const Vec3d& hi);
    /// Distance from the segment [a, b] to the box [lo, hi], a lower bound within 1e-12 relative.
    static double segmentBoxDistance(const Vec3d& a, const Vec3d& b, const Vec3d& lo, const Vec3d& hi);
    /// True when the segment [a, b] meets the box [lo, hi].
    static bool segmentMeetsBox(const Vec3d& a, const Vec3d& b, const Vec3d& lo, const Vec3d& hi);
    /// Boundary-current edge i (0 <= i < currentEdges()): its ends and its signed current.
    static void currentEdge(const FastWindingNumber& f, size_t i, Vec3d& a, Vec3d& b, double& signedCurrent);
};
} // namespace levelforge

namespace levelforge::winding_internal {

/// The sum of triangles' solid angles seen from one point with one atan2 for all of them:
/// triangleSolidAngle() is 2 atan2(num, den) (Van Oosterom–Strackee), and Σ atan2(num_i, den_i)
/// is the argument of the product Π (den_i + i num_i) plus 2π for every time the running
/// product's argument passes ±π. A term with num = 0 (the point in the triangle's plane) adds 0,
/// as triangleSolidAngle() does. The product is renormalised at every step (no overflow). The
/// turns are read from the signs of the imaginary parts: a pass past ±π can only happen where
/// the two terms of the new imaginary part have the same sign, so rounding cannot hide one, and
/// the result equals the sum of atan2s up to rounding (~1e-15 per term), never by a multiple
/// of 2π.
struct SolidAngleSum
{
    double re = 1.0, im = 0.0;
    int turns = 0;

    /// Adds the solid angle of the triangle (a, b, c) seen from @p p (3 coordinates each).
    inline void add(const double* a0, const double* b0, const double* c0, const double* p)
    {
        double num, den;
        if (terms(a0, b0, c0, p, num, den)) addTerm(num, den);
    }
    /// Van Oosterom–Strackee's numerator a·(b×c) and denominator of the triangle (a, b, c) seen
    /// from @p p (its solid angle is 2 atan2(num, den)); false when num = 0 (p in its plane).
    static inline bool terms(const double* a0, const double* b0, const double* c0, const double* p, double& num,
                             double& den)
    {
        const double ax = a0[0] - p[0], ay = a0[1] - p[1], az = a0[2] - p[2];
        const double bx = b0[0] - p[0], by = b0[1] - p[1], bz = b0[2] - p[2];
        const double cx = c0[0] - p[0], cy = c0[1] - p[1], cz = c0[2] - p[2];
        num = ax * (by * cz - bz * cy) + ay * (bz * cx - bx * cz) + az * (bx * cy - by * cx);
        if (num == 0.0) return false;
        const double la = std::sqrt(ax * ax + ay * ay + az * az), lb = std::sqrt(bx * bx + by * by + bz * bz),
                     lc = std::sqrt(cx * cx + cy * cy + cz * cz);
        den = la * lb * lc + (ax * bx + ay * by + az * bz) * lc + (bx * cx + by * cy + bz * cz) * la +
              (cx * ax + cy * ay + cz * az) * lb;
        return true;
    }
    /// Adds atan2(num, den) (num != 0).
    inline void addTerm(double num, double den)
    {
        const double r = re * den - im * num, i = re * num + im * den;
        if (num > 0.0 && im >= 0.0 && i < 0.0) ++turns;
        else if (num < 0.0 && im < 0.0 && (i > 0.0 || (i == 0.0 && r < 0.0))) --turns;
        const double s = 1.0 / (std::abs(r) + std::abs(i));
        re = r * s;
        im = i * s + 0.0; // −0 → +0, so that atan2 reads an argument of π as +π
    }
    /// Σ of the solid angles added (steradians).
    double value() const { return 2.0 * (std::atan2(im, re) + 2.0 * 3.14159265358979323846 * double(turns)); }
};

/// 1: |w| > 1/2 for every w within @p err of @p w (inside for sure); 0: |w| < 1/2 for all of
/// them (outside for sure); -1: undecided.
inline int verdict(double w, double err)
{
    const double a = std::abs(w);
    if (a - err > 0.5) return 1;
    if (a + err < 0.5) return 0;
    return -1;
}

/// The inside rule applied to an estimate: |w| > 1/2.
inline bool insideByEstimate(double w) { return std::abs(w) > 0.5; }

/// A value carried from an estimate with a rigorous bound `carried` on what the carrying added
/// (gradient bound × path, or a first-order model's remainder): 1 / 0 when the interval
/// w ± (kWindingTolerance + carried) excludes ±1/2, or when carried <= kWindingTolerance (then
/// the value is as good as an estimate of its own, and its verdict |w| > 1/2 is taken); -1
/// otherwise. So a decided sign is exact wherever ||w| − 1/2| > 2 kWindingTolerance.
inline int decide(double w, double carried)
{
    const int v = verdict(w, kWindingTolerance + carried);
    if (v >= 0) return v;
    return carried <= kWindingTolerance ? (insideByEstimate(w) ? 1 : 0) : -1;
}

/// The change of w along the segment P→Q (world units) from its crossings of the triangles
/// @p tris (leaf-order indices, which must include every triangle the segment meets): +1 for each
/// crossing of a triangle's interior from its front (the side its counter-clockwise normal
/// points to) to its back, −1 the other way. Returns false when a crossing is too close to call
/// (the segment passes within rounding of an edge or a vertex, or ends in a triangle's plane
/// where it meets the triangle); the caller then perturbs the segment or evaluates w.
bool crossingChange(const FastWindingNumber& fwn, const std::vector<uint32_t>& tris, const Vec3d& P, const Vec3d& Q,
                    int& change);

/// Breadth-first search on an n³ grid (n = 1 << log2n) in OpenVDB offset order
/// ((x << 2 log2n) | (y << log2n) | z), 6-neighbours, restricted to cells with member[i] != 0
/// for which adjacent(i, j) holds. Starting from `start`, writes hops[i] (0 at start) for every
/// cell reached and lists them in `order` (BFS order, start first). `hops` must hold -1 at the
/// cells not visited yet; cells already labelled are not entered again.
template<typename Adjacent>
void bfs(int log2n, uint32_t start, const uint8_t* member, Adjacent&& adjacent, int32_t* hops,
         std::vector<uint32_t>& order)
{
    const uint32_t n = 1u << log2n, mask = n - 1;
    order.clear();
    order.push_back(start);
    hops[start] = 0;
    for (size_t head = 0; head < order.size(); ++head) {
        const uint32_t i = order[head];
        const uint32_t x = i >> (2 * log2n), y = (i >> log2n) & mask, z = i & mask;
        const uint32_t nb[6] = {x > 0 ? i - (1u << (2 * log2n)) : ~0u, x < mask ? i + (1u << (2 * log2n)) : ~0u,
                                y > 0 ? i - (1u << log2n) : ~0u,       y < mask ? i + (1u << log2n) : ~0u,
                                z > 0 ? i - 1u : ~0u,                  z < mask ? i + 1u : ~0u};
        for (uint32_t j : nb) {
            if (j == ~0u || !member[j] || hops[j] >= 0 || !adjacent(i, j)) continue;
            hops[j] = hops[i] + 1;
            order.push_back(j);
        }
    }
}

/// The tile pass: signs every tile (root, level 2, level 1) of @p tree by the winding number,
/// and with @p leavesToo also the values of its leaves with |φ| >= exactBand (world units)
/// and every inactive leaf voxel (see signInactiveByWindingNumber()). Without leavesToo the
/// leaves are taken as fully signed (meshToLevelSet()'s winding band). New leaves are made
/// where a tile's sign changes inside it. The interrupter (if any) is polled by work done;
/// throws InterruptedError (the tree half signed) when it asks to stop.
void signTree(openvdb::FloatTree& tree, const openvdb::math::Transform& xform, const FastWindingNumber& fwn,
              const BBoxd& meshBounds, bool leavesToo, double exactBand, WindingSignStats& stats,
              openvdb::util::NullInterrupter* interrupter = nullptr);

/// The fast winding number the winding sign uses: that of @p mesh, except in one case, where it
/// is exact to leave a triangle out. When the mesh's whole boundary current is the boundary of
/// one of its triangles t (a lone open triangle beside closed parts: a stray vertex's, a broken
/// export's), w = w_rest + w_t with w_rest an integer (the rest has no boundary) and |w_t| < 1/2
/// (one triangle subtends less than 2π from any point off its plane, and 0 in it), so
/// |w| > 1/2 exactly where |w_rest| >= 1: t is left out, and the rest is signed as a closed mesh
/// is, without boundary current. @p leftOut: the triangle left out (its index), or -1.
std::unique_ptr<FastWindingNumber> signingWindingNumber(const TriangleMesh& mesh, const FastWindingNumberOptions& options,
                                                        int64_t& leftOut);

/// Activates every inactive negative value of @p tree: tiles stay tiles, leaf voxels keep their
/// values (fill interior). Returns the number of voxels activated (tiles counted by volume).
uint64_t activateInterior(openvdb::FloatTree& tree);

} // namespace levelforge::winding_internal
