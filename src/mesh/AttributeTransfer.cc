// SPDX-License-Identifier: Apache-2.0
// Attribute transfer: the value of a mesh attribute at each voxel's closest point. See
// mesh/AttributeTransfer.h.
#include <levelforge/mesh/AttributeTransfer.h>

#include <levelforge/core/Exceptions.h>

#include <openvdb/tree/LeafManager.h>

#include <algorithm>
#include <atomic>
#include <cmath>

namespace levelforge {

namespace attribute_internal {

/// Barycentric weights (of a, b, c) of the point of triangle (a, b, c) closest to p: the
/// Voronoi-region classification of closestPointOnTriangle(), keeping the weights. A degenerate
/// triangle that reaches the face region falls back to its closest corner.
Vec3d closestBarycentric(const Vec3d& p, const Vec3d& a, const Vec3d& b, const Vec3d& c)
{
    const Vec3d ab = b - a, ac = c - a, ap = p - a;
    const double d1 = ab.dot(ap), d2 = ac.dot(ap);
    if (d1 <= 0.0 && d2 <= 0.0) return Vec3d(1.0, 0.0, 0.0);
    const Vec3d bp = p - b;
    const double d3 = ab.dot(bp), d4 = ac.dot(bp);
    if (d3 >= 0.0 && d4 <= d3) return Vec3d(0.0, 1.0, 0.0);
    const double vc = d1 * d4 - d3 * d2;
    if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) {
        const double v = d1 / (d1 - d3);
        return Vec3d(1.0 - v, v, 0.0);
    }
    const Vec3d cp = p - c;
    const double d5 = ab.dot(cp), d6 = ac.dot(cp);
    if (d6 >= 0.0 && d5 <= d6) return Vec3d(0.0, 0.0, 1.0);
    const double vb = d5 * d2 - d1 * d6;
    if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) {
        const double w = d2 / (d2 - d6);
        return Vec3d(1.0 - w, 0.0, w);
    }
    const double va = d3 * d6 - d5 * d4;
    if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0) {
        const double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return Vec3d(0.0, 1.0 - w, w);
    }
    const double sum = va + vb + vc;
    if (!(std::abs(sum) > 0.0) || !std::isfinite(1.0 / sum)) { // no area: the closest corner
        const double da = (p - a).lengthSqr(), db = (p - b).lengthSqr(), dc = (p - c).lengthSqr();
        if (da <= db && da <= dc) return Vec3d(1.0, 0.0, 0.0);
        return db <= dc ? Vec3d(0.0, 1.0, 0.0) : Vec3d(0.0, 0.0, 1.0);
    }
    const double v = vb / sum, w = vc / sum;
    return Vec3d(1.0 - v - w, v, w);
}

template<typename GridT, int C>
typename GridT::Ptr transfer(const TriangleMesh& mesh, const MeshAttribute& attr, const openvdb::Int32Grid& closest,
                             const AttributeTransferOptions& options)
{
    using TreeT = typename GridT::TreeType;
    using LeafT = typename TreeT::LeafNodeType;
    using ValueT = typename GridT::ValueType;
    auto tree = std::make_shared<TreeT>(closest.tree(), openvdb::zeroVal<ValueT>(), openvdb::TopologyCopy());
    const openvdb::math::Transform& xform = closest.transform();
    const openvdb::Int32Tree& tris = closest.tree();
    const size_t nT = mesh.triangles.size();
    const float* values = attr.values.data();
    std::atomic<bool> stop{false};
    openvdb::tree::LeafManager<TreeT> leaves(*tree);
    leaves.foreach([&](LeafT& leaf, size_t) {
        if (stop.load(std::memory_order_relaxed)) return;
        if (options.interrupter && options.interrupter->wasInterrupted()) {
            stop.store(true, std::memory_order_relaxed);
            return;
        }
        const openvdb::Int32Tree::LeafNodeType* src = tris.probeConstLeaf(leaf.origin());
        for (openvdb::Index i = 0; i < LeafT::SIZE; ++i) {
            if (!leaf.isValueOn(i)) continue;
            const int32_t t = src ? src->getValue(i) : -1;
            if (t < 0 || size_t(t) >= nT) {
                leaf.setValueOff(i, openvdb::zeroVal<ValueT>());
                continue;
            }
            const Vec3I& tri = mesh.triangles[size_t(t)];
            const Vec3d p = xform.indexToWorld(leaf.offsetToGlobalCoord(i));
            const Vec3d w = closestBarycentric(p, mesh.points[tri[0]], mesh.points[tri[1]], mesh.points[tri[2]]);
            const float* corner = values + size_t(t) * 3 * C;
            ValueT out;
            if constexpr (C == 1) {
                out = float(w[0] * double(corner[0]) + w[1] * double(corner[1]) + w[2] * double(corner[2]));
            } else {
                for (int c = 0; c < C; ++c) {
                    out[c] = float(w[0] * double(corner[c]) + w[1] * double(corner[C + c]) +
                                   w[2] * double(corner[2 * C + c]));
                }
            }
            leaf.setValueOn(i, out);
        }
    });
    if (stop.load()) throw InterruptedError("interrupted while transferring attribute '" + attr.name + "'");
    // active tiles of the closest-triangle grid have no triangle: inactive
    typename TreeT::ValueOnIter it = tree->beginValueOn();
    it.setMaxDepth(TreeT::ValueOnIter::LEAF_DEPTH - 1);
    for (; it; ++it) it.setActiveState(false);
    auto grid = GridT::create(tree);
    grid->setTransform(xform.copy());
    grid->setName(options.gridName.empty() ? attr.name : options.gridName);
    grid->setGridClass(openvdb::GRID_UNKNOWN);
    return grid;
}

} // namespace attribute_internal

const MeshAttribute& findMeshAttribute(const TriangleMesh& mesh, const std::string& name)
{
    const std::string what = mesh.source.empty() ? std::string("mesh") : mesh.source;
    std::string has;
    for (const MeshAttribute& a : mesh.attributes) {
        if (a.name == name) {
            const size_t want = mesh.triangles.size() * 3 * size_t(std::max(a.components, 0));
            if (a.values.size() != want) {
                throw InvalidMeshError(what + ": attribute '" + name + "' has " + std::to_string(a.values.size()) +
                                       " values for " + std::to_string(mesh.triangles.size()) + " triangles of " +
                                       std::to_string(a.components) + " components per corner (expected " +
                                       std::to_string(want) + ")");
            }
            return a;
        }
        has += (has.empty() ? "" : ", ") + a.name;
    }
    throw InvalidArgumentError(what + ": no vertex attribute '" + name + "' (" +
                               (has.empty() ? std::string("it has none") : "it has: " + has) + ")");
}

openvdb::GridBase::Ptr transferAttribute(const TriangleMesh& mesh, const std::string& name,
                                         const openvdb::Int32Grid& closestTriangles,
                                         const AttributeTransferOptions& options)
{
    const MeshAttribute& attr = findMeshAttribute(mesh, name);
    if (attr.components == 1)
        return attribute_internal::transfer<openvdb::FloatGrid, 1>(mesh, attr, closestTriangles, options);
    if (attr.components == 3) {
        auto g = attribute_internal::transfer<openvdb::Vec3SGrid, 3>(mesh, attr, closestTriangles, options);
        g->setVectorType(name == "N" ? openvdb::VEC_COVARIANT_NORMALIZE : openvdb::VEC_INVARIANT);
        return g;
    }
    throw InvalidArgumentError("attribute '" + name + "' has " + std::to_string(attr.components) +
                               " components per corner: only 1 (float grid) or 3 (vector grid) can be transferred");
}

} // namespace levelforge
