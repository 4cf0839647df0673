// SPDX-License-Identifier: Apache-2.0
// Loop subdivision through OpenMesh (LoopT), shared by the benchmarks that need meshes of
// ~0.4-1.6 M faces made from the 100 k-face dev meshes.
#pragma once

#include <levelforge/core/Exceptions.h>
#include <levelforge/core/TriangleMesh.h>

#include <OpenMesh/Core/Mesh/TriMesh_ArrayKernelT.hh>
#include <OpenMesh/Tools/Subdivider/Uniform/LoopT.hh>

#include <cstdint>
#include <string>
#include <vector>

namespace levelforge_bench {

struct DoubleTraits : public OpenMesh::DefaultTraits
{
    typedef OpenMesh::Vec3d Point;
    typedef OpenMesh::Vec3d Normal;
};
using OMesh = OpenMesh::TriMesh_ArrayKernelT<DoubleTraits>;

inline levelforge::TriangleMesh loopSubdivide(const levelforge::TriangleMesh& in, int levels)
{
    OMesh om;
    // only the vertices a face uses: LoopT gives an isolated vertex (valence 0) NaN coordinates
    std::vector<uint8_t> used(in.points.size(), 0);
    for (const auto& t : in.triangles)
        for (int k = 0; k < 3; ++k) used[t[k]] = 1;
    std::vector<OMesh::VertexHandle> vh(in.points.size());
    for (size_t i = 0; i < in.points.size(); ++i)
        if (used[i]) vh[i] = om.add_vertex(OMesh::Point(in.points[i][0], in.points[i][1], in.points[i][2]));
    size_t rejected = 0;
    for (const auto& t : in.triangles) {
        if (!om.add_face(vh[t[0]], vh[t[1]], vh[t[2]]).is_valid()) ++rejected;
    }
    if (rejected)
        throw levelforge::InvalidMeshError(in.source + ": " + std::to_string(rejected) +
                                           " faces are non-manifold for OpenMesh; cannot Loop-subdivide");
    OpenMesh::Subdivider::Uniform::LoopT<OMesh, double> loop;
    loop.attach(om);
    loop(size_t(levels));
    loop.detach();
    om.garbage_collection();

    levelforge::TriangleMesh out;
    out.source = in.source + " (Loop x" + std::to_string(levels) + ")";
    out.points.reserve(om.n_vertices());
    for (auto v : om.vertices()) {
        const auto& p = om.point(v);
        out.points.emplace_back(p[0], p[1], p[2]);
    }
    out.triangles.reserve(om.n_faces());
    for (auto f : om.faces()) {
        levelforge::Vec3I t;
        int k = 0;
        for (auto v : om.fv_range(f)) t[k++] = uint32_t(v.idx());
        out.triangles.push_back(t);
    }
    return out;
}

} // namespace levelforge_bench
