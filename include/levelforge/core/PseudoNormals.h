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

/// @brief Face, edge and vertex pseudonormals of a triangle mesh, and the sign rule built on them.
///
/// Face normals are unit vectors; edge and vertex pseudonormals are the (unnormalised) sums
/// described in the file comment, since only the sign of a dot product with them is used.
class PseudoNormals
{
public:
    /// @brief Computes face, edge and vertex pseudonormals.
    ///
    /// Degenerate (zero-area) triangles get a zero normal and contribute nothing. Keeps a
    /// reference to @p mesh (normal() reads its triangles), which must outlive this object.
    /// Deterministic: sums are taken in a fixed order whatever the number of threads.
    /// @param[in] mesh  a usable mesh (see requireUsableMesh()), counter-clockwise seen from outside
    explicit PseudoNormals(const TriangleMesh& mesh);

    /// @brief Unit normal of triangle @p tri (zero for a degenerate triangle).
    /// @param[in] tri  triangle index into mesh.triangles
    /// @return the face normal
    const Vec3d& faceNormal(uint32_t tri) const { return mFace[tri]; }
    /// @brief Angle-weighted pseudonormal of vertex @p vtx (zero for an unused vertex).
    /// @param[in] vtx  vertex index into mesh.points
    /// @return the vertex pseudonormal (not normalised)
    const Vec3d& vertexNormal(uint32_t vtx) const { return mVertex[vtx]; }
    /// @brief Pseudonormal of edge k of triangle tri (k = 0: v0→v1, 1: v1→v2, 2: v2→v0).
    /// @param[in] tri  triangle index into mesh.triangles
    /// @param[in] k    edge of the triangle, 0, 1 or 2
    /// @return the sum of the normals of all faces on the edge (not normalised)
    const Vec3d& edgeNormal(uint32_t tri, int k) const { return mEdge[3 * size_t(tri) + k]; }
    /// @brief The pseudonormal of the given feature of triangle tri.
    /// @param[in] tri  triangle index into mesh.triangles
    /// @param[in] f    the feature (face, one of its vertices or edges), as returned by
    ///                 closestPointOnTriangle()
    /// @return the face, vertex or edge pseudonormal
    const Vec3d& normal(uint32_t tri, TriangleFeature f) const;
    /// @brief True when triangle @p tri got a zero face normal (zero area or non-finite normal).
    /// @param[in] tri  triangle index into mesh.triangles
    /// @return true for a triangle that takes no part in the pseudonormals
    bool isDegenerate(uint32_t tri) const { return mFace[tri].lengthSqr() == 0.0; }
    /// @brief The sign rule: p is inside when dot(p - c, n) < 0, with c = closest.point on
    ///        triangle tri and n the pseudonormal of closest.feature.
    ///
    /// `Closest` is a TriangleClosestPoint (TriangleDistance.h); any type with `point` and
    /// `feature` members works.
    /// @param[in] tri      the triangle holding the closest point (index into mesh.triangles)
    /// @param[in] closest  the closest point on that triangle to @p p and its feature
    /// @param[in] p        the query point, in the same units as the mesh points
    /// @return true when @p p is inside
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
