// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Angle-weighted pseudonormals (Bærentzen & Aanæs, IEEE TVCG 2005).
///
/// For a closed, consistently oriented 2-manifold, the sign of dot(p - c, n) where c is the
/// closest point on the mesh and n is the pseudonormal of the feature containing c (face normal,
/// edge normal = sum of the two incident face normals, vertex normal = sum of incident face
/// normals weighted by their incident angles) tells inside from outside exactly. This is the sign
/// rule of Chang et al. §4.2. Non-manifold edges sum all incident face normals; boundary edges
/// use their single face's normal.
#pragma once

#include <levelforge/core/TriangleFeature.h>
#include <levelforge/core/TriangleMesh.h>

#include <cstdint>
#include <vector>

namespace levelforge {

class PseudoNormals
{
public:
    /// Computes face, edge and vertex pseudonormals. Degenerate (zero-area) triangles get a zero
    /// normal and contribute nothing.
    explicit PseudoNormals(const TriangleMesh& mesh);

    const Vec3d& faceNormal(uint32_t tri) const { return mFace[tri]; }
    const Vec3d& vertexNormal(uint32_t vtx) const { return mVertex[vtx]; }
    /// Pseudonormal of edge k of triangle tri (k = 0: v0→v1, 1: v1→v2, 2: v2→v0).
    const Vec3d& edgeNormal(uint32_t tri, int k) const { return mEdge[3 * size_t(tri) + k]; }
    /// The pseudonormal of the given feature of triangle tri.
    const Vec3d& normal(uint32_t tri, TriangleFeature f) const;
    bool isDegenerate(uint32_t tri) const { return mFace[tri].lengthSqr() == 0.0; }
    /// The sign rule: p is inside when dot(p - c, n) < 0, with c = closest.point on triangle tri
    /// and n the pseudonormal of closest.feature. `Closest` is a TriangleClosestPoint
    /// (TriangleDistance.h); any type with `point` and `feature` members works.
    template<typename Closest>
    bool isInside(uint32_t tri, const Closest& closest, const Vec3d& p) const
    {
        return (p - closest.point).dot(normal(tri, closest.feature)) < 0.0;
    }

private:
    const TriangleMesh& mMesh;
    std::vector<Vec3d> mFace, mVertex, mEdge; // mEdge: 3 per triangle
};

} // namespace levelforge
