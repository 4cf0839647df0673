// SPDX-License-Identifier: Apache-2.0
// The mesh pipeline: exact band (Chang or T4 scan) → optional expansion → metadata. See
// pipeline/MeshToSdf.h.
#include <levelforge/pipeline/MeshToSdf.h>

#include "detail/Timer.h"
#include "mesh/WindingSignInternal.h"

#include <levelforge/core/Exceptions.h>
#include <levelforge/core/MeshValidation.h>
#include <levelforge/core/Metadata.h>
#include <levelforge/gpu/VulkanSlabBackend.h>
#include <levelforge/io/VdbIO.h>
#include <levelforge/levelset/SdfToFog.h>
#include <levelforge/mesh/AttributeTransfer.h>
#include <levelforge/mesh/FastWindingNumber.h>

#include <openvdb/tools/Prune.h>
#include <openvdb/tree/LeafManager.h>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <memory>
#include <cmath>
#include <sstream>

namespace levelforge {

BandMethod bandMethodFromString(const std::string& name)
{
    if (name == "chang") return BandMethod::Chang;
    if (name == "scan") return BandMethod::Scan;
    throw InvalidArgumentError("unknown band method '" + name + "' (chang, scan)");
}

Expansion expansionFromString(const std::string& name)
{
    if (name == "none" || name == "exact") return Expansion::None;
    if (name == "sweep") return Expansion::Sweep;
    if (name == "vector") return Expansion::Vector;
    throw InvalidArgumentError("unknown expansion '" + name + "' (none, exact, sweep, vector)");
}

double checkUniformLinearTransform(const openvdb::math::Transform& transform, const std::string& what)
{
    if (!transform.isLinear())
        throw InvalidArgumentError(what + ": the transform is not linear (" + transform.mapType() +
                                   "): a level set needs a linear transform with a uniform scale");
    // The images of the index axes (convention-free: through the map itself).
    const openvdb::Vec3d t = transform.indexToWorld(openvdb::Vec3d(0.0));
    openvdb::Vec3d a[3];
    for (int k = 0; k < 3; ++k) {
        openvdb::Vec3d e(0.0);
        e[k] = 1.0;
        a[k] = transform.indexToWorld(e) - t;
    }
    const double h = a[0].length();
    std::ostringstream os;
    os.precision(9);
    if (!(std::isfinite(h) && h > 0.0) || !t.isFinite()) {
        os << what << ": the transform's voxel size " << h << " is not finite and positive";
        throw InvalidArgumentError(os.str());
    }
    for (int k = 1; k < 3; ++k) {
        if (!(std::abs(a[k].length() - h) <= 1e-6 * h)) {
            os << what << ": the transform has a non-uniform scale (voxel size " << transform.voxelSize()
               << "): levelforge needs cubic voxels";
            throw InvalidArgumentError(os.str());
        }
    }
    for (int i = 0; i < 3; ++i)
        for (int j = i + 1; j < 3; ++j)
            if (!(std::abs(a[i].dot(a[j])) <= 1e-6 * h * h)) {
                os << what << ": the transform has a shear (index axes " << i << " and " << j
                   << " are not perpendicular): levelforge needs cubic voxels";
                throw InvalidArgumentError(os.str());
            }
    return h;
}

ReferenceGrid readReferenceGrid(const std::string& path)
{
    const openvdb::GridPtrVecPtr grids = readGrids(path); // IoError names the file
    openvdb::FloatGrid::Ptr g;
    std::string found;
    for (const openvdb::GridBase::Ptr& b : *grids) {
        if (!b) continue;
        if ((g = openvdb::gridPtrCast<openvdb::FloatGrid>(b))) break;
        found += (found.empty() ? "" : ", ") + ("'" + b->getName() + "' (" + b->valueType() + ")");
    }
    if (!g)
        throw InvalidArgumentError("reference '" + path + "': no float grid in the file" +
                                   (found.empty() ? std::string(" (it holds no grid)") : " (it holds " + found + ")"));
    ReferenceGrid r;
    r.path = path;
    r.name = g->getName();
    r.voxelSize = checkUniformLinearTransform(g->transform(), "reference '" + path + "' grid '" + r.name + "'");
    r.transform = g->transform().copy();
    auto band = [&](const char* key) {
        if (auto m = g->getMetadata<openvdb::FloatMetadata>(key)) return double(m->value());
        if (auto m = g->getMetadata<openvdb::DoubleMetadata>(key)) return m->value();
        return 0.0;
    };
    r.exteriorBandVoxels = band(meta::kExteriorBandVoxels);
    r.interiorBandVoxels = band(meta::kInteriorBandVoxels);
    if (g->getGridClass() == openvdb::GRID_LEVEL_SET) {
        const double fromBackground = double(std::abs(g->background())) / r.voxelSize;
        if (!(r.exteriorBandVoxels > 0.0)) r.exteriorBandVoxels = fromBackground;
        if (!(r.interiorBandVoxels > 0.0)) r.interiorBandVoxels = fromBackground;
    }
    if (!(std::isfinite(r.exteriorBandVoxels) && r.exteriorBandVoxels > 0.0)) r.exteriorBandVoxels = 0.0;
    if (!(std::isfinite(r.interiorBandVoxels) && r.interiorBandVoxels > 0.0)) r.interiorBandVoxels = 0.0;
    return r;
}

namespace {

/// The mesh in the output transform's frame: moved by the rigid motion p -> voxelSize ·
/// worldToIndex(p), so that voxel ijk of a linear transform of that voxel size (no translation)
/// is voxel ijk of @p transform. Returns false (and leaves @p out alone) when the transform is
/// already that plain scale.
bool meshInTransformFrame(const TriangleMesh& mesh, const openvdb::math::Transform& transform, double h,
                          TriangleMesh& out)
{
    const openvdb::Vec3d t = transform.indexToWorld(openvdb::Vec3d(0.0));
    openvdb::Vec3d a[3];
    bool plain = t == openvdb::Vec3d(0.0);
    for (int k = 0; k < 3; ++k) {
        openvdb::Vec3d e(0.0);
        e[k] = 1.0;
        a[k] = transform.indexToWorld(e) - t;
        openvdb::Vec3d expected(0.0);
        expected[k] = h;
        plain = plain && a[k] == expected;
    }
    if (plain) return false;
    // Rows of the rotation R (a_k / h, orthonormal up to the check's tolerance): p' = R (p - t).
    for (int k = 0; k < 3; ++k) a[k] /= h;
    out.source = mesh.source;
    out.faceIndex = mesh.faceIndex;
    out.attributes = mesh.attributes;
    out.points.resize(mesh.points.size());
    tbb::parallel_for(tbb::blocked_range<size_t>(0, mesh.points.size(), 8192), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t i = r.begin(); i != r.end(); ++i) {
            const Vec3d d = mesh.points[i] - t;
            out.points[i] = Vec3d(a[0].dot(d), a[1].dot(d), a[2].dot(d));
        }
    });
    out.triangles = mesh.triangles;
    if (a[0].cross(a[1]).dot(a[2]) < 0.0) { // a reflection: keep "counter-clockwise seen from outside"
        for (Vec3I& tri : out.triangles) std::swap(tri[1], tri[2]);
        for (MeshAttribute& attr : out.attributes) { // the corners' values follow their corners
            const size_t C = size_t(attr.components);
            if (attr.values.size() != out.triangles.size() * 3 * C) continue; // findMeshAttribute() reports it
            for (size_t t = 0; t < out.triangles.size(); ++t)
                std::swap_ranges(attr.values.begin() + std::ptrdiff_t((3 * t + 1) * C),
                                 attr.values.begin() + std::ptrdiff_t((3 * t + 2) * C),
                                 attr.values.begin() + std::ptrdiff_t((3 * t + 2) * C));
        }
    }
    return true;
}

MeshToSdfGrids run(const TriangleMesh& inputMesh, const MeshToSdfOptions& o, MeshToSdfStats* statsOut, bool extras)
{
    const auto t0 = detail::Clock::now();
    MeshToSdfStats stats;
    const bool wantFog = extras && !o.fogGridName.empty();
    const bool wantPrimitive = extras && !o.primitiveIndexGridName.empty();
    if (wantFog && o.fogGridName == o.gridName)
        throw InvalidArgumentError("the fog grid and the level set have the same name '" + o.gridName +
                                   "': grid names must be distinct");
    if (wantPrimitive && o.primitiveIndexGridName == o.gridName)
        throw InvalidArgumentError("the primitive index grid and the level set have the same name '" + o.gridName +
                                   "': grid names must be distinct");
    if (wantFog && wantPrimitive && o.fogGridName == o.primitiveIndexGridName)
        throw InvalidArgumentError("the fog grid and the primitive index grid have the same name '" + o.fogGridName +
                                   "': grid names must be distinct");
    const bool wantAttributes = extras && !o.attributes.empty();
    if (wantAttributes) {
        std::vector<std::string> names = {o.gridName};
        if (wantFog) names.push_back(o.fogGridName);
        if (wantPrimitive) names.push_back(o.primitiveIndexGridName);
        for (const std::string& a : o.attributes) {
            findMeshAttribute(inputMesh, a); // InvalidArgumentError listing what the mesh has
            if (std::find(names.begin(), names.end(), a) != names.end())
                throw InvalidArgumentError("the attribute grid '" + a + "' has the name of another grid (or is asked "
                                           "for twice): grid names must be distinct");
            names.push_back(a);
        }
        if (o.method == BandMethod::Scan)
            throw InvalidArgumentError("attribute transfer needs the chang band method (the scan method keeps no "
                                       "closest triangle)");
        if (o.expansion != Expansion::None)
            throw InvalidArgumentError("attribute transfer needs --expansion none: only the exact band knows each "
                                       "voxel's closest point (an expansion's new voxels do not)");
        if (o.fillInterior)
            throw InvalidArgumentError("attribute transfer cannot be combined with fill interior: the filled voxels "
                                       "deeper than the band have no closest point");
    }
    if (wantPrimitive) {
        if (o.method == BandMethod::Scan)
            throw InvalidArgumentError("a primitive index grid needs the chang band method (the scan method keeps no "
                                       "closest triangle)");
        if (o.expansion != Expansion::None)
            throw InvalidArgumentError("a primitive index grid needs --expansion none: only the exact band knows each "
                                       "voxel's closest face (an expansion's new voxels do not)");
        if (o.fillInterior)
            throw InvalidArgumentError("a primitive index grid cannot be combined with fill interior: the filled voxels "
                                       "deeper than the band have no closest face");
        if (!inputMesh.faceIndex.empty() && inputMesh.faceIndex.size() != inputMesh.triangles.size())
            throw InvalidMeshError((inputMesh.source.empty() ? std::string("mesh") : inputMesh.source) + ": " +
                                   std::to_string(inputMesh.faceIndex.size()) + " face indices for " +
                                   std::to_string(inputMesh.triangles.size()) + " triangles");
    }

    // The output transform: the given one (the mesh moved into its frame), else a plain scale.
    double hGiven = 0.0;
    TriangleMesh moved;
    const TriangleMesh* meshPtr = &inputMesh;
    if (o.transform) {
        hGiven = checkUniformLinearTransform(*o.transform, "the output transform");
        if (meshInTransformFrame(inputMesh, *o.transform, hGiven, moved)) meshPtr = &moved;
    }
    const TriangleMesh& mesh = *meshPtr;
    const bool scan = o.method == BandMethod::Scan;
    const bool expand = o.expansion != Expansion::None;
    const bool vector = o.expansion == Expansion::Vector;
    if (expand && !(std::isfinite(o.exactBandVoxels) && o.exactBandVoxels >= 1.0)) {
        std::ostringstream os;
        os << "the exact band must be at least 1 voxel, got " << o.exactBandVoxels;
        throw InvalidArgumentError(os.str());
    }

    // The sign mode, once, for every stage.
    // (Auto with the chang method is resolved by the band stage, from the same report.)
    SignMode sign = o.sign;
    std::string signReason = std::string(toString(sign)) + ": requested";
    MeshReport localReport;
    const MeshReport* report = o.validation;
    bool resolvedHere = sign != SignMode::Auto; // else the band stage says why
    if (sign == SignMode::Auto) {
        requireUsableMesh(mesh);
        if (!report) {
            localReport = validateMesh(mesh);
            report = &localReport;
        }
        if (scan) {
            sign = SignMode::Pseudonormal;
            resolvedHere = true;
            signReason = std::string("auto: the scan method signs by pseudonormals") +
                         (report->closed() ? "" : " (the mesh is not closed: signs may be wrong away from the surface)");
        } else if (o.expansion == Expansion::Sweep && !report->closed()) {
            sign = SignMode::Pseudonormal;
            resolvedHere = true;
            signReason = "auto: the mesh is not closed, but fast sweeping needs pseudonormal signs (signs and "
                         "swept distances may be wrong across its holes; --expansion vector signs it by the winding number)";
        }
    }
    if (sign == SignMode::Winding && o.expansion == Expansion::Sweep)
        throw InvalidArgumentError("the winding sign mode cannot be fast-swept: across a hole the signed band has no zero "
                                   "crossing and the sweep makes one up; use --expansion vector");
    if (scan && (sign == SignMode::Winding || sign == SignMode::Unsigned))
        throw InvalidArgumentError(std::string("the ") + toString(sign) +
                                   " sign mode needs the chang band method (the scan method signs by pseudonormals)");
    if (sign == SignMode::Unsigned && expand)
        throw InvalidArgumentError("an unsigned distance cannot be expanded: the expansion needs inside and outside");
    if (sign == SignMode::Unsigned && o.fillInterior)
        throw InvalidArgumentError("fill interior needs an inside: it cannot be combined with the unsigned sign mode");

    // One voxel size and the final widths in voxels, held in float as the band stages hold them.
    const double h = o.transform ? hGiven : resolveVoxelSize(mesh, o);
    const float exteriorTarget = static_cast<float>(o.widthInVoxels(o.exteriorWidth, h));
    const float interiorTarget = static_cast<float>(o.widthInVoxels(o.interiorWidth, h));
    float exteriorBand = exteriorTarget, interiorBand = interiorTarget;
    if (expand) {
        const float exact = static_cast<float>(o.exactBandVoxels);
        exteriorBand = std::min(exteriorBand, exact);
        interiorBand = std::min(interiorBand, exact);
    }

    // The exact band, in voxels, at the resolved voxel size.
    GridSpec band = o;
    band.voxelSize = h;
    band.voxelCount = 0;
    band.units = WidthUnits::Voxels;
    band.exteriorWidth = exteriorBand;
    band.interiorWidth = interiorBand;

    openvdb::FloatGrid::Ptr grid;
    openvdb::Vec3fGrid::Ptr closest;
    openvdb::Int32Grid::Ptr closestTriangles;
    if (scan) {
        TetScanOptions so;
        static_cast<GridSpec&>(so) = band;
        so.shell = o.shell;
        so.coverage = o.coverage;
        so.conservative = o.conservative;
        // the slabs on a Vulkan device: always with Vulkan, with Auto on a discrete GPU
        std::unique_ptr<VulkanSlabBackend> device;
        std::string note;
        if (o.device == ComputeDevice::Vulkan) {
            device = std::make_unique<VulkanSlabBackend>(o.deviceMemoryBudget);
        } else if (o.device == ComputeDevice::Auto) {
            std::string why;
            if (autoUsesVulkan(why)) {
                try {
                    device = std::make_unique<VulkanSlabBackend>(o.deviceMemoryBudget);
                } catch (const DeviceError& e) {
                    note = std::string("device auto: ") + e.what() + "; the CPU was used";
                }
            }
        }
        so.backend = device.get();
        try {
            grid = meshToLevelSetScan(mesh, so, &stats.scan);
        } catch (const DeviceError& e) {
            if (o.device != ComputeDevice::Auto) throw;
            note = std::string("device auto: ") + e.what() + "; the CPU was used";
            so.backend = nullptr;
            device.reset();
            grid = meshToLevelSetScan(mesh, so, &stats.scan);
        }
        stats.scan.device = device ? "vulkan: " + device->deviceName() : "cpu";
        stats.scan.deviceNote = note;
    } else {
        MeshToLevelSetOptions mo;
        static_cast<GridSpec&>(mo) = band;
        mo.sign = sign;
        mo.validation = report;
        mo.windingAccuracy = o.windingAccuracy;
        mo.device = o.device;
        mo.deviceMemoryBudget = o.deviceMemoryBudget;
        mo.fillInterior = o.fillInterior && !expand; // after an expansion: below
        if (vector || wantPrimitive || wantAttributes) {
            LevelSetWithClosestPoints r = meshToLevelSetWithClosestPoints(mesh, mo, &stats.band);
            grid = r.levelSet;
            closest = r.closestPoints;
            closestTriangles = r.closestTriangles;
        } else {
            grid = meshToLevelSet(mesh, mo, &stats.band);
        }
        if (!vector) closest.reset(); // a primitive index needs the triangles only
        sign = stats.band.sign;
        if (!resolvedHere) signReason = stats.band.signReason;
        stats.filledVoxels = stats.band.filledVoxels;
    }
    if (wantFog && sign == SignMode::Unsigned)
        throw InvalidArgumentError("a fog grid needs an inside: it cannot be made with the unsigned sign mode");
    if (sign == SignMode::Winding && expand &&
        !(exteriorBand >= 1.0f && interiorBand >= 1.0f)) {
        std::ostringstream os;
        os << "the winding sign mode with an expansion needs an exact band of at least 1 voxel on each side, got "
           << exteriorBand << " outside and " << interiorBand << " inside";
        throw InvalidArgumentError(os.str());
    }

    std::string method = scan ? "erleben-dohlmann-t4-scan" : "chang2008-exact-band";
    if (expand) {
        ExpandLevelSetOptions eo;
        eo.exteriorWidth = exteriorTarget;
        eo.interiorWidth = interiorTarget;
        eo.inputExteriorWidth = exteriorBand;
        eo.inputInteriorWidth = interiorBand;
        eo.maxVoxels = o.maxVoxels;
        eo.interrupter = o.interrupter;
        if (vector) {
            // After a scan band there are no closest points: the offsets are estimated from φ.
            eo.method = ExpansionMethod::Vector;
            if (closest) eo.closestPoints = &closest->tree();
            if (closestTriangles) {
                eo.closestTriangles = &closestTriangles->tree();
                eo.mesh = &mesh;
            }
        }
        grid = expandLevelSet(*grid, eo, &stats.expansion);
        method += vector ? "+satherley-jones-vcvdt8" : "+zhao2005-fast-sweeping";
        if (sign == SignMode::Winding) {
            // the sweep signs what it adds from a flood fill of the band: sign everything beyond
            // the exact band (and every tile) by the winding number again
            FastWindingNumberOptions fo;
            fo.accuracy = o.windingAccuracy;
            fo.leafSizeWithoutCurrent = 64; // (without boundary current: a few estimates only)
            int64_t leftOut = -1;
            const auto fwn = winding_internal::signingWindingNumber(mesh, fo, leftOut);
            WindingSignStats ws;
            winding_internal::signTree(grid->tree(), grid->transform(), *fwn, mesh.bounds(), true,
                                       double(std::min(exteriorBand, interiorBand)) * h, ws, o.interrupter);
        }
    }
    if (o.fillInterior && (expand || scan)) stats.filledVoxels = winding_internal::activateInterior(grid->tree());

    stampLevelSetMetadata(*grid, exteriorTarget, interiorTarget, o.source.empty() ? mesh.source : o.source,
                          method);
    if (sign == SignMode::Unsigned) grid->setGridClass(openvdb::GRID_UNKNOWN); // a UDF has no inside
    grid->insertMeta(kSignMetadata, openvdb::StringMetadata(toString(sign)));
    if (o.fillInterior) grid->insertMeta(kFillInteriorMetadata, openvdb::BoolMetadata(true));
    else grid->removeMeta(kFillInteriorMetadata);
    stats.sign = sign;
    stats.signReason = signReason;
    stats.voxelSize = h;
    stats.exteriorBandVoxels = exteriorTarget;
    stats.interiorBandVoxels = interiorTarget;
    stats.method = method;

    MeshToSdfGrids out;
    if (o.transform) grid->setTransform(o.transform->copy());
    out.sdf = grid;
    if (wantFog) {
        SdfToFogOptions fo;
        fo.interiorWidthWorld = double(interiorTarget) * h;
        fo.gridName = o.fogGridName;
        fo.interrupter = o.interrupter;
        out.fog = sdfToFog(*grid, fo);
        out.fog->insertMeta(meta::kSource, openvdb::StringMetadata(o.source.empty() ? mesh.source : o.source));
        out.fog->insertMeta(meta::kGenerator, openvdb::StringMetadata(generatorString()));
    }
    if (wantPrimitive || wantAttributes) {
        // The exact band's closest triangles on the level set's active topology (voxels the
        // band computed but left inactive are dropped).
        const openvdb::FloatTree& sdfTree = grid->tree();
        openvdb::tree::LeafManager<openvdb::Int32Tree> leaves(closestTriangles->tree());
        leaves.foreach([&](openvdb::Int32Tree::LeafNodeType& leaf, size_t) {
            const openvdb::FloatTree::LeafNodeType* s = sdfTree.probeConstLeaf(leaf.origin());
            for (openvdb::Index i = 0; i < openvdb::Int32Tree::LeafNodeType::SIZE; ++i) {
                const int32_t tri = leaf.getValue(i);
                if (!(s && s->isValueOn(i) && leaf.isValueOn(i) && tri >= 0 && size_t(tri) < mesh.triangles.size()))
                    leaf.setValueOff(i, -1);
            }
        });
        openvdb::tools::pruneInactive(closestTriangles->tree());
    }
    if (wantAttributes) {
        // Before the primitive index renumbers the triangles in place; in the mesh's frame (the
        // closest-triangle grid's transform), then given the level set's transform.
        for (const std::string& a : o.attributes) {
            AttributeTransferOptions ao;
            ao.interrupter = o.interrupter;
            openvdb::GridBase::Ptr g = transferAttribute(mesh, a, *closestTriangles, ao);
            g->setTransform(grid->transform().copy());
            g->insertMeta(meta::kSource, openvdb::StringMetadata(o.source.empty() ? mesh.source : o.source));
            g->insertMeta(meta::kGenerator, openvdb::StringMetadata(generatorString()));
            out.attributes.push_back(g);
        }
    }
    if (wantPrimitive) {
        // The closest triangles, renumbered as input faces.
        openvdb::Int32Grid::Ptr prim = closestTriangles; // ours: renumbered in place
        openvdb::tree::LeafManager<openvdb::Int32Tree> leaves(prim->tree());
        leaves.foreach([&](openvdb::Int32Tree::LeafNodeType& leaf, size_t) {
            for (auto it = leaf.beginValueOn(); it; ++it) it.setValue(int32_t(mesh.sourceFace(size_t(*it))));
        });
        prim->setTransform(grid->transform().copy());
        prim->setName(o.primitiveIndexGridName);
        prim->setGridClass(openvdb::GRID_UNKNOWN);
        prim->insertMeta(meta::kSource, openvdb::StringMetadata(o.source.empty() ? mesh.source : o.source));
        prim->insertMeta(meta::kGenerator, openvdb::StringMetadata(generatorString()));
        out.primitiveIndex = prim;
    }
    stats.seconds = detail::secondsSince(t0);
    if (statsOut) *statsOut = stats;
    return out;
}

} // namespace

openvdb::FloatGrid::Ptr meshToSdf(const TriangleMesh& mesh, const MeshToSdfOptions& o, MeshToSdfStats* statsOut)
{
    return run(mesh, o, statsOut, false).sdf;
}

MeshToSdfGrids meshToSdfGrids(const TriangleMesh& mesh, const MeshToSdfOptions& o, MeshToSdfStats* statsOut)
{
    return run(mesh, o, statsOut, true);
}

} // namespace levelforge
