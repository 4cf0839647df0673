// SPDX-License-Identifier: Apache-2.0
// ADF reconstruction (Yin, Liu, Wu 2011 on the VDB tile hierarchy; see AdaptiveDistanceField.h):
// which cell holds a point, the lattice values (stored or hanging) and the C0 trilinear
// interpolation. Shared by the builder, the queries, the level-set conversion and CSG.
#include "adf/AdfInternal.h"

#include <levelforge/core/Exceptions.h>

#include <algorithm>
#include <cmath>
#include <string>

namespace levelforge {
namespace adf_internal {

bool Reconstruction::subdividedIn(const FloatLeaf& leaf, int x0, int y0, int z0, int n)
{
    const auto& m = leaf.getValueMask();
    const uint64_t zb = ((uint64_t(1) << n) - 1) << z0;
    uint64_t pat = 0;
    for (int y = y0; y < y0 + n; ++y) pat |= zb << (8 * y);
    for (int x = x0; x < x0 + n; ++x)
        if (m.template getWord<uint64_t>(openvdb::Index(x)) & pat) return true;
    return false;
}

CellInfo Reconstruction::cellAt(const Coord& c)
{
    const Internal1* n1 = mAcc.template probeConstNode<Internal1>(c);
    if (!n1) return {128, Coord(c.x() & ~127, c.y() & ~127, c.z() & ~127)};
    const FloatLeaf* leaf = mAcc.probeConstLeaf(c);
    if (!leaf) return {8, Coord(c.x() & ~7, c.y() & ~7, c.z() & ~7)};
    return cellInLeaf(*leaf, c);
}

CellInfo cellInLeaf(const FloatLeaf& leaf, const Coord& c)
{
    const int lx = c.x() & 7, ly = c.y() & 7, lz = c.z() & 7;
    if (!Reconstruction::subdividedIn(leaf, lx & ~3, ly & ~3, lz & ~3, 4))
        return {4, Coord(c.x() & ~3, c.y() & ~3, c.z() & ~3)};
    if (!Reconstruction::subdividedIn(leaf, lx & ~1, ly & ~1, lz & ~1, 2))
        return {2, Coord(c.x() & ~1, c.y() & ~1, c.z() & ~1)};
    return {1, c};
}

bool Reconstruction::stored(const Coord& p, float& v)
{
    if (const FloatLeaf* leaf = mAcc.probeConstLeaf(p)) {
        v = leaf->getValue(p);
        return true;
    }
    if (mAcc.template probeConstNode<Internal1>(p)) {
        if ((p.x() & 7) || (p.y() & 7) || (p.z() & 7)) return false;
        v = mAcc.getValue(p);
        return true;
    }
    if (mAcc.template probeConstNode<Internal2>(p)) {
        if ((p.x() & 127) || (p.y() & 127) || (p.z() & 127)) return false;
        v = mAcc.getValue(p);
        return true;
    }
    // No node holds p: the tree was collapsed (e.g. pruned by another tool), and a root tile
    // covers it. A 128-aligned point is then a stored coarse sample (the tile's value), which
    // also ends the recursion of value() -> cellAt() -> value() for such points.
    if (!((p.x() & 127) || (p.y() & 127) || (p.z() & 127))) {
        v = mAcc.getValue(p);
        return true;
    }
    return false;
}

Coord Reconstruction::clampCell(const Coord& p) const
{
    const Coord& lo = mDomain.min();
    const Coord& hi = mDomain.max();
    return Coord(std::max(lo.x(), std::min(p.x(), hi.x() - 1)), std::max(lo.y(), std::min(p.y(), hi.y() - 1)),
                 std::max(lo.z(), std::min(p.z(), hi.z() - 1)));
}

double Reconstruction::value(const Coord& p)
{
    return valueAt(p, 0);
}

// Why this ends, for any tree (not only an ADF layout): stored() holds every cell's minimum
// corner (a 128-aligned point always, an 8-aligned point under an internal-1 node, every voxel
// of a leaf), so a point p that is not stored is not the origin of the cell X = cellAt(p) whose
// half-open box holds it; one of its coordinates then lies strictly inside X, so p is aligned to
// less than X.size while every corner of X is aligned to X.size at least. The cell of a corner
// that is not stored is therefore larger than X: sizes grow 1 < 2 < 4 < 8 < 128 along any chain
// of calls, at most kMaxDepth deep. That needs cellAt(p) of the point itself, also on the layer
// of storage past the domain's maximum faces: the cell of the clamped point (the in-domain cell
// below the face) has p as a corner when p is one of its face corners, and a tree whose storage
// on that layer is coarser than the cell (a leaf touching the maximum face; a tree that is not
// an ADF layout) made value(p) call value(p) again without end. Only the corners with a
// non-zero weight are read, so every corner read lies inside the domain's lattice [min, max].
double Reconstruction::valueAt(const Coord& p, int depth)
{
    float stv;
    if (stored(p, stv)) return stv;
    if (depth >= kMaxDepth) {
        // Unreachable by the argument above; a defensive stop rather than a stack overflow.
        throw Error("ADF reconstruction: the value of lattice point (" + std::to_string(p.x()) + ", " +
                    std::to_string(p.y()) + ", " + std::to_string(p.z()) + ")" +
                    " depends on itself (the tree is not an ADF layout)");
    }
    bool inside = true;
    for (int k = 0; k < 3; ++k) inside = inside && p[k] >= mDomain.min()[k] && p[k] <= mDomain.max()[k];
    if (!inside) {
        // Outside the lattice (a direct latticeValue() query): the trilinear extension of the
        // in-domain cell nearest to it; its corners lie inside the lattice.
        return interpAt(cellAt(clampCell(p)), Vec3d(p.x(), p.y(), p.z()), nullptr, depth + 1);
    }
    const CellInfo X = cellAt(p);
    const int s = X.size;
    const Coord d = p - X.origin; // each in [0, s)
    double v[8];
    for (int k = 0; k < 8; ++k) {
        const int ox = (k >> 2) & 1, oy = (k >> 1) & 1, oz = k & 1;
        // a corner past p on an axis where p lies on the cell's minimum face has weight 0
        if ((ox && d.x() == 0) || (oy && d.y() == 0) || (oz && d.z() == 0)) {
            v[k] = 0.0;
            continue;
        }
        v[k] = valueAt(X.origin + Coord(ox * s, oy * s, oz * s), depth + 1);
    }
    return trilinear(v, Vec3d(d.x(), d.y(), d.z()) / double(s), nullptr);
}

double Reconstruction::interp(const CellInfo& X, const Vec3d& q, Vec3d* dvdt)
{
    return interpAt(X, q, dvdt, 0);
}

double Reconstruction::interpAt(const CellInfo& X, const Vec3d& q, Vec3d* dvdt, int depth)
{
    const int s = X.size;
    double v[8];
    for (int k = 0; k < 8; ++k) {
        const Coord c = X.origin + Coord(((k >> 2) & 1) * s, ((k >> 1) & 1) * s, (k & 1) * s);
        v[k] = valueAt(c, depth);
    }
    return trilinear(v, (q - Vec3d(X.origin.x(), X.origin.y(), X.origin.z())) / double(s), dvdt);
}

double Reconstruction::trilinear(const double* v, const Vec3d& t, Vec3d* dvdt)
{
    const double tx = t[0], ty = t[1], tz = t[2];
    // v index = (x << 2) | (y << 1) | z
    const double c00 = v[0] + (v[4] - v[0]) * tx, c01 = v[1] + (v[5] - v[1]) * tx;
    const double c10 = v[2] + (v[6] - v[2]) * tx, c11 = v[3] + (v[7] - v[3]) * tx;
    const double c0 = c00 + (c10 - c00) * ty, c1 = c01 + (c11 - c01) * ty;
    if (dvdt) {
        const double ax = (v[4] - v[0]) * (1 - ty) * (1 - tz) + (v[6] - v[2]) * ty * (1 - tz) +
                          (v[5] - v[1]) * (1 - ty) * tz + (v[7] - v[3]) * ty * tz;
        const double ay = (c10 - c00) * (1 - tz) + (c11 - c01) * tz;
        const double az = c1 - c0;
        *dvdt = Vec3d(ax, ay, az);
    }
    return c0 + (c1 - c0) * tz;
}

double Reconstruction::distanceIndex(const Vec3d& q, Vec3d* gradIndex, int* levelOut)
{
    const Coord& lo = mDomain.min();
    const Coord& hi = mDomain.max();
    Vec3d qc = q;
    for (int k = 0; k < 3; ++k) qc[k] = std::max(double(lo[k]), std::min(q[k], double(hi[k])));
    const double extra = (q - qc).length();
    const Coord c = clampCell(Coord(int(std::floor(qc[0])), int(std::floor(qc[1])), int(std::floor(qc[2]))));
    const CellInfo X = cellAt(c);
    if (levelOut) *levelOut = levelOfSize(X.size);
    const int s = X.size;
    Vec3d dvdt;
    double d;
    const FloatLeaf* leaf = s == 1 ? mAcc.probeConstLeaf(c) : nullptr;
    if (leaf && (c.x() & 7) < 7 && (c.y() & 7) < 7 && (c.z() & 7) < 7) {
        // fast path: the 8 corners are voxels of the same leaf
        const openvdb::Index o = FloatLeaf::coordToOffset(c);
        const float* buf = leaf->buffer().data();
        const double v[8] = {buf[o], buf[o + 1], buf[o + 8], buf[o + 9], buf[o + 64], buf[o + 65], buf[o + 72], buf[o + 73]};
        d = trilinear(v, qc - Vec3d(c.x(), c.y(), c.z()), &dvdt);
    } else {
        d = interp(X, qc, &dvdt);
    }
    if (gradIndex) *gradIndex = dvdt / double(s);
    return d + extra;
}

int levelOfSize(int size)
{
    switch (size) {
    case 1: return 0;
    case 2: return 1;
    case 4: return 2;
    case 8: return 3;
    case 128: return 4;
    default: return -1;
    }
}

} // namespace adf_internal
} // namespace levelforge
