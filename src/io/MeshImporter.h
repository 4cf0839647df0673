// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Private to src/io/MeshIO.cc and MeshAssemble.cc: the OpenMesh importer that copies
///        vertices and faces into flat arrays (no half-edge mesh), and their assembly into a
///        TriangleMesh.
#pragma once

#include "io/MeshIOInternal.h"

#include <OpenMesh/Core/IO/importer/BaseImporter.hh>

namespace levelforge {

namespace meshio_internal {

// --------------------------------------------------------------------------------- importer

/// Receives OpenMesh's reader calls. Vertices and faces go into flat arrays; no half-edges.
class Importer final : public OpenMesh::IO::BaseImporter
{
public:
    using VertexHandle = OpenMesh::VertexHandle;
    using FaceHandle = OpenMesh::FaceHandle;
    using HalfedgeHandle = OpenMesh::HalfedgeHandle;
    using EdgeHandle = OpenMesh::EdgeHandle;
    using Vec2f = OpenMesh::Vec2f;
    using Vec3f = OpenMesh::Vec3f;
    using Vec3dOM = OpenMesh::Vec3d;
    using Vec3uc = OpenMesh::Vec3uc;
    using Vec4uc = OpenMesh::Vec4uc;
    using Vec4f = OpenMesh::Vec4f;
    using Status = OpenMesh::Attributes::StatusInfo;

    std::vector<Vec3d> mPoints;
    std::vector<int32_t> mFaceStream; ///< per face: corner count, then the corner indices
    uint64_t mFaceCount = 0;

    VertexHandle add_vertex(const Vec3f& p) override { return addPoint(Vec3d(p[0], p[1], p[2])); }
    VertexHandle add_vertex(const Vec3dOM& p) override { return addPoint(Vec3d(p[0], p[1], p[2])); }
    VertexHandle add_vertex() override { return addPoint(Vec3d(0.0)); }
    void set_point(VertexHandle vh, const Vec3f& p) override
    {
        if (vh.idx() >= 0 && size_t(vh.idx()) < mPoints.size()) {
            mPoints[size_t(vh.idx())] = Vec3d(p[0], p[1], p[2]);
        }
    }
    FaceHandle add_face(const VHandles& corners) override
    {
        mFaceStream.push_back(int32_t(corners.size()));
        for (const VertexHandle& h : corners) mFaceStream.push_back(h.idx());
        return FaceHandle(int(mFaceCount++));
    }
    void reserve(unsigned int nV, unsigned int, unsigned int nF) override
    {
        // A hint from the file's header: capped, the pre-scan has checked it against the data.
        constexpr unsigned int kCap = 1u << 26;
        mPoints.reserve(std::min(nV, kCap));
        mFaceStream.reserve(size_t(std::min(nF, kCap)) * 4);
    }
    size_t n_vertices() const override { return mPoints.size(); }
    size_t n_faces() const override { return size_t(mFaceCount); }
    size_t n_edges() const override { return 0; }

    // Half-edge construction (OM format only) is not supported: nothing is built.
    HalfedgeHandle add_edge(VertexHandle, VertexHandle) override { return HalfedgeHandle(); }
    FaceHandle add_face(HalfedgeHandle) override { return FaceHandle(); }

    // Attributes are irrelevant to distance fields: ignored.
    void add_face_texcoords(FaceHandle, VertexHandle, const std::vector<Vec2f>&) override {}
    void add_face_texcoords(FaceHandle, VertexHandle, const std::vector<Vec3f>&) override {}
    void set_face_texindex(FaceHandle, int) override {}
    void set_halfedge(VertexHandle, HalfedgeHandle) override {}
    void set_normal(VertexHandle, const Vec3f&) override {}
    void set_normal(VertexHandle, const Vec3dOM&) override {}
    void set_color(VertexHandle, const Vec3uc&) override {}
    void set_color(VertexHandle, const Vec4uc&) override {}
    void set_color(VertexHandle, const Vec3f&) override {}
    void set_color(VertexHandle, const Vec4f&) override {}
    void set_texcoord(VertexHandle, const Vec2f&) override {}
    void set_status(VertexHandle, const Status&) override {}
    void set_next(HalfedgeHandle, HalfedgeHandle) override {}
    void set_face(HalfedgeHandle, FaceHandle) override {}
    void request_face_texcoords2D() override {}
    void set_texcoord(HalfedgeHandle, const Vec2f&) override {}
    void set_texcoord(VertexHandle, const Vec3f&) override {}
    void set_texcoord(HalfedgeHandle, const Vec3f&) override {}
    void set_status(HalfedgeHandle, const Status&) override {}
    void set_color(EdgeHandle, const Vec3uc&) override {}
    void set_color(EdgeHandle, const Vec4uc&) override {}
    void set_color(EdgeHandle, const Vec3f&) override {}
    void set_color(EdgeHandle, const Vec4f&) override {}
    void set_status(EdgeHandle, const Status&) override {}
    void set_normal(FaceHandle, const Vec3f&) override {}
    void set_normal(FaceHandle, const Vec3dOM&) override {}
    void set_color(FaceHandle, const Vec3uc&) override {}
    void set_color(FaceHandle, const Vec4uc&) override {}
    void set_color(FaceHandle, const Vec3f&) override {}
    void set_color(FaceHandle, const Vec4f&) override {}
    void set_status(FaceHandle, const Status&) override {}
    void add_texture_information(int, std::string) override {}

private:
    VertexHandle addPoint(const Vec3d& p)
    {
        mPoints.push_back(p);
        return VertexHandle(int(mPoints.size() - 1));
    }
};

/// Builds @a mesh from what OpenMesh handed over and the pre-scan: exact positions when they
/// agree, range-checked faces, polygons triangulated, faces without area dropped; fills the
/// counts of @a info. Throws InvalidMeshError (MeshAssemble.cc).
void assemble(const std::string& path, Importer& imp, Prescan& pre, TriangleMesh& mesh,
              MeshReadInfo& info);

} // namespace meshio_internal

} // namespace levelforge
