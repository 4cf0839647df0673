// SPDX-License-Identifier: Apache-2.0
// Iso-surface of a scalar grid (OpenVDB volumeToMesh) → exact narrow band (levelforge
// meshToLevelSet). See levelset/RebuildLevelSet.h.
#include <levelforge/levelset/RebuildLevelSet.h>

#include <levelforge/core/Exceptions.h>
#include <levelforge/core/Metadata.h>
#include <levelforge/core/TriangleMesh.h>
#include <levelforge/io/VdbIO.h>
#include <levelforge/mesh/MeshToLevelSet.h>

#include <openvdb/tools/Count.h>
#include <openvdb/tools/VolumeToMesh.h>

#include <chrono>
#include <cmath>
#include <sstream>

namespace levelforge {

RebuildInside rebuildInsideFromString(const std::string& name)
{
    if (name == "auto") return RebuildInside::Auto;
    if (name == "below") return RebuildInside::Below;
    if (name == "above") return RebuildInside::Above;
    throw InvalidArgumentError("unknown inside rule '" + name + "' (auto, below, above)");
}

bool isSimilarityTransform(const openvdb::math::Transform& transform)
{
    if (!transform.isLinear()) return false;
    const openvdb::Mat3d m = transform.baseMap()->getAffineMap()->getConstMat4().getMat3();
    const openvdb::Mat3d mmt = m * m.transpose();
    const double h2 = (mmt(0, 0) + mmt(1, 1) + mmt(2, 2)) / 3.0;
    if (!(h2 > 0.0) || !std::isfinite(h2)) return false;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
            if (std::abs(mmt(i, j) - (i == j ? h2 : 0.0)) > 1e-9 * h2) return false;
    return true;
}

openvdb::math::Transform::Ptr transformWithVoxelSize(const openvdb::math::Transform& transform, double voxelSize)
{
    if (!std::isfinite(voxelSize) || !(voxelSize > 0.0)) {
        std::ostringstream os;
        os << "the voxel size must be a positive number, got " << voxelSize;
        throw InvalidArgumentError(os.str());
    }
    if (!isSimilarityTransform(transform)) return openvdb::math::Transform::createLinearTransform(voxelSize);
    openvdb::math::Transform::Ptr t = transform.copy();
    t->preScale(voxelSize / transform.voxelSize()[0]);
    return t;
}

namespace {

using Clock = std::chrono::steady_clock;

double since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

/// Maps the distance step's progress (0–100) to 10–100 of the caller's interrupter.
struct Poller : openvdb::util::NullInterrupter
{
    openvdb::util::NullInterrupter* user = nullptr;
    bool wasInterrupted(int percent = -1) override
    {
        return user && user->wasInterrupted(percent < 0 ? -1 : 10 + 90 * percent / 100);
    }
};

} // namespace

openvdb::FloatGrid::Ptr rebuildLevelSet(const openvdb::FloatGrid& grid, const RebuildLevelSetOptions& options,
                                        RebuildLevelSetStats* stats)
{
    const std::string what = "rebuild: grid '" + grid.getName() + "'";
    if (!std::isfinite(options.isoValue)) throw InvalidArgumentError("rebuild: the iso-value must be a finite number");

    // target transform
    openvdb::math::Transform::ConstPtr target = options.transform;
    if (!target && options.voxelSize != 0.0) target = transformWithVoxelSize(grid.transform(), options.voxelSize);
    if (!target) target = grid.transformPtr();
    if (!isSimilarityTransform(*target)) {
        throw InvalidArgumentError(options.transform || options.voxelSize != 0.0
                                       ? "rebuild: the target transform is not linear with uniform scale (rotation, "
                                         "uniform scale and translation only)"
                                       : what + " has non-uniform voxels or a non-linear transform; give a voxel size");
    }
    const double h = target->voxelSize()[0];
    const double ext = options.units == WidthUnits::World ? options.exteriorWidth / h : options.exteriorWidth;
    const double inw = options.units == WidthUnits::World ? options.interiorWidth / h : options.interiorWidth;
    for (const double w : {ext, inw}) {
        if (!std::isfinite(w) || !(w > 0.0) || w > 10000.0) {
            std::ostringstream os;
            os << "rebuild: band widths must be positive numbers of at most 10000 voxels, got " << options.exteriorWidth
               << " and " << options.interiorWidth << (options.units == WidthUnits::World ? " world units" : " voxels");
            throw InvalidArgumentError(os.str());
        }
    }
    if (options.interrupter && options.interrupter->wasInterrupted(0)) throw InterruptedError("rebuild: interrupted");

    // 1. the iso-surface, oriented counter-clockwise seen from outside
    const auto t0 = Clock::now();
    RebuildInside inside = options.inside;
    if (inside == RebuildInside::Auto)
        inside = grid.getGridClass() == openvdb::GRID_FOG_VOLUME ? RebuildInside::Above : RebuildInside::Below;
    // volumeToMesh takes "inside" from the grid class: below the iso-value for level sets, above
    // for every other class; a shallow copy carries the class we want. Its polygons are then
    // clockwise seen from outside (Houdini's convention), so each one is reversed below.
    // (copyGrid() shares the tree and copies the metadata: the new Grid object is ours to change)
    openvdb::FloatGrid::Ptr view =
        std::const_pointer_cast<openvdb::FloatGrid>(openvdb::gridConstPtrCast<openvdb::FloatGrid>(grid.copyGrid()));
    view->setGridClass(inside == RebuildInside::Below ? openvdb::GRID_LEVEL_SET : openvdb::GRID_FOG_VOLUME);
    std::vector<openvdb::Vec3s> points;
    std::vector<openvdb::Vec3I> triangles;
    std::vector<openvdb::Vec4I> quads;
    openvdb::tools::volumeToMesh(*view, points, triangles, quads, options.isoValue, /*adaptivity=*/0.0,
                                 /*relaxDisorientedTriangles=*/true);
    view.reset();
    if (triangles.empty() && quads.empty()) {
        const openvdb::math::MinMax<float> mm = openvdb::tools::minMax(grid.tree());
        std::ostringstream os;
        os << what << " has no iso-surface at iso-value " << options.isoValue << " (its values range from " << mm.min()
           << " to " << mm.max() << ")";
        throw InvalidArgumentError(os.str());
    }
    TriangleMesh mesh;
    mesh.source = "iso-surface of grid '" + grid.getName() + "'";
    mesh.points.resize(points.size());
    // into the target's index space scaled by h: distances there are world distances
    for (size_t i = 0; i < points.size(); ++i) mesh.points[i] = target->worldToIndex(openvdb::Vec3d(points[i])) * h;
    mesh.triangles.reserve(triangles.size() + 2 * quads.size());
    for (const auto& t : triangles) mesh.triangles.push_back(Vec3I(t[0], t[2], t[1]));
    for (const auto& q : quads) {
        mesh.triangles.push_back(Vec3I(q[0], q[2], q[1]));
        mesh.triangles.push_back(Vec3I(q[0], q[3], q[2]));
    }
    points.clear();
    points.shrink_to_fit();
    const double secondsSurface = since(t0);
    if (options.interrupter && options.interrupter->wasInterrupted(10)) throw InterruptedError("rebuild: interrupted");

    // 2. the exact band on the target
    const auto t1 = Clock::now();
    Poller poller;
    poller.user = options.interrupter;
    MeshToLevelSetOptions mo;
    mo.voxelSize = h;
    mo.exteriorWidth = ext;
    mo.interiorWidth = inw;
    mo.units = WidthUnits::Voxels;
    mo.gridName = options.gridName.empty() ? grid.getName() : options.gridName;
    mo.maxVoxels = options.maxVoxels;
    mo.interrupter = &poller;
    // pseudonormals, not Auto: the surface is closed (volumeToMesh meshes the sign field of the
    // whole grid, background included), and with Below on a fog volume its inside is unbounded
    // (negative enclosed volume), which winding numbers would read as a bounded inside
    mo.sign = SignMode::Pseudonormal;
    MeshToLevelSetStats ms;
    openvdb::FloatGrid::Ptr out = meshToLevelSet(mesh, mo, &ms);
    out->setTransform(target->copy());
    for (auto it = grid.beginMeta(); it != grid.endMeta(); ++it) {
        if (it->first.rfind("file_", 0) == 0 || (*out)[it->first]) continue;
        out->insertMeta(it->first, *it->second);
    }
    out->setGridClass(openvdb::GRID_LEVEL_SET);
    stampLevelSetMetadata(*out, ext, inw, "grid '" + grid.getName() + "'", "volume-to-mesh+exact-band");
    out->insertMeta(meta::kIso, openvdb::FloatMetadata(float(options.isoValue)));

    if (stats) {
        stats->surfacePoints = mesh.points.size();
        stats->surfaceTriangles = mesh.triangles.size();
        stats->activeVoxels = out->activeVoxelCount();
        stats->sign = toString(ms.sign);
        stats->voxelSize = h;
        stats->secondsSurface = secondsSurface;
        stats->secondsDistance = since(t1);
    }
    return out;
}

} // namespace levelforge
