// SPDX-License-Identifier: Apache-2.0
// Pseudonormals on demand for the exact band. See LazyPseudoNormals.h.
#include "mesh/LazyPseudoNormals.h"

#include <tbb/parallel_for.h>

namespace levelforge::mesh_internal {

LazyPseudoNormals::LazyPseudoNormals(const TriangleMesh& mesh) : mMesh(mesh)
{
    const size_t nt = mesh.triangles.size(), nv = mesh.points.size();
    mDegenerate.assign(nt, 0);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, nt, 8192), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t t = r.begin(); t != r.end(); ++t)
            mDegenerate[t] = faceNormalOf(mesh, uint32_t(t)).lengthSqr() == 0.0 ? 1 : 0;
    });
    // Counting sort of the corners of the non-degenerate triangles by vertex; a serial fill in
    // triangle order keeps each vertex's list ascending.
    mFirst.assign(nv + 1, 0);
    for (size_t t = 0; t < nt; ++t) {
        if (mDegenerate[t]) continue;
        for (int k = 0; k < 3; ++k) ++mFirst[mesh.triangles[t][k] + 1];
    }
    for (size_t v = 0; v < nv; ++v) mFirst[v + 1] += mFirst[v];
    mCorner.resize(mFirst[nv]);
    std::vector<uint32_t> fill(mFirst.begin(), mFirst.end() - 1);
    for (size_t t = 0; t < nt; ++t) {
        if (mDegenerate[t]) continue;
        for (int k = 0; k < 3; ++k) mCorner[fill[mesh.triangles[t][k]]++] = uint32_t(3 * t + k);
    }
}

Vec3d LazyPseudoNormals::vertexNormal(uint32_t v) const
{
    Vec3d sum(0.0);
    for (uint32_t i = mFirst[v]; i < mFirst[v + 1]; ++i) {
        const uint32_t t = mCorner[i] / 3, k = mCorner[i] % 3;
        const Vec3I& tri = mMesh.triangles[t];
        const Vec3d* p[3] = {&mMesh.points[tri[0]], &mMesh.points[tri[1]], &mMesh.points[tri[2]]};
        const Vec3d u = *p[(k + 1) % 3] - *p[k], w = *p[(k + 2) % 3] - *p[k];
        const double lu = u.length(), lw = w.length();
        double angle = 0.0;
        if (lu > 0.0 && lw > 0.0) angle = std::acos(std::clamp(u.dot(w) / (lu * lw), -1.0, 1.0));
        sum += faceNormal(t) * angle;
    }
    return sum;
}

Vec3d LazyPseudoNormals::edgeNormal(uint32_t t, int k) const
{
    const Vec3I& tri = mMesh.triangles[t];
    const uint32_t a = tri[k], b = tri[(k + 1) % 3];
    Vec3d sum(0.0);
    if (mDegenerate[t]) return sum; // PseudoNormals leaves a degenerate triangle's edges at zero
    for (uint32_t i = mFirst[a]; i < mFirst[a + 1]; ++i) {
        const uint32_t s = mCorner[i] / 3;
        const Vec3I& o = mMesh.triangles[s];
        if (o[0] == b || o[1] == b || o[2] == b) sum += faceNormal(s);
    }
    return sum;
}

Vec3d LazyPseudoNormals::normal(uint32_t t, TriangleFeature f) const
{
    switch (f) {
    case TriangleFeature::Face: return faceNormal(t);
    case TriangleFeature::Vertex0: return vertexNormal(mMesh.triangles[t][0]);
    case TriangleFeature::Vertex1: return vertexNormal(mMesh.triangles[t][1]);
    case TriangleFeature::Vertex2: return vertexNormal(mMesh.triangles[t][2]);
    case TriangleFeature::Edge01: return edgeNormal(t, 0);
    case TriangleFeature::Edge12: return edgeNormal(t, 1);
    case TriangleFeature::Edge20: return edgeNormal(t, 2);
    }
    return faceNormal(t);
}

} // namespace levelforge::mesh_internal
