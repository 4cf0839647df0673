// SPDX-License-Identifier: Apache-2.0
// Exact signed distance reference (BVH + brute force). See ExactReference.h.
#include <levelforge/reference/ExactReference.h>
#include <levelforge/core/TriangleDistance.h>

#include "detail/Bvh.h"

#include <openvdb/tree/LeafManager.h>

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>

namespace levelforge {

ExactReference::ExactReference(const TriangleMesh& mesh)
    : mMesh(mesh), mNormals(new PseudoNormals(mesh)), mBvh(new detail::Bvh)
{
    const size_t nt = mesh.triangles.size();
    std::vector<BBoxd> boxes(nt);
    std::vector<Vec3d> centroid(nt);
    std::vector<uint32_t> ids;
    for (uint32_t t = 0; t < nt; ++t) {
        if (mNormals->isDegenerate(t)) continue;
        BBoxd b;
        for (int k = 0; k < 3; ++k) b.expand(mesh.points[mesh.triangles[t][k]]);
        boxes[t] = b;
        centroid[t] = b.getCenter();
        ids.push_back(t);
    }
    // Top-down median split on the longest axis of the centroid box; leaves of <= 4 triangles.
    mBvh->build(
        std::move(ids), boxes, 4,
        [&](const uint32_t* first, size_t count, const detail::Bvh::Node&) {
            BBoxd cbox;
            for (size_t i = 0; i < count; ++i) cbox.expand(centroid[first[i]]);
            return int(cbox.maxExtent());
        },
        [&](uint32_t a, uint32_t b, int axis) {
            return centroid[a][axis] < centroid[b][axis] || (centroid[a][axis] == centroid[b][axis] && a < b);
        });
}

ExactReference::~ExactReference() = default;

namespace reference_internal {
/// Running minimum over triangles; ties go to the lowest triangle id (deterministic).
struct Closest
{
    const TriangleMesh& mesh;
    const Vec3d& p;
    double d2 = std::numeric_limits<double>::infinity();
    TriangleClosestPoint cp{Vec3d(0.0), 0.0, TriangleFeature::Face};
    uint32_t tri = ~0u;

    Closest(const TriangleMesh& m, const Vec3d& q) : mesh(m), p(q) {}
    void consider(uint32_t t)
    {
        const Vec3I& v = mesh.triangles[t];
        const TriangleClosestPoint c = closestPointOnTriangle(p, mesh.points[v[0]], mesh.points[v[1]], mesh.points[v[2]]);
        if (c.distanceSqr < d2 || (c.distanceSqr == d2 && t < tri)) { d2 = c.distanceSqr; cp = c; tri = t; }
    }
    ExactReference::Result result(const PseudoNormals& normals) const
    {
        ExactReference::Result r;
        if (tri == ~0u) return r;
        r.triangle = tri;
        r.closestPoint = cp.point;
        r.distance = std::sqrt(d2) * (normals.isInside(tri, cp, p) ? -1.0 : 1.0);
        return r;
    }
};
} // namespace reference_internal

ExactReference::Result ExactReference::query(const Vec3d& p) const
{
    if (mBvh->empty()) return Result();
    reference_internal::Closest best(mMesh, p);
    // Visits boxes at exactly the best distance too: they may hold a lower-id tie (the same
    // answer as bruteForce).
    mBvh->nearest<true>(p, best.d2, [&](const uint32_t* ids, uint32_t n) {
        for (uint32_t i = 0; i < n; ++i) best.consider(ids[i]);
    });
    return best.result(*mNormals);
}

ExactReference::Result ExactReference::bruteForce(const Vec3d& p) const
{
    reference_internal::Closest best(mMesh, p);
    for (uint32_t t : mBvh->order()) best.consider(t);
    return best.result(*mNormals);
}

double ExactReference::windingNumber(const Vec3d& q) const
{
    // Van Oosterom & Strackee (1983): tan(Ω/2) = a·(b×c) / (|a||b||c| + (a·b)|c| + (b·c)|a| + (c·a)|b|)
    double sum = 0.0;
    for (uint32_t t = 0; t < mMesh.triangles.size(); ++t) {
        if (mNormals->isDegenerate(t)) continue;
        const Vec3I& v = mMesh.triangles[t];
        const Vec3d a = mMesh.points[v[0]] - q, b = mMesh.points[v[1]] - q, c = mMesh.points[v[2]] - q;
        const double det = a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) +
                           a[2] * (b[0] * c[1] - b[1] * c[0]);
        if (det == 0.0) continue;
        const double la = std::sqrt(a.dot(a)), lb = std::sqrt(b.dot(b)), lc = std::sqrt(c.dot(c));
        const double den = la * lb * lc + a.dot(b) * lc + b.dot(c) * la + c.dot(a) * lb;
        sum += 2.0 * std::atan2(det, den);
    }
    return sum / (4.0 * 3.14159265358979323846);
}

WindingSignReport compareSignsToWindingNumber(const openvdb::FloatGrid& grid, const ExactReference& reference,
                                              double margin, uint64_t stride, bool inactive)
{
    using openvdb::Coord;
    if (stride == 0) stride = 1;
    struct Acc { WindingSignReport r; };
    tbb::enumerable_thread_specific<Acc> tls;
    const auto judge = [&](Acc& acc, const Vec3d& world, float value) {
        if (value == 0.0f) return;
        const double w = reference.windingNumber(world);
        ++acc.r.checked;
        acc.r.maxAbsW = std::max(acc.r.maxAbsW, std::abs(w));
        if (!(std::abs(std::abs(w) - 0.5) > margin)) { ++acc.r.undecisive; return; }
        ++acc.r.decisive;
        if ((std::abs(w) > 0.5) != (value < 0.0f)) ++acc.r.signErrors;
    };
    const auto sampled = [stride](const Coord& c) {
        return stride <= 1 || (uint64_t(c.x() * 73856093u ^ c.y() * 19349663u ^ c.z() * 83492791u) % stride) == 0;
    };
    openvdb::tree::LeafManager<const openvdb::FloatTree> leafs(grid.tree());
    tbb::parallel_for(tbb::blocked_range<size_t>(0, leafs.leafCount(), 4), [&](const tbb::blocked_range<size_t>& r) {
        Acc& acc = tls.local();
        for (size_t l = r.begin(); l != r.end(); ++l) {
            for (auto it = leafs.leaf(l).cbeginValueAll(); it; ++it) {
                if (!inactive && !it.isValueOn()) continue;
                const Coord c = it.getCoord();
                if (!sampled(c)) continue;
                judge(acc, grid.indexToWorld(c), *it);
            }
        }
    });
    std::vector<std::pair<Vec3d, float>> tiles;
    if (inactive) {
        auto it = grid.tree().cbeginValueAll();
        it.setMaxDepth(openvdb::FloatTree::ValueAllCIter::LEAF_DEPTH - 1); // tiles only
        for (; it; ++it) {
            if (it.isVoxelValue()) continue;
            const openvdb::CoordBBox b = it.getBoundingBox();
            if (!sampled(b.min())) continue;
            const Vec3d centre = (Vec3d(b.min().x(), b.min().y(), b.min().z()) + Vec3d(b.max().x(), b.max().y(), b.max().z())) * 0.5;
            tiles.emplace_back(grid.indexToWorld(centre), *it);
        }
    }
    tbb::parallel_for(tbb::blocked_range<size_t>(0, tiles.size(), 1), [&](const tbb::blocked_range<size_t>& r) {
        Acc& acc = tls.local();
        for (size_t i = r.begin(); i != r.end(); ++i) judge(acc, tiles[i].first, tiles[i].second);
    });
    WindingSignReport rep;
    for (const Acc& a : tls) {
        rep.checked += a.r.checked;
        rep.decisive += a.r.decisive;
        rep.signErrors += a.r.signErrors;
        rep.undecisive += a.r.undecisive;
        rep.maxAbsW = std::max(rep.maxAbsW, a.r.maxAbsW);
    }
    return rep;
}

BandErrorReport compareToReference(const openvdb::FloatGrid& grid, const ExactReference& reference,
                                   double exteriorWidth, double interiorWidth, uint64_t stride)
{
    using openvdb::Coord;
    const double h = grid.voxelSize()[0];
    const double tol = 1e-6; // voxels: boundary tolerance for band membership and sign
    struct Acc { uint64_t n = 0, sign = 0, extra = 0; double maxE = 0, sumE = 0; std::vector<Coord> missing; };
    tbb::enumerable_thread_specific<Acc> tls;
    openvdb::tree::LeafManager<const openvdb::FloatTree> leafs(grid.tree());
    if (stride == 0) stride = 1;
    tbb::parallel_for(tbb::blocked_range<size_t>(0, leafs.leafCount(), 16), [&](const tbb::blocked_range<size_t>& r) {
        Acc& acc = tls.local();
        openvdb::tree::ValueAccessor<const openvdb::FloatTree> va(grid.tree());
        for (size_t l = r.begin(); l != r.end(); ++l) {
            for (auto it = leafs.leaf(l).cbeginValueOn(); it; ++it) {
                const Coord c = it.getCoord();
                if (stride > 1 && (uint64_t(c.x() * 73856093u ^ c.y() * 19349663u ^ c.z() * 83492791u) % stride) != 0)
                    continue;
                const Vec3d wp = grid.indexToWorld(c);
                const double ref = reference.signedDistance(wp) / h;
                const double val = double(*it) / h;
                const double e = std::abs(val - ref);
                ++acc.n;
                acc.sumE += e;
                acc.maxE = std::max(acc.maxE, e);
                if (std::abs(ref) > tol && ((ref < 0) != (val < 0))) ++acc.sign;
                if (ref >= exteriorWidth + tol || ref <= -interiorWidth - tol) ++acc.extra;
                static const Coord nb[6] = {Coord(1, 0, 0), Coord(-1, 0, 0), Coord(0, 1, 0),
                                            Coord(0, -1, 0), Coord(0, 0, 1), Coord(0, 0, -1)};
                for (const Coord& o : nb) {
                    const Coord q = c + o;
                    if (va.isValueOn(q)) continue;
                    const double rq = reference.signedDistance(grid.indexToWorld(q)) / h;
                    if (rq < exteriorWidth - tol && rq > -interiorWidth + tol) acc.missing.push_back(q);
                }
            }
        }
    });
    BandErrorReport rep;
    std::vector<Coord> missing;
    for (Acc& a : tls) {
        rep.checkedVoxels += a.n;
        rep.signErrors += a.sign;
        rep.extraVoxels += a.extra;
        rep.maxError = std::max(rep.maxError, a.maxE);
        rep.meanError += a.sumE;
        missing.insert(missing.end(), a.missing.begin(), a.missing.end());
    }
    std::sort(missing.begin(), missing.end());
    rep.missingVoxels = uint64_t(std::unique(missing.begin(), missing.end()) - missing.begin());
    if (rep.checkedVoxels) rep.meanError /= double(rep.checkedVoxels);
    return rep;
}

} // namespace levelforge
