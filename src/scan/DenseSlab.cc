// SPDX-License-Identifier: Apache-2.0
// Dense slabs and the CPU slab backend. See DenseSlab.h.
#include <levelforge/scan/DenseSlab.h>
#include <levelforge/core/TriangleDistance.h>

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>

namespace levelforge {

SlabTriangles SlabTriangles::build(const TriangleMesh& mesh, const PseudoNormals& normals, double voxelSize)
{
    SlabTriangles s;
    s.voxelSize = voxelSize;
    const size_t nt = mesh.triangles.size();
    s.corners.resize(3 * nt);
    s.normals.resize(7 * nt);
    for (size_t t = 0; t < nt; ++t) {
        for (int k = 0; k < 3; ++k) s.corners[3 * t + k] = mesh.points[mesh.triangles[t][k]];
        for (int f = 0; f < 7; ++f) s.normals[7 * t + f] = normals.normal(uint32_t(t), TriangleFeature(f));
    }
    return s;
}

void DenseSlab::reset(const openvdb::CoordBBox& b)
{
    box = b;
    const size_t n = size_t(b.volume());
    dist.assign(n, std::numeric_limits<double>::infinity());
    tri.assign(n, kNone);
    rasterized = 0;
}

void SlabBackend::fillBatch(const SlabJob* jobs, size_t n, const SlabTriangles& tris) const
{
    tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 1), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t i = r.begin(); i != r.end(); ++i) fill(*jobs[i].slab, jobs[i].items, jobs[i].count, tris);
    });
}

bool crossSectionSpan(const CrossSection& cs, double y, double tol, double& xl, double& xr)
{
    xl = std::numeric_limits<double>::infinity();
    xr = -xl;
    const uint32_t n = cs.count;
    for (uint32_t i = 0; i < n; ++i) {
        const uint32_t j = (i + 1) % n;
        const double ax = cs.x[i], ay = cs.y[i], bx = cs.x[j], by = cs.y[j];
        const double lo = std::min(ay, by), hi = std::max(ay, by);
        if (y < lo - tol || y > hi + tol) continue;
        if (hi - lo <= 1e-12) {
            xl = std::min({xl, ax, bx});
            xr = std::max({xr, ax, bx});
            continue;
        }
        const double t = std::clamp((y - ay) / (by - ay), 0.0, 1.0);
        const double x = ax + t * (bx - ax);
        xl = std::min(xl, x);
        xr = std::max(xr, x);
    }
    return xl <= xr;
}

void CpuSlabBackend::fill(DenseSlab& slab, const CrossSection* items, size_t count, const SlabTriangles& tris) const
{
    constexpr double tol = 1e-7; // voxels
    const double h = tris.voxelSize;
    const openvdb::Coord lo = slab.box.min(), hi = slab.box.max();
    std::vector<double> best(slab.size(), std::numeric_limits<double>::infinity());
    uint64_t rasterized = 0;
    for (size_t it = 0; it < count; ++it) {
        const CrossSection& cs = items[it];
        if (cs.count == 0 || cs.z < lo.z() || cs.z > hi.z()) continue;
        double ymin = cs.y[0], ymax = cs.y[0];
        for (uint32_t i = 1; i < cs.count; ++i) { ymin = std::min(ymin, cs.y[i]); ymax = std::max(ymax, cs.y[i]); }
        const int y0 = std::max(lo.y(), int(std::ceil(ymin - tol)));
        const int y1 = std::min(hi.y(), int(std::floor(ymax + tol)));
        const uint32_t t = cs.triangle;
        const Vec3d& A = tris.corners[3 * size_t(t)];
        const Vec3d& B = tris.corners[3 * size_t(t) + 1];
        const Vec3d& C = tris.corners[3 * size_t(t) + 2];
        for (int y = y0; y <= y1; ++y) {
            double xl, xr;
            if (!crossSectionSpan(cs, double(y), tol, xl, xr)) continue;
            const int x0 = std::max(lo.x(), int(std::ceil(xl - tol)));
            const int x1 = std::min(hi.x(), int(std::floor(xr + tol)));
            for (int x = x0; x <= x1; ++x) {
                ++rasterized;
                const openvdb::Coord c(x, y, cs.z);
                const size_t idx = slab.index(c);
                const Vec3d p(double(x) * h, double(y) * h, double(cs.z) * h);
                const TriangleClosestPoint cp = closestPointOnTriangle(p, A, B, C);
                if (cp.distanceSqr < best[idx] || (cp.distanceSqr == best[idx] && t < slab.tri[idx])) {
                    best[idx] = cp.distanceSqr;
                    slab.tri[idx] = t;
                    const Vec3d& n = tris.normals[7 * size_t(t) + size_t(cp.feature)];
                    const double s = (p - cp.point).dot(n) < 0.0 ? -1.0 : 1.0;
                    slab.dist[idx] = std::sqrt(cp.distanceSqr) * s;
                }
            }
        }
    }
    slab.rasterized += rasterized;
}

} // namespace levelforge
