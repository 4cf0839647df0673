// SPDX-License-Identifier: Apache-2.0
// Angle-weighted pseudonormals (Bærentzen & Aanæs 2005). See PseudoNormals.h.
#include <levelforge/core/PseudoNormals.h>

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

namespace levelforge {

PseudoNormals::PseudoNormals(const TriangleMesh& mesh) : mMesh(mesh)
{
    const size_t nt = mesh.triangles.size(), nv = mesh.points.size();
    mFace.assign(nt, Vec3d(0.0));
    mEdge.assign(3 * nt, Vec3d(0.0));
    mVertex.assign(nv, Vec3d(0.0));

    // Face normals and per-corner angles.
    std::vector<double> angle(3 * nt, 0.0);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, nt, 4096), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t t = r.begin(); t != r.end(); ++t) {
            const Vec3I& tri = mesh.triangles[t];
            const Vec3d& a = mesh.points[tri[0]];
            const Vec3d& b = mesh.points[tri[1]];
            const Vec3d& c = mesh.points[tri[2]];
            Vec3d n = (b - a).cross(c - a);
            const double len = n.length();
            if (!(len > 0.0) || !std::isfinite(len)) continue; // degenerate: zero normal
            mFace[t] = n / len;
            const Vec3d* p[3] = {&a, &b, &c};
            for (int k = 0; k < 3; ++k) {
                Vec3d u = *p[(k + 1) % 3] - *p[k], v = *p[(k + 2) % 3] - *p[k];
                const double lu = u.length(), lv = v.length();
                if (lu > 0.0 && lv > 0.0) {
                    const double cosv = std::clamp(u.dot(v) / (lu * lv), -1.0, 1.0);
                    angle[3 * t + k] = std::acos(cosv);
                }
            }
        }
    });

    // Vertex pseudonormals: serial accumulation keeps the sum order fixed (deterministic).
    for (size_t t = 0; t < nt; ++t) {
        if (mFace[t].lengthSqr() == 0.0) continue;
        for (int k = 0; k < 3; ++k) mVertex[mesh.triangles[t][k]] += mFace[t] * angle[3 * t + k];
    }

    // Edge pseudonormals: sum of the normals of all faces sharing the (undirected) edge. The
    // edge slots are bucketed by their smaller vertex (counting sort, O(E)); within a bucket they
    // stay in slot order, so each sum is taken in ascending slot order, as a global sort by
    // (edge, slot) would.
    std::vector<uint32_t> first(nv + 1, 0);
    for (size_t t = 0; t < nt; ++t) {
        if (mFace[t].lengthSqr() == 0.0) continue;
        for (int k = 0; k < 3; ++k)
            ++first[std::min(mesh.triangles[t][k], mesh.triangles[t][(k + 1) % 3]) + 1];
    }
    for (size_t v = 0; v < nv; ++v) first[v + 1] += first[v];
    struct EdgeRef { uint32_t other, slot; };
    std::vector<EdgeRef> refs(first[nv]);
    {
        std::vector<uint32_t> fill(first.begin(), first.end() - 1);
        for (size_t t = 0; t < nt; ++t) {
            if (mFace[t].lengthSqr() == 0.0) continue;
            for (int k = 0; k < 3; ++k) {
                uint32_t u = mesh.triangles[t][k], v = mesh.triangles[t][(k + 1) % 3];
                if (u > v) std::swap(u, v);
                refs[fill[u]++] = {v, uint32_t(3 * t + k)};
            }
        }
    }
    tbb::parallel_for(tbb::blocked_range<size_t>(0, nv, 4096), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t u = r.begin(); u != r.end(); ++u) {
            EdgeRef* b = refs.data() + first[u];
            EdgeRef* e = refs.data() + first[u + 1];
            // stable by the other vertex: slots of one edge keep their ascending order
            std::stable_sort(b, e, [](const EdgeRef& x, const EdgeRef& y) { return x.other < y.other; });
            for (EdgeRef* i = b; i != e;) {
                EdgeRef* j = i;
                Vec3d sum(0.0);
                for (; j != e && j->other == i->other; ++j) sum += mFace[j->slot / 3];
                for (EdgeRef* k = i; k != j; ++k) mEdge[k->slot] = sum;
                i = j;
            }
        }
    });
}

const Vec3d& PseudoNormals::normal(uint32_t tri, TriangleFeature f) const
{
    switch (f) {
    case TriangleFeature::Face: return mFace[tri];
    case TriangleFeature::Vertex0: return mVertex[mMesh.triangles[tri][0]];
    case TriangleFeature::Vertex1: return mVertex[mMesh.triangles[tri][1]];
    case TriangleFeature::Vertex2: return mVertex[mMesh.triangles[tri][2]];
    case TriangleFeature::Edge01: return edgeNormal(tri, 0);
    case TriangleFeature::Edge12: return edgeNormal(tri, 1);
    case TriangleFeature::Edge20: return edgeNormal(tri, 2);
    }
    return mFace[tri];
}

} // namespace levelforge
