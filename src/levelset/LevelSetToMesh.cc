// SPDX-License-Identifier: Apache-2.0
// The isosurface of a float grid as a triangle mesh, through OpenVDB's volumeToMesh. See
// levelset/LevelSetToMesh.h.
#include <levelforge/levelset/LevelSetToMesh.h>

#include <levelforge/core/Exceptions.h>

#include <openvdb/tools/VolumeToMesh.h>

#include <cmath>
#include <cstdio>
#include <limits>
#include <sstream>
#include <vector>

namespace levelforge {

namespace {

constexpr uint32_t kUnused = std::numeric_limits<uint32_t>::max();

/// Polls @p interrupter every 2^20 polygons; throws InterruptedError when it asks to stop.
void poll(openvdb::util::NullInterrupter* interrupter, size_t done, size_t total)
{
    if (!interrupter || (done & ((size_t(1) << 20) - 1)) != 0) return;
    const int percent = 50 + int(50.0 * double(done) / double(std::max<size_t>(total, 1)));
    if (interrupter->wasInterrupted(percent)) throw InterruptedError("sdf-to-mesh: interrupted");
}

} // namespace

TriangleMesh levelSetToMesh(const openvdb::FloatGrid& grid, const LevelSetToMeshOptions& options,
                            LevelSetToMeshStats* stats)
{
    if (!std::isfinite(options.isovalue)) {
        std::ostringstream os;
        os << "sdf-to-mesh: the isovalue must be a finite number, got " << options.isovalue;
        throw InvalidArgumentError(os.str());
    }
    if (!(options.adaptivity >= 0.0 && options.adaptivity <= 1.0)) {
        std::ostringstream os;
        os << "sdf-to-mesh: the adaptivity must be in [0, 1], got " << options.adaptivity;
        throw InvalidArgumentError(os.str());
    }
    openvdb::util::NullInterrupter* interrupter = options.interrupter;
    if (interrupter) {
        interrupter->start("sdf-to-mesh");
        if (interrupter->wasInterrupted(0)) throw InterruptedError("sdf-to-mesh: interrupted");
    }

    std::vector<openvdb::Vec3s> points;
    std::vector<openvdb::Vec3I> triangles;
    std::vector<openvdb::Vec4I> quads;
    openvdb::tools::volumeToMesh(grid, points, triangles, quads, options.isovalue, options.adaptivity,
                                 options.relaxDisorientedTriangles);
    if (interrupter && interrupter->wasInterrupted(50)) throw InterruptedError("sdf-to-mesh: interrupted");

    LevelSetToMeshStats st;
    st.quads = quads.size();
    st.openvdbTriangles = triangles.size();

    // OpenVDB winds a level set's polygons clockwise seen from outside (and inverts the winding of
    // other grid classes, whose inside is above the isovalue): every polygon is reversed here, so
    // the mesh is counter-clockwise seen from outside for both (TriangleMesh's convention).
    TriangleMesh mesh;
    mesh.triangles.reserve(quads.size() * 2 + triangles.size());
    const size_t total = quads.size() + triangles.size();
    size_t done = 0;
    const auto add = [&](uint32_t a, uint32_t b, uint32_t c) {
        if (a == b || b == c || a == c) {
            ++st.degenerateDropped;
            return;
        }
        mesh.triangles.emplace_back(a, c, b); // reversed
    };
    for (const openvdb::Vec4I& q : quads) {
        poll(interrupter, done++, total);
        add(q[0], q[1], q[2]); // split along the 0-2 diagonal, as OpenVDB and readMesh() split quads
        add(q[0], q[2], q[3]);
    }
    for (const openvdb::Vec3I& t : triangles) {
        poll(interrupter, done++, total);
        add(t[0], t[1], t[2]);
    }

    std::vector<openvdb::Vec4I>().swap(quads); // free as we go: the peak is the float and double points
    std::vector<openvdb::Vec3I>().swap(triangles);

    // Keep only the points the triangles use, in OpenVDB's order.
    std::vector<uint32_t> remap(points.size(), kUnused);
    for (const Vec3I& t : mesh.triangles)
        for (int k = 0; k < 3; ++k) remap[t[k]] = 0;
    mesh.points.reserve(points.size());
    for (size_t i = 0; i < points.size(); ++i) {
        if (remap[i] == kUnused) {
            ++st.unusedVerticesDropped;
            continue;
        }
        remap[i] = uint32_t(mesh.points.size());
        const openvdb::Vec3s& p = points[i];
        mesh.points.emplace_back(double(p[0]), double(p[1]), double(p[2]));
    }
    std::vector<openvdb::Vec3s>().swap(points);
    for (Vec3I& t : mesh.triangles)
        for (int k = 0; k < 3; ++k) t[k] = remap[t[k]];

    char iso[64];
    std::snprintf(iso, sizeof(iso), "%g", options.isovalue);
    mesh.source = "isosurface " + std::string(iso) + " of grid '" + grid.getName() + "'";
    if (interrupter) {
        if (interrupter->wasInterrupted(100)) throw InterruptedError("sdf-to-mesh: interrupted");
        interrupter->end();
    }
    if (stats) *stats = st;
    return mesh;
}

} // namespace levelforge
