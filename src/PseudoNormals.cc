// Angle-weighted pseudonormals (Bærentzen & Aanæs 2005). See PseudoNormals.h.
#include <levelforge/PseudoNormals.h>

#include <tbb/parallel_for.h>
#include <tbb/parallel_sort.h>

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

    // Edge pseudonormals: sum of the normals of all faces sharing the (undirected) edge.
    struct EdgeRef { uint64_t key; uint32_t slot; };
    std::vector<EdgeRef> refs;
    refs.reserve(3 * nt);
    for (size_t t = 0; t < nt; ++t) {
        if (mFace[t].lengthSqr() == 0.0) continue;
        for (int k = 0; k < 3; ++k) {
            uint64_t u = mesh.triangles[t][k], v = mesh.triangles[t][(k + 1) % 3];
            if (u > v) std::swap(u, v);
            refs.push_back({(u << 32) | v, uint32_t(3 * t + k)});
        }
    }
    tbb::parallel_sort(refs.begin(), refs.end(), [](const EdgeRef& x, const EdgeRef& y) {
        return x.key < y.key || (x.key == y.key && x.slot < y.slot);
    });
    for (size_t i = 0; i < refs.size();) {
        size_t j = i;
        Vec3d sum(0.0);
        for (; j < refs.size() && refs[j].key == refs[i].key; ++j) sum += mFace[refs[j].slot / 3];
        for (size_t k = i; k < j; ++k) mEdge[refs[k].slot] = sum;
        i = j;
    }
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
