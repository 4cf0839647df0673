// SPDX-License-Identifier: Apache-2.0
// The conversions of the Python module: mesh_to_sdf, expand, volume_to_sdf, mesh_to_adf (Adf),
// csg, mesh and volume I/O, the exact reference and mesh validation. Each mirrors one operator
// of the CLI (houdini_like_tools/operators/), with the operator's parameters as keyword arguments
// and its defaults, and stamps the same metadata. See docs/python.md.
#include "Common.h"

#include <levelforge/adf/AdaptiveDistanceField.h>
#include <levelforge/core/Exceptions.h>
#include <levelforge/core/Metadata.h>
#include <levelforge/core/MeshValidation.h>
#include <levelforge/expand/ExpandLevelSet.h>
#include <levelforge/io/MeshIO.h>
#include <levelforge/io/VdbIO.h>
#include <levelforge/io/VolumeIO.h>
#include <levelforge/levelset/LevelSetCsg.h>
#include <levelforge/pipeline/MeshToSdf.h>
#include <levelforge/reference/ExactReference.h>
#include <levelforge/reference/MeshShapes.h>
#include <levelforge/volume/SparseVolumeToLevelSet.h>
#include <levelforge/volume/VolumeToLevelSet.h>

#include <openvdb/tools/Dense.h>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <pybind11/stl.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <sstream>
#include <type_traits>

namespace levelforge::python_internal {

namespace {

using namespace pybind11::literals;

/// The CLI's --max-voxels default for grids (GridParamSet::maxVoxels).
constexpr uint64_t kCliMaxVoxels = 2'000'000'000ull;

std::string meshSource(const py::object& source, size_t nv, size_t nf)
{
    if (!source.is_none()) return source.cast<std::string>();
    return "<numpy mesh: " + std::to_string(nv) + " vertices, " + std::to_string(nf) + " triangles>";
}

size_t rows(py::handle obj)
{
    py::object shape = py::getattr(obj, "shape", py::none());
    if (shape.is_none() || py::len(shape) == 0) return py::hasattr(obj, "__len__") ? py::len(obj) : 0;
    return shape.cast<py::tuple>()[0].cast<size_t>();
}

// ---------------------------------------------------------------- stats as dicts

py::dict bandStats(const MeshToLevelSetStats& s)
{
    return py::dict("triangles"_a = s.triangles, "skipped_degenerate"_a = s.skippedDegenerate,
                    "hierarchy_nodes"_a = s.hierarchyNodes, "clusters"_a = s.clusters,
                    "candidate_leaves"_a = s.candidateLeaves, "candidate_voxels"_a = s.candidateVoxels,
                    "active_voxels"_a = s.activeVoxels, "distance_evaluations"_a = s.distanceEvaluations,
                    "bound_tests"_a = s.boundTests, "node_tests"_a = s.nodeTests, "leaf_passes"_a = s.leafPasses,
                    "seconds_hierarchy"_a = s.secondsHierarchy, "seconds_candidates"_a = s.secondsCandidates,
                    "seconds_distance"_a = s.secondsDistance, "seconds_finish"_a = s.secondsFinish);
}

py::dict scanStats(const TetScanStats& s)
{
    return py::dict("triangles"_a = s.triangles, "skipped_degenerate"_a = s.skippedDegenerate,
                    "tetrahedra"_a = s.tetrahedra, "cross_sections"_a = s.crossSections, "slabs"_a = s.slabs,
                    "slab_items"_a = s.slabItems, "voxels_rasterized"_a = s.voxelsRasterized,
                    "active_voxels"_a = s.activeVoxels, "seconds_shell"_a = s.secondsShell,
                    "seconds_sort"_a = s.secondsSort, "seconds_sweep"_a = s.secondsSweep,
                    "seconds_fill"_a = s.secondsFill, "seconds_finish"_a = s.secondsFinish);
}

py::dict expandStats(const ExpandLevelSetStats& s)
{
    return py::dict("method"_a = s.method == ExpansionMethod::Vector ? "vector" : "sweep",
                    "input_exterior_width"_a = s.inputExteriorWidth, "input_interior_width"_a = s.inputInteriorWidth,
                    "frozen_voxels"_a = s.frozenVoxels, "candidate_voxels"_a = s.candidateVoxels,
                    "active_voxels"_a = s.activeVoxels, "leaf_updates"_a = s.leafUpdates,
                    "voxel_updates"_a = s.voxelUpdates, "iterations"_a = s.iterations, "max_change"_a = s.maxChange,
                    "converged"_a = s.converged, "unreached_voxels"_a = s.unreachedVoxels,
                    "refined_voxels"_a = s.refinedVoxels, "seconds_topology"_a = s.secondsTopology,
                    "seconds_sweep"_a = s.secondsSweep, "seconds_finish"_a = s.secondsFinish);
}

// ---------------------------------------------------------------- mesh I/O

/// A NumPy array viewing @p data (moved to the heap, freed with the array): no copy.
template<typename T, typename V>
py::array_t<T> viewOf(std::vector<V>&& data, size_t rowsCount)
{
    auto* owner = new std::vector<V>(std::move(data));
    py::capsule free(owner, [](void* p) { delete static_cast<std::vector<V>*>(p); });
    static_assert(sizeof(V) == 3 * sizeof(T), "three packed values per row");
    return py::array_t<T>({py::ssize_t(rowsCount), py::ssize_t(3)},
                          {py::ssize_t(sizeof(V)), py::ssize_t(sizeof(T))},
                          reinterpret_cast<const T*>(owner->data()), free);
}

TriangleMesh loadMesh(const std::string& path, const MeshReadOptions& options = {})
{
    if (isBuiltinMeshName(path)) {
        TriangleMesh m = makeBuiltinMesh(path);
        if (!options.attributes.empty())
            throw InvalidArgumentError(path + ": no vertex attribute '" + options.attributes.front() + "' (it has none)");
        return m;
    }
    MeshReadInfo info;
    return readMesh(path, options, info);
}

/// The names of an `attribute` argument: "Cd,N" (the CLI's form) or a sequence of names.
std::vector<std::string> attributeNames(py::handle obj)
{
    std::vector<std::string> names;
    auto add = [&](const std::string& list) {
        size_t start = 0;
        while (start <= list.size()) {
            const size_t comma = std::min(list.find(',', start), list.size());
            std::string n = list.substr(start, comma - start);
            n.erase(0, n.find_first_not_of(" \t"));
            n.erase(n.find_last_not_of(" \t") + 1);
            if (n.empty()) throw InvalidArgumentError("attribute: an empty attribute name in '" + list + "'");
            names.push_back(n);
            start = comma + 1;
        }
    };
    if (py::isinstance<py::str>(obj)) {
        add(obj.cast<std::string>());
    } else {
        for (py::handle h : obj) add(py::str(h).cast<std::string>());
    }
    return names;
}

/// Per-corner values of one attribute, float32 (M, 3, C).
py::array_t<float> cornerArray(const MeshAttribute& a, size_t triangles)
{
    const py::ssize_t C = a.components;
    py::array_t<float> out({py::ssize_t(triangles), py::ssize_t(3), C});
    std::copy(a.values.begin(), a.values.end(), out.mutable_data());
    return out;
}

py::tuple readMeshPy(py::handle pathObj, py::object attribute)
{
    const std::string path = toPath(pathObj);
    MeshReadOptions ro;
    if (!attribute.is_none()) ro.attributes = attributeNames(attribute);
    TriangleMesh mesh = runReleased([&] { return loadMesh(path, ro); });
    py::dict attrs;
    for (const MeshAttribute& a : mesh.attributes) attrs[py::str(a.name)] = cornerArray(a, mesh.triangles.size());
    std::vector<MeshAttribute>().swap(mesh.attributes);
    if (mesh.points.size() > size_t(std::numeric_limits<int32_t>::max())) {
        throw py::value_error(path + ": " + std::to_string(mesh.points.size()) +
                              " vertices cannot be indexed by int32 faces");
    }
    // Indices < 2^31 have the same bits as uint32 and int32: the faces are viewed, not copied.
    const size_t nv = mesh.points.size(), nf = mesh.triangles.size();
    if (attribute.is_none())
        return py::make_tuple(viewOf<double>(std::move(mesh.points), nv), viewOf<int32_t>(std::move(mesh.triangles), nf));
    return py::make_tuple(viewOf<double>(std::move(mesh.points), nv), viewOf<int32_t>(std::move(mesh.triangles), nf),
                          attrs);
}

void writeMeshPy(py::handle pathObj, py::handle vertices, py::handle faces)
{
    const std::string path = toPath(pathObj);
    TriangleMesh mesh = toMesh(vertices, faces, path);
    requireUsableMesh(mesh);
    runReleased([&] { writeMesh(mesh, path); });
}

py::dict validateMeshPy(py::handle vertices, py::handle faces, py::object source)
{
    TriangleMesh mesh = toMesh(vertices, faces, meshSource(source, rows(vertices), rows(faces)));
    MeshReport r = runReleased([&] { return validateMesh(mesh); });
    py::list warnings;
    for (const std::string& w : r.warnings()) warnings.append(w);
    return py::dict("closed"_a = r.closed(), "vertices"_a = r.vertices, "triangles"_a = r.triangles,
                    "edges"_a = r.edges, "degenerate_triangles"_a = r.degenerateTriangles,
                    "unused_vertices"_a = r.unusedVertices, "boundary_edges"_a = r.boundaryEdges,
                    "non_manifold_edges"_a = r.nonManifoldEdges,
                    "inconsistently_oriented_edges"_a = r.inconsistentlyOrientedEdges, "components"_a = r.components,
                    "non_manifold_vertices"_a = r.nonManifoldVertices,
                    "euler_characteristic"_a = r.eulerCharacteristic(), "warnings"_a = warnings,
                    "summary"_a = r.summary());
}

// ---------------------------------------------------------------- mesh_to_sdf

/// Sign modes (SignMode, MeshToSdfOptions::sign / fillInterior / windingAccuracy) are detected at
/// compile time, so that this file builds against a library with or without them. The names are
/// the library's own (toString(SignMode), found by argument-dependent lookup).
template<typename O, typename = void>
struct HasSignModes : std::false_type
{
};
template<typename O>
struct HasSignModes<O, std::void_t<decltype(std::declval<O&>().sign), decltype(std::declval<O&>().fillInterior),
                                   decltype(std::declval<O&>().windingAccuracy)>> : std::true_type
{
};

template<typename O>
void applySignOptions(O& o, const std::string& sign, bool fillInterior, double windingAccuracy)
{
    if constexpr (HasSignModes<O>::value) {
        using SignT = std::remove_reference_t<decltype(o.sign)>;
        bool found = false;
        for (SignT m : {SignT::Auto, SignT::Pseudonormal, SignT::Winding, SignT::Unsigned}) {
            if (sign == toString(m)) {
                o.sign = m;
                found = true;
            }
        }
        if (!found) throw InvalidArgumentError("unknown sign mode '" + sign + "' (auto, pseudonormal, winding, unsigned)");
        o.fillInterior = fillInterior;
        o.windingAccuracy = windingAccuracy;
    } else {
        if (sign != "auto" && sign != "pseudonormal")
            throw InvalidArgumentError("unknown sign mode '" + sign + "' (this levelforge signs by pseudonormals only)");
        if (fillInterior) throw InvalidArgumentError("fill_interior is not supported by this levelforge library");
    }
}

template<typename S>
void addSignStats(py::dict& d, const S& s)
{
    if constexpr (HasSignModes<MeshToSdfOptions>::value) {
        d["sign"] = toString(s.sign);
        d["sign_reason"] = s.signReason;
        d["filled_voxels"] = s.filledVoxels;
    } else {
        d["sign"] = "pseudonormal";
    }
}

constexpr bool kHaveSignModes = HasSignModes<MeshToSdfOptions>::value;

/// mesh_to_sdf(attribute={name: values}): per-vertex (N,), (N, C) or per-corner (M, 3, C) values,
/// C = 1 or 3, spread over the corners of @p mesh.
void addAttributes(TriangleMesh& mesh, py::handle obj)
{
    if (!py::isinstance<py::dict>(obj))
        throw InvalidArgumentError("attribute: give a dict {name: values} of per-vertex (N, C) or per-corner "
                                   "(M, 3, C) values (read_mesh(path, attribute='Cd,N') returns them for a file)");
    const size_t nV = mesh.points.size(), nT = mesh.triangles.size();
    for (auto item : obj.cast<py::dict>()) {
        MeshAttribute a;
        a.name = py::str(item.first).cast<std::string>();
        auto arr = py::array_t<float, py::array::c_style | py::array::forcecast>::ensure(item.second);
        if (!arr) {
            PyErr_Clear();
            throw InvalidArgumentError("attribute '" + a.name + "': the values are not a numeric array");
        }
        const py::ssize_t nd = arr.ndim();
        bool perVertex = false;
        int C = 0;
        if (nd == 1 && size_t(arr.shape(0)) == nV) {
            perVertex = true;
            C = 1;
        } else if (nd == 2 && size_t(arr.shape(0)) == nV) {
            perVertex = true;
            C = int(arr.shape(1));
        } else if (nd == 3 && size_t(arr.shape(0)) == nT && arr.shape(1) == 3) {
            C = int(arr.shape(2));
        }
        if (C != 1 && C != 3) {
            std::string shape;
            for (py::ssize_t d = 0; d < nd; ++d) shape += (d ? ", " : "") + std::to_string(arr.shape(d));
            throw InvalidArgumentError("attribute '" + a.name + "': expected per-vertex values (" + std::to_string(nV) +
                                       ", C) or per-corner values (" + std::to_string(nT) + ", 3, C) with C = 1 or 3, got (" +
                                       shape + ")");
        }
        a.components = C;
        const float* v = arr.data();
        if (perVertex) {
            a.values.resize(nT * 3 * size_t(C));
            for (size_t t = 0; t < nT; ++t)
                for (int k = 0; k < 3; ++k)
                    std::copy_n(v + size_t(mesh.triangles[t][k]) * size_t(C), size_t(C),
                                a.values.data() + (3 * t + size_t(k)) * size_t(C));
        } else {
            a.values.assign(v, v + nT * 3 * size_t(C));
        }
        mesh.attributes.push_back(std::move(a));
    }
}

/// The active voxels of a grid that is not a float grid: (coords int32 (K, 3), values (K,) or (K, 3)).
template<typename GridT>
py::tuple activeArrays(const GridT& grid)
{
    using ValueT = typename GridT::ValueType;
    constexpr bool vec = openvdb::VecTraits<ValueT>::IsVec;
    using Scalar = std::conditional_t<vec, float, ValueT>;
    const py::ssize_t k = py::ssize_t(grid.activeVoxelCount());
    py::array_t<int32_t> coords({k, py::ssize_t(3)});
    py::array_t<Scalar> values = vec ? py::array_t<Scalar>({k, py::ssize_t(3)}) : py::array_t<Scalar>(k);
    int32_t* c = coords.mutable_data();
    Scalar* v = values.mutable_data();
    py::ssize_t i = 0;
    for (auto it = grid.tree().cbeginValueOn(); it && i < k; ++it) {
        openvdb::CoordBBox box;
        it.getBoundingBox(box);
        for (auto ijk = box.begin(); ijk && i < k; ++ijk, ++i) {
            for (int a = 0; a < 3; ++a) c[3 * i + a] = (*ijk)[a];
            if constexpr (vec) {
                for (int a = 0; a < 3; ++a) v[3 * i + a] = float((*it)[a]);
            } else {
                v[i] = *it;
            }
        }
    }
    return py::make_tuple(coords, values);
}

/// A grid of meshToSdfGrids() for Python: a FloatGrid as a Grid, others as activeArrays().
py::object extraGrid(const openvdb::GridBase::Ptr& g)
{
    if (auto f = openvdb::gridPtrCast<openvdb::FloatGrid>(g)) return py::cast(PyGrid{f});
    if (auto i = openvdb::gridPtrCast<openvdb::Int32Grid>(g)) return activeArrays(*i);
    if (auto v = openvdb::gridPtrCast<openvdb::Vec3SGrid>(g)) return activeArrays(*v);
    throw InvalidArgumentError("grid '" + g->getName() + "' of type " + g->valueType() + " has no Python form");
}

py::object meshToSdfPy(py::handle vertices, py::handle faces, std::optional<double> voxelSize, int voxelCount,
                       double exteriorBand, double interiorBand, bool worldUnits, const std::string& expansion,
                       double exactBand, const std::string& method, const std::string& shell,
                       const std::string& shellCoverage, bool conservative, const std::string& sign,
                       bool fillInterior, double windingAccuracy, const std::string& device, uint64_t maxVoxels,
                       const std::string& gridName, py::object source, py::object fogGrid, py::object reference,
                       py::object primitiveIndexGrid, py::object attribute, py::object progress, bool returnStats)
{
    TriangleMesh mesh = toMesh(vertices, faces, meshSource(source, rows(vertices), rows(faces)));
    MeshToSdfOptions o;
    if (!attribute.is_none()) {
        addAttributes(mesh, attribute);
        for (const MeshAttribute& a : mesh.attributes) o.attributes.push_back(a.name);
    }
    if (!fogGrid.is_none()) o.fogGridName = fogGrid.cast<std::string>();
    if (!primitiveIndexGrid.is_none()) o.primitiveIndexGridName = primitiveIndexGrid.cast<std::string>();
    const bool extras = !fogGrid.is_none() || !primitiveIndexGrid.is_none() || !attribute.is_none();
    if (!reference.is_none() && voxelSize)
        throw InvalidArgumentError("reference and voxel_size cannot be combined: the reference gives the voxel size");
    if (voxelSize) {
        if (!(*voxelSize > 0.0) || !std::isfinite(*voxelSize)) {
            std::ostringstream os;
            os << "voxel_size must be a finite number > 0 (world units), got " << *voxelSize;
            throw InvalidArgumentError(os.str());
        }
        o.voxelSize = *voxelSize;
    } else {
        o.voxelCount = voxelCount;
    }
    o.exteriorWidth = exteriorBand;
    o.interiorWidth = interiorBand;
    o.units = worldUnits ? WidthUnits::World : WidthUnits::Voxels;
    o.maxVoxels = maxVoxels;
    o.gridName = gridName;
    o.method = bandMethodFromString(method);
    o.expansion = expansionFromString(expansion);
    o.exactBandVoxels = exactBand;
    o.shell = shellMethodFromString(shell);
    o.coverage = shellCoverageFromString(shellCoverage);
    o.conservative = conservative;
    applySignOptions(o, sign, fillInterior, windingAccuracy);
    o.device = parseComputeDevice(device);
    if (!reference.is_none()) {
        // the CLI's --reference: its transform, and its band widths unless they were changed here
        const std::string refPath = toPath(reference);
        const ReferenceGrid r = runReleased([&] { return readReferenceGrid(refPath); });
        o.transform = r.transform;
        const double toUnits = o.units == WidthUnits::World ? r.voxelSize : 1.0;
        if (exteriorBand == 3.0 && r.exteriorBandVoxels > 0.0) o.exteriorWidth = r.exteriorBandVoxels * toUnits;
        if (interiorBand == 3.0 && r.interiorBandVoxels > 0.0) o.interiorWidth = r.interiorBandVoxels * toUnits;
    }
    o.source = mesh.source;
    PyInterrupter interrupter(std::move(progress));
    o.interrupter = &interrupter;
    MeshToSdfStats stats;
    MeshToSdfGrids grids = runReleased(interrupter, [&] {
        if (extras) return meshToSdfGrids(mesh, o, &stats);
        MeshToSdfGrids g;
        g.sdf = meshToSdf(mesh, o, &stats);
        return g;
    });
    openvdb::FloatGrid::Ptr grid = grids.sdf;
    py::object result = py::cast(PyGrid{grid});
    if (extras) {
        py::dict all;
        for (const openvdb::GridBase::Ptr& g : grids.all()) all[py::str(g->getName())] = extraGrid(g);
        result = all;
    }
    if (!returnStats) return result;
    py::dict d("voxel_size"_a = stats.voxelSize, "exterior_band_voxels"_a = stats.exteriorBandVoxels,
               "interior_band_voxels"_a = stats.interiorBandVoxels, "method"_a = stats.method,
               "seconds"_a = stats.seconds, "active_voxels"_a = uint64_t(grid->activeVoxelCount()));
    addSignStats(d, stats);
    if (o.method == BandMethod::Chang) d["band"] = bandStats(stats.band);
    else d["scan"] = scanStats(stats.scan);
    if (o.expansion != Expansion::None) d["expansion"] = expandStats(stats.expansion);
    return py::make_tuple(result, d);
}

// ---------------------------------------------------------------- expand

py::object expandPy(py::handle gridObj, double exteriorWidth, double interiorWidth, bool worldUnits,
                    bool fillInterior, const std::string& domain, double bboxMargin, const std::string& method,
                    double tolerance, int maxIterations, uint64_t maxVoxels, py::object source, py::object progress,
                    bool returnStats)
{
    const PyGrid& in = toGrid(gridObj, "grid");
    ExpandLevelSetOptions opt;
    opt.exteriorWidth = exteriorWidth;
    opt.interiorWidth = interiorWidth;
    opt.units = worldUnits ? WidthUnits::World : WidthUnits::Voxels;
    opt.fillInterior = fillInterior;
    if (domain == "band") opt.domain = ExpansionDomain::Band;
    else if (domain == "bbox") opt.domain = ExpansionDomain::BoundingBox;
    else throw InvalidArgumentError("unknown domain '" + domain + "' (band, bbox)");
    opt.boundingBoxMargin = bboxMargin;
    opt.tolerance = tolerance;
    opt.maxIterations = maxIterations;
    opt.maxVoxels = maxVoxels;
    bool vector = false;
    if (method == "vector") vector = true;
    else if (method != "sweep") throw InvalidArgumentError("unknown expansion method '" + method + "' (sweep, vector)");
    opt.method = vector ? ExpansionMethod::Vector : ExpansionMethod::Sweep;
    std::string src;
    if (!source.is_none()) {
        src = source.cast<std::string>();
    } else if (openvdb::Metadata::Ptr m = (*in.grid)[meta::kSource]) {
        src = m->str();
    }
    PyInterrupter interrupter(std::move(progress));
    opt.interrupter = &interrupter;
    ExpandLevelSetStats st;
    const openvdb::FloatGrid& input = *in.grid;
    openvdb::FloatGrid::Ptr out = runReleased(interrupter, [&] { return expandLevelSet(input, opt, &st); });
    // The CLI's metadata (houdini_like_tools/operators/Expand.cc).
    const double h = out->voxelSize()[0];
    const double bg = out->background() / h;
    const bool box = opt.domain == ExpansionDomain::BoundingBox;
    const double ext = box ? bg : opt.widthInVoxels(opt.exteriorWidth, h);
    const double inw = (box || opt.fillInterior) ? bg : opt.widthInVoxels(opt.interiorWidth, h);
    stampLevelSetMetadata(*out, ext, inw, src, vector ? "satherley-jones-vcvdt8" : "zhao2005-fast-sweeping");
    py::object result = py::cast(PyGrid{out});
    if (!returnStats) return result;
    return py::make_tuple(result, expandStats(st));
}

// ---------------------------------------------------------------- volumes

/// A dense volume over the active box of @p grid grown by @p padding voxels, as the CLI reads a
/// .vdb volume (readVdbVolume): inactive voxels keep the tree's value; linear, axis-aligned
/// transforms with positive scale only.
ScalarVolume denseFromGrid(const openvdb::FloatGrid& grid, int padding, uint64_t maxVoxels)
{
    const openvdb::CoordBBox active = grid.evalActiveVoxelBoundingBox();
    if (active.empty() || grid.activeVoxelCount() == 0)
        throw InvalidArgumentError("volume: grid '" + grid.getName() + "' has no active voxels");
    const openvdb::math::Transform& xf = grid.transform();
    if (!xf.isLinear()) throw InvalidArgumentError("volume: grid '" + grid.getName() + "' has a non-linear transform");
    const openvdb::Mat4d m = xf.baseMap()->getAffineMap()->getMat4();
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
            if ((i == j) ? !(m(i, j) > 0.0) : m(i, j) != 0.0)
                throw InvalidArgumentError("volume: grid '" + grid.getName() +
                                           "' has a rotated, sheared or mirrored transform (axis-aligned scale and "
                                           "translation only)");
    openvdb::CoordBBox box = active;
    box.expand(std::max(0, padding));
    const openvdb::Coord d = box.dim();
    const double count = double(d.x()) * double(d.y()) * double(d.z());
    if (maxVoxels > 0 && count > double(maxVoxels)) {
        std::ostringstream os;
        os << "volume: grid '" << grid.getName() << "' densified over " << box.min() << " - " << box.max() << " holds "
           << uint64_t(count) << " samples, more than max_voxels = " << maxVoxels;
        throw ResourceLimitError(os.str());
    }
    ScalarVolume vol(d, 0.0f, openvdb::Vec3d(m(0, 0), m(1, 1), m(2, 2)), xf.indexToWorld(box.min()));
    openvdb::tools::Dense<float, openvdb::tools::LayoutXYZ> dense(box, vol.data.data());
    openvdb::tools::copyToDense(grid, dense);
    return vol;
}

py::object volumeToSdfPy(py::handle volume, py::handle spacing, py::handle origin, float iso, bool invert,
                         const std::string& method, bool subvoxel, double exteriorBand, double interiorBand,
                         bool fillInterior, bool sparse, const std::string& device, uint64_t maxVoxels,
                         const std::string& gridName, py::object source, py::object progress, bool returnStats)
{
    VolumeToLevelSetOptions opt;
    opt.device = parseComputeDevice(device);
    opt.iso = iso;
    opt.insideBelow = invert;
    opt.method = volumeDistanceMethodFromName(method);
    opt.subvoxel = subvoxel;
    opt.exteriorWidth = exteriorBand;
    opt.interiorWidth = interiorBand;
    opt.fillInterior = fillInterior;
    opt.maxVoxels = maxVoxels;
    opt.gridName = gridName;
    const bool isGrid = py::isinstance<PyGrid>(volume);
    std::string src = source.is_none() ? std::string() : source.cast<std::string>();

    ScalarVolume vol;
    openvdb::FloatGrid::ConstPtr field;
    if (isGrid) {
        const openvdb::Vec3d s = toTriple(spacing, "spacing"), o = toTriple(origin, "origin");
        if (s != openvdb::Vec3d(1.0) || o != openvdb::Vec3d(0.0)) {
            throw py::value_error("volume_to_sdf: a Grid brings its own spacing and origin (its transform); "
                                  "leave spacing and origin at their defaults");
        }
        field = toGrid(volume, "volume").grid;
        if (src.empty()) src = "<grid '" + field->getName() + "'>";
    } else {
        if (sparse) throw py::value_error("volume_to_sdf: sparse=True needs a Grid (a sparse .vdb volume), not an array");
        if (volume.is_none()) throw py::type_error("volume must be a 3-D array of samples or a Grid, got None");
        py::array a = py::module_::import("numpy").attr("asarray")(volume).cast<py::array>();
        if (a.ndim() != 3) {
            throw py::value_error("volume must be a 3-D array indexed [i, j, k] (x, y, z), got " +
                                  std::to_string(a.ndim()) + " dimension(s), shape " +
                                  std::string(py::str(py::tuple(a.attr("shape")))));
        }
        const char kind = a.dtype().kind();
        if (kind != 'f' && kind != 'i' && kind != 'u' && kind != 'b') {
            throw py::value_error("volume must hold real numbers, got dtype " + std::string(py::str(a.dtype())));
        }
        if (a.shape(0) == 0 || a.shape(1) == 0 || a.shape(2) == 0) {
            throw py::value_error("volume is empty (shape " + std::string(py::str(py::tuple(a.attr("shape")))) + ")");
        }
        for (int k = 0; k < 3; ++k)
            if (a.shape(k) > py::ssize_t(std::numeric_limits<int32_t>::max()))
                throw py::value_error("volume: a dimension exceeds 2^31 - 1 samples");
        // x fastest, as ScalarVolume stores it: a Fortran-ordered float32 view (a copy only when
        // the array is not already one).
        auto f = py::array_t<float, py::array::f_style | py::array::forcecast>::ensure(a);
        vol.dims = openvdb::Coord(int(a.shape(0)), int(a.shape(1)), int(a.shape(2)));
        vol.spacing = toTriple(spacing, "spacing");
        vol.origin = toTriple(origin, "origin");
        for (int k = 0; k < 3; ++k)
            if (!std::isfinite(vol.origin[k])) throw py::value_error("origin must be finite");
        const double count = double(vol.dims.x()) * double(vol.dims.y()) * double(vol.dims.z());
        if (maxVoxels > 0 && count > double(maxVoxels)) {
            std::ostringstream os;
            os << "volume of " << uint64_t(count) << " samples exceeds max_voxels = " << maxVoxels;
            throw ResourceLimitError(os.str());
        }
        vol.data.resize(size_t(count));
        std::memcpy(vol.data.data(), f.data(), vol.data.size() * sizeof(float));
        if (src.empty()) src = "<numpy volume " + std::to_string(a.shape(0)) + "x" + std::to_string(a.shape(1)) + "x" +
                               std::to_string(a.shape(2)) + ">";
    }

    PyInterrupter interrupter(std::move(progress));
    opt.interrupter = &interrupter;
    py::dict stats;
    openvdb::FloatGrid::Ptr grid;
    std::string methodName = std::string("satherley-jones-") + volumeDistanceMethodName(opt.method);
    double hmin = 0.0;
    if (sparse) {
        if (!subvoxel) {
            throw InvalidArgumentError("sparse=True needs subvoxel=True (the sparse path builds the sub-voxel shell)");
        }
        SparseVolumeToLevelSetStats st;
        const openvdb::FloatGrid& in = *field;
        grid = runReleased(interrupter, [&] { return sparseVolumeToLevelSet(in, opt, &st); });
        hmin = grid->voxelSize()[0];
        methodName += "-subvoxel-sparse";
        stats = py::dict("candidate_cells"_a = st.candidateCells, "surface_cells"_a = st.surfaceCells,
                         "triangles"_a = st.triangles, "exact_voxels"_a = st.exactVoxels,
                         "active_voxels"_a = st.activeVoxels, "exact_band"_a = st.exactBand, "widened"_a = st.widened,
                         "seconds_surface"_a = st.secondsSurface, "seconds_exact"_a = st.secondsExact,
                         "seconds_widen"_a = st.secondsWiden);
    } else {
        if (isGrid) {
            // As the CLI densifies a .vdb input: the active box plus the band, so that the band
            // around data that reaches the box is not clipped.
            const double band = std::max(exteriorBand, fillInterior ? 0.0 : interiorBand);
            const int padding = int(std::min(std::ceil(band) + 1.0, 1.0e6));
            const openvdb::FloatGrid& in = *field;
            vol = runReleased([&] { return denseFromGrid(in, padding, maxVoxels); });
        }
        // Samples must be finite (as the CLI's volume readers require).
        const size_t bad = runReleased([&] {
            return size_t(std::find_if(vol.data.begin(), vol.data.end(), [](float x) { return !std::isfinite(x); }) -
                          vol.data.begin());
        });
        if (bad < vol.data.size()) {
            const size_t nx = size_t(vol.dims.x()), ny = size_t(vol.dims.y());
            std::ostringstream os;
            os << "volume[" << bad % nx << ", " << (bad / nx) % ny << ", " << bad / (nx * ny) << "] is "
               << vol.data[bad] << "; samples must be finite";
            throw InvalidArgumentError(os.str());
        }
        VolumeToLevelSetStats st;
        grid = runReleased(interrupter, [&] { return volumeToLevelSet(vol, opt, &st); });
        hmin = std::min({vol.spacing[0], vol.spacing[1], vol.spacing[2]});
        methodName += subvoxel ? "-subvoxel" : "-binary";
        stats = py::dict("feature_voxels"_a = st.featureVoxels, "shell_voxels"_a = st.shell.shellVoxels,
                         "shell_triangles"_a = st.shell.triangles, "active_voxels"_a = st.activeVoxels,
                         "seconds_classify"_a = st.secondsClassify, "seconds_transform"_a = st.secondsTransform,
                         "seconds_build"_a = st.secondsBuild);
    }
    // The CLI's metadata (houdini_like_tools/operators/VolumeToSdf.cc).
    stampLevelSetMetadata(*grid, opt.exteriorWidth, opt.fillInterior ? grid->background() / hmin : opt.interiorWidth,
                          src, methodName);
    grid->insertMeta(meta::kIso, openvdb::FloatMetadata(opt.iso));
    py::object result = py::cast(PyGrid{grid});
    if (!returnStats) return result;
    return py::make_tuple(result, stats);
}

/// The inverse of volumeValueTypeName().
VolumeValueType valueTypeFromName(const std::string& t)
{
    for (VolumeValueType v : {VolumeValueType::UInt8, VolumeValueType::Int8, VolumeValueType::UInt16,
                              VolumeValueType::Int16, VolumeValueType::UInt32, VolumeValueType::Int32,
                              VolumeValueType::UInt64, VolumeValueType::Int64, VolumeValueType::Float32,
                              VolumeValueType::Float64})
        if (volumeValueTypeName(v) == t) return v;
    throw InvalidArgumentError("unknown raw sample type '" + t +
                               "' (uint8, int8, uint16, int16, uint32, int32, uint64, int64, float32, float64)");
}

py::tuple readVolumePy(py::handle pathObj, py::object vdbGrid, int padding, py::object rawDims,
                       const std::string& rawType, py::handle rawSpacing, uint64_t rawHeaderBytes, bool rawBigEndian,
                       uint64_t maxVoxels)
{
    const std::string path = toPath(pathObj);
    ReadVolumeOptions ro;
    if (!vdbGrid.is_none()) ro.vdbGridName = vdbGrid.cast<std::string>();
    if (padding < 0) throw py::value_error("padding must be >= 0");
    ro.vdbPadding = padding;
    ro.maxVoxels = maxVoxels;
    if (!rawDims.is_none()) {
        RawVolumeLayout raw;
        const openvdb::Vec3d d = toTriple(rawDims, "raw_dims");
        for (int a = 0; a < 3; ++a) {
            if (!(d[a] >= 1) || d[a] != std::floor(d[a]) || d[a] > 2147483647.0)
                throw py::value_error("raw_dims must be three positive integers");
            raw.dims[a] = int(d[a]);
        }
        raw.type = valueTypeFromName(rawType);
        raw.bigEndian = rawBigEndian;
        raw.spacing = toTriple(rawSpacing, "raw_spacing");
        raw.headerBytes = rawHeaderBytes;
        ro.raw = raw;
    }
    VolumeInfo info;
    ScalarVolume vol = runReleased([&] { return readVolume(path, ro, &info); });
    // ScalarVolume is x fastest: a Fortran-ordered (nx, ny, nz) array indexed [i, j, k], viewing
    // the samples (no copy).
    const py::ssize_t nx = vol.dims.x(), ny = vol.dims.y(), nz = vol.dims.z();
    auto* owner = new std::vector<float>(std::move(vol.data));
    py::capsule free(owner, [](void* p) { delete static_cast<std::vector<float>*>(p); });
    const py::ssize_t f = sizeof(float);
    py::array_t<float> samples({nx, ny, nz}, {f, f * nx, f * nx * ny}, owner->data(), free);
    return py::make_tuple(samples, py::make_tuple(vol.spacing[0], vol.spacing[1], vol.spacing[2]),
                          py::make_tuple(vol.origin[0], vol.origin[1], vol.origin[2]));
}

// ---------------------------------------------------------------- ADF

py::array_t<double> adfQuery(const AdaptiveDistanceField& adf, py::handle points, int what, bool& single)
{
    auto pts = asQueryPoints(points, "points", single);
    const size_t n = size_t(pts.shape(0));
    const double* p = pts.data();
    py::array_t<double> out = what == 1 ? py::array_t<double>({py::ssize_t(n), py::ssize_t(3)})
                                        : py::array_t<double>(static_cast<py::ssize_t>(n));
    double* o = out.mutable_data();
    runReleased([&] {
        tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 256), [&](const tbb::blocked_range<size_t>& r) {
            for (size_t i = r.begin(); i < r.end(); ++i) {
                const Vec3d x(p[3 * i], p[3 * i + 1], p[3 * i + 2]);
                if (what == 0) {
                    o[i] = adf.distance(x);
                } else if (what == 1) {
                    const Vec3d g = adf.gradient(x);
                    o[3 * i] = g[0];
                    o[3 * i + 1] = g[1];
                    o[3 * i + 2] = g[2];
                } else {
                    o[i] = double(adf.level(x));
                }
            }
        });
    });
    return out;
}

py::object meshToAdfPy(py::handle vertices, py::handle faces, std::optional<double> voxelSize, int voxelCount,
                       double tolerance, double padding, bool bounds, int boundStride, uint64_t maxVoxels,
                       const std::string& gridName, py::object source, py::object progress, bool returnStats)
{
    TriangleMesh mesh = toMesh(vertices, faces, meshSource(source, rows(vertices), rows(faces)));
    AdaptiveDistanceFieldOptions opt;
    if (voxelSize) {
        if (!(*voxelSize > 0.0) || !std::isfinite(*voxelSize)) {
            std::ostringstream os;
            os << "voxel_size must be a finite number > 0 (world units), got " << *voxelSize;
            throw InvalidArgumentError(os.str());
        }
        opt.voxelSize = *voxelSize;
    } else {
        opt.voxelCount = voxelCount;
    }
    opt.toleranceVoxels = tolerance;
    opt.paddingVoxels = padding;
    opt.computeBounds = bounds;
    opt.boundStride = boundStride;
    opt.maxVoxels = maxVoxels;
    opt.gridName = gridName;
    PyInterrupter interrupter(std::move(progress));
    opt.interrupter = &interrupter;
    AdaptiveDistanceFieldStats s;
    AdaptiveDistanceField adf = runReleased(interrupter, [&] { return meshToAdaptiveDistanceField(mesh, opt, &s); });
    py::object result = py::cast(PyAdf{adf});
    if (!returnStats) return result;
    py::list levelBounds;
    for (double b : s.levelBoundVoxels) levelBounds.append(b);
    py::dict d("voxel_size"_a = s.voxelSize, "triangles"_a = s.triangles, "boundary_cells"_a = s.boundaryCells,
               "leaves"_a = s.leaves, "level1_tiles"_a = s.level1Tiles, "level2_tiles"_a = s.level2Tiles,
               "type1"_a = s.type1, "type2"_a = s.type2, "type3"_a = s.type3, "hanging"_a = s.hanging,
               "refined_tiles"_a = s.refinedTiles, "level_bound_voxels"_a = levelBounds,
               "domain_voxels"_a = s.domainVoxels, "memory_bytes"_a = s.memoryBytes, "seconds"_a = s.secondsTotal());
    return py::make_tuple(result, d);
}

// ---------------------------------------------------------------- CSG

/// The CLI's csg (houdini_like_tools/operators/Csg.cc): two ADFs on one transform give an ADF
/// (unless level_set); otherwise level sets, an ADF input resampled with the other's band.
py::object csgPy(py::handle aObj, py::handle bObj, const std::string& opName, bool levelSet, py::object bandObj)
{
    auto gridOf = [](py::handle o, const char* what) -> openvdb::FloatGrid::Ptr {
        if (py::isinstance<PyAdf>(o)) {
            const PyAdf& a = o.cast<const PyAdf&>();
            if (!a.adf.valid()) throw py::value_error(std::string(what) + " is an empty Adf");
            return openvdb::ConstPtrCast<openvdb::FloatGrid>(a.adf.grid());
        }
        if (py::isinstance<PyGrid>(o)) return toGrid(o, what).grid;
        throw py::type_error(std::string(what) + " must be a levelforge.Grid or levelforge.Adf, got " +
                             std::string(py::str(py::type::handle_of(o).attr("__name__"))));
    };
    const CsgOperation op = csgOperationFromString(opName);
    openvdb::FloatGrid::Ptr a = gridOf(aObj, "a"), b = gridOf(bObj, "b");
    const bool adfA = isAdaptiveDistanceField(*a), adfB = isAdaptiveDistanceField(*b);
    std::optional<double> band;
    if (!bandObj.is_none()) band = bandObj.cast<double>();
    if (adfA && adfB && a->transform() == b->transform() && !levelSet) {
        AdaptiveDistanceField r = runReleased([&] {
            return csgAdaptiveDistanceFields(AdaptiveDistanceField(a), AdaptiveDistanceField(b), op);
        });
        return py::cast(PyAdf{r});
    }
    auto bandVoxels = [](const openvdb::FloatGrid& g) { return double(g.background()) / g.voxelSize()[0]; };
    const double w = band ? *band : (!adfA ? bandVoxels(*a) : (!adfB ? bandVoxels(*b) : 3.0));
    openvdb::FloatGrid::Ptr r = runReleased([&] {
        openvdb::FloatGrid::Ptr la = adfA ? adaptiveDistanceFieldToLevelSet(AdaptiveDistanceField(a), w) : a;
        openvdb::FloatGrid::Ptr lb = adfB ? adaptiveDistanceFieldToLevelSet(AdaptiveDistanceField(b), w) : b;
        return csgLevelSets(*la, *lb, op);
    });
    return py::cast(PyGrid{r});
}

// ---------------------------------------------------------------- exact reference

py::object exactSignedDistancePy(py::handle vertices, py::handle faces, py::handle points, bool bruteForce,
                                 bool returnClosest)
{
    TriangleMesh mesh = toMesh(vertices, faces, meshSource(py::none(), rows(vertices), rows(faces)));
    requireUsableMesh(mesh);
    bool single = false;
    auto pts = asQueryPoints(points, "points", single);
    const size_t n = size_t(pts.shape(0));
    const double* p = pts.data();
    py::array_t<double> dist(static_cast<py::ssize_t>(n));
    py::array_t<int64_t> tri = returnClosest ? py::array_t<int64_t>(static_cast<py::ssize_t>(n)) : py::array_t<int64_t>();
    py::array_t<double> cp = returnClosest ? py::array_t<double>({py::ssize_t(n), py::ssize_t(3)}) : py::array_t<double>();
    double* d = dist.mutable_data();
    int64_t* t = returnClosest ? tri.mutable_data() : nullptr;
    double* c = returnClosest ? cp.mutable_data() : nullptr;
    runReleased([&] {
        const ExactReference ref(mesh);
        tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 64), [&](const tbb::blocked_range<size_t>& r) {
            for (size_t i = r.begin(); i < r.end(); ++i) {
                const Vec3d x(p[3 * i], p[3 * i + 1], p[3 * i + 2]);
                const ExactReference::Result q = bruteForce ? ref.bruteForce(x) : ref.query(x);
                d[i] = q.distance;
                if (t) {
                    t[i] = q.triangle == ~0u ? -1 : int64_t(q.triangle);
                    c[3 * i] = q.closestPoint[0];
                    c[3 * i + 1] = q.closestPoint[1];
                    c[3 * i + 2] = q.closestPoint[2];
                }
            }
        });
    });
    if (!returnClosest) {
        if (single) return py::float_(d[0]);
        return std::move(dist);
    }
    if (single) return py::make_tuple(d[0], t[0], cp.attr("reshape")(3));
    return py::make_tuple(dist, tri, cp);
}

std::string adfRepr(const PyAdf& a)
{
    if (!a.adf.valid()) return "<levelforge.Adf (empty)>";
    std::ostringstream os;
    const auto& d = a.adf.indexDomain();
    os << "<levelforge.Adf '" << a.adf.grid()->getName() << "': finest voxel " << a.adf.voxelSize() << ", domain "
       << d.min() << " - " << d.max() << ">";
    return os.str();
}

} // namespace

void bindConvert(py::module_& m)
{
    m.attr("HAVE_SIGN_MODES") = kHaveSignModes;
    m.def("read_mesh", &readMeshPy, py::arg("path"), py::kw_only(), py::arg("attribute") = py::none(), R"doc(
Reads a triangle mesh (OBJ, OFF, PLY, STL; polygons are triangulated), or builds a built-in one
("builtin:torus-knot", "builtin:sphere", "builtin:box"), as the CLI's mesh input does.

Returns (vertices, faces): vertices float64 (N, 3), world units; faces int32 (M, 3), vertex
indices, counter-clockwise seen from outside. The arrays view the library's buffers (no copy).
attribute: also read per-vertex attributes, by name as the CLI's --attribute ("Cd,N" or a list:
    "Cd" colour, "N" normal, "uv", or a PLY vertex property by its name); then returns
    (vertices, faces, {name: float32 (M, 3, C)}), the values at each triangle corner (OBJ vt / vn
    belong to face corners: seams are kept). A name the file does not have raises
    InvalidArgumentError listing those it has.
Raises IoError (missing or unreadable file, unknown extension) or InvalidMeshError (bad content;
the message names the file, the element and the value).
)doc");
    m.def("write_mesh", &writeMeshPy, py::arg("path"), py::arg("vertices"), py::arg("faces"), R"doc(
Writes a triangle mesh atomically; the extension chooses the format: .obj, .off (ASCII, shortest
round-trip decimals), .ply (binary, double coordinates) or .stl (binary, single precision).
The mesh is checked first (ValueError for bad shapes, NaN coordinates, out-of-range indices).
Raises IoError when the file cannot be written (nothing is left behind).
)doc");
    m.def("validate_mesh", &validateMeshPy, py::arg("vertices"), py::arg("faces"), py::arg("source") = py::none(),
          R"doc(
Checks a mesh as `levelforge mesh-to-sdf --report` does (core/MeshValidation.h): returns a dict with
'closed' (watertight and consistently oriented: the sign of the distance is a true inside/outside),
counts of boundary, non-manifold and inconsistently oriented edges, degenerate triangles, unused
vertices, components, the Euler characteristic, 'warnings' (the lines the CLI prints) and
'summary'. Raises InvalidMeshError for fatal problems (no triangles, NaN, index out of range).
)doc");

    m.def("mesh_to_sdf", &meshToSdfPy, py::arg("vertices"), py::arg("faces"), py::kw_only(),
          py::arg("voxel_size") = py::none(), py::arg("voxel_count") = 256, py::arg("exterior_band") = 3.0,
          py::arg("interior_band") = 3.0, py::arg("world_units") = false, py::arg("expansion") = "none",
          py::arg("exact_band") = 3.0, py::arg("method") = "chang", py::arg("shell") = "obb",
          py::arg("shell_coverage") = "complete", py::arg("conservative") = false, py::arg("sign") = "auto",
          py::arg("fill_interior") = false, py::arg("winding_accuracy") = 2.0, py::arg("device") = "auto",
          py::arg("max_voxels") = kCliMaxVoxels, py::arg("grid_name") = "surface", py::arg("source") = py::none(),
          py::arg("fog_grid") = py::none(), py::arg("reference") = py::none(),
          py::arg("primitive_index_grid") = py::none(), py::arg("attribute") = py::none(),
          py::arg("progress") = py::none(), py::arg("return_stats") = false, R"doc(
Triangle mesh -> narrow-band signed distance level set: `levelforge mesh-to-sdf`
(levelforge::meshToSdf) with the operator's parameters and defaults.

vertices: (N, 3) array-like of world positions (any real dtype; converted to float64).
faces: (M, 3) array-like of integer vertex indices (>= 0), counter-clockwise seen from outside.
voxel_size: voxel edge length, world units; None (default): derived from voxel_count.
voxel_count: voxels along the longest side of the mesh bounding box, used when voxel_size is
    None (default 256).
exterior_band, interior_band: half-widths of the band outside / inside the surface, in voxels
    (world units with world_units=True); default 3 each. A voxel is active when
    -interior_band < d / voxel_size < exterior_band.
expansion: "none" (or "exact"; the whole band is exact), "sweep" (exact within exact_band
    voxels, then fast sweeping) or "vector" (exact within exact_band, then closest-point
    vectors, VCVDT).
exact_band: half-width of the exact band computed before an expansion, voxels (default 3).
method: "chang" (exact band, Chang et al. 2008) or "scan" (T4 scan conversion of tetrahedral
    shells, Erleben-Dohlmann); shell ("obb", "pseudonormal", "thin", "offset"),
    shell_coverage ("complete", "paper") and conservative apply to "scan".
sign: "auto" (default: pseudonormal for closed, consistently oriented meshes, winding number
    otherwise), "pseudonormal", "winding" (inside where the generalized winding number
    |w| > 1/2: holes, cracks, self-intersections) or "unsigned" (the unsigned distance; grid
    class 'unknown'). fill_interior: every inside voxel active (exact in the band,
    -background deeper). winding_accuracy: the fast winding number's beta (> 1, default 2).
    (Available when the library has sign modes: levelforge.HAVE_SIGN_MODES.)
device: "auto" (a discrete Vulkan GPU for large bands, else the CPU), "cpu" or "vulkan" (DeviceError
    when there is no usable Vulkan device); the grid is bit-identical on every device (docs/gpu.md).
max_voxels: refuse work whose voxel budget exceeds this (0: no limit), ResourceLimitError.
grid_name: the grid name (default "surface"). source: the levelforge:source metadata and the
    prefix of error messages (default: a description of the arrays).
progress: None or a callable progress(stage: str, percent: int), called from this thread as the
    work advances; an exception it raises stops the work and propagates.
return_stats: also return a dict of what each stage did (the CLI's --report counters).
fog_grid: also make a fog volume of this name (--fog-grid; Houdini's Build Fog).
reference: a .vdb file whose first float grid gives the transform (--reference), and its band
    widths unless exterior_band / interior_band differ from their default 3; not with voxel_size.
primitive_index_grid: also make the closest input face of every active voxel, under this name
    (--primitive-index-grid; needs method "chang", expansion "none", no fill_interior).
attribute: {name: values}: transfer attributes to grids of the same names (--attribute; same
    needs as primitive_index_grid): per-vertex (N,) / (N, C) or per-corner (M, 3, C) values,
    C = 1 or 3, as read_mesh(path, attribute="Cd,N") returns them. Each active voxel gets the
    barycentric interpolation at its exact closest point.

Returns a Grid (the library's result, not copied), or (Grid, stats) with return_stats. With
fog_grid, primitive_index_grid or attribute: a dict {grid name: grid} of every grid the CLI
would write, in its order: float grids (the level set, the fog, 1-component attributes) as
Grid, the primitive index as (coords int32 (K, 3), values int32 (K,)) and 3-component
attributes as (coords, values float32 (K, 3)), coords in the level set's index space.
The GIL is released while the library works; Ctrl-C raises KeyboardInterrupt promptly.
Raises InvalidMeshError (no triangles, NaN, index out of range), InvalidArgumentError (bad
options), ValueError (bad array shapes or dtypes), ResourceLimitError.
)doc");

    m.def("expand", &expandPy, py::arg("grid"), py::kw_only(), py::arg("exterior_width") = 20.0,
          py::arg("interior_width") = 20.0, py::arg("world_units") = false, py::arg("fill_interior") = false,
          py::arg("domain") = "band", py::arg("bbox_margin") = 10.0, py::arg("method") = "sweep",
          py::arg("tolerance") = 1e-4, py::arg("max_iterations") = 50, py::arg("max_voxels") = kCliMaxVoxels,
          py::arg("source") = py::none(), py::arg("progress") = py::none(), py::arg("return_stats") = false, R"doc(
Widens (or narrows) the band of a level set: `levelforge expand` (levelforge::expandLevelSet).
The input is not modified; a new Grid is returned.

exterior_width, interior_width: target half-widths, voxels (world units with world_units=True);
    default 20 each.
fill_interior: activate every voxel inside the surface (interior_width is then ignored).
domain: "band" (the widths around the surface) or "bbox" (every voxel of the input's bounding
    box grown by bbox_margin voxels).
method: "sweep" (Zhao's fast sweeping) or "vector" (closest-point vectors, 8-pass VCVDT).
tolerance: changes of at most this (voxels) are not passed on; max_iterations: sweeps per leaf.
source: the levelforge:source metadata (default: the input's).
progress, return_stats, max_voxels: as in mesh_to_sdf.
)doc");

    m.def("volume_to_sdf", &volumeToSdfPy, py::arg("volume"), py::arg("spacing") = py::make_tuple(1.0, 1.0, 1.0),
          py::arg("origin") = py::make_tuple(0.0, 0.0, 0.0), py::kw_only(), py::arg("iso") = 0.0f,
          py::arg("invert") = false, py::arg("method") = "vcvdt8", py::arg("subvoxel") = false,
          py::arg("exterior_band") = 3.0, py::arg("interior_band") = 3.0, py::arg("fill_interior") = false,
          py::arg("sparse") = false, py::arg("device") = "auto", py::arg("max_voxels") = kCliMaxVoxels,
          py::arg("grid_name") = "surface",
          py::arg("source") = py::none(), py::arg("progress") = py::none(), py::arg("return_stats") = false, R"doc(
Scalar volume -> signed distance level set: `levelforge volume-to-sdf` (Satherley-Jones distance
transforms; levelforge::volumeToLevelSet) with the operator's parameters and defaults.

volume: a 3-D array-like indexed [i, j, k] (x, y, z), any real or bool dtype (converted to
    float32), sample (i, j, k) at world position origin + (i, j, k) * spacing; or a Grid (a
    fog volume or any scalar field), densified over its active box plus the band as the CLI
    does for a .vdb input, or kept sparse with sparse=True.
spacing: voxel spacing, one number or three (world units); origin: world position of sample
    (0, 0, 0). Both come from the transform for a Grid.
iso: samples >= iso are inside (negative); invert=True: samples <= iso are inside.
method: "vcvdt8" (default), "vcvdt4", "evdt", "evdt-grid", "exact", or a chamfer metric
    ("city-block", "chessboard", "quasi-euclidean-3", "complete-3", "quasi-euclidean-5";
    binary only).
subvoxel: seed the transform with exact closest points on the interpolated surface instead of
    binary feature voxels (default False, as the CLI's --subvoxel flag).
device: where method="exact" runs: "auto" (a discrete Vulkan GPU for large volumes), "cpu" or
    "vulkan"; bit-identical on every device.
exterior_band, interior_band: half-widths kept, voxels of the smallest spacing (default 3);
    fill_interior keeps every inside voxel active.
sparse: a Grid input converted on its own sparse topology (needs subvoxel=True, method
    "vcvdt8" or "exact").
max_voxels: samples (dense) or band voxels (sparse) allowed, default 2e9 as the CLI.
The result is stamped with the CLI's metadata (band widths, method, levelforge:iso).
)doc");

    m.def("read_volume", &readVolumePy, py::arg("path"), py::kw_only(), py::arg("vdb_grid") = py::none(),
          py::arg("padding") = 0, py::arg("raw_dims") = py::none(), py::arg("raw_type") = "uint8",
          py::arg("raw_spacing") = py::make_tuple(1.0, 1.0, 1.0), py::arg("raw_header_bytes") = 0,
          py::arg("raw_big_endian") = false, py::arg("max_voxels") = uint64_t(1) << 31, R"doc(
Reads a scalar volume (.nii, .nii.gz, .inr, .inr.gz, .den, raw with raw_dims, .vdb) as the CLI's
volume-to-sdf does. Returns (samples, spacing, origin): samples float32 (nx, ny, nz) indexed
[i, j, k] (a Fortran-ordered view of the library's buffer, no copy), spacing and origin tuples;
ready for volume_to_sdf(samples, spacing, origin). vdb_grid: the .vdb grid to read (default:
the first scalar grid); padding: voxels added around a .vdb grid's active box.
Raises IoError, InvalidVolumeError, ResourceLimitError.
)doc");

    py::class_<PyAdf>(m, "Adf", R"doc(
An adaptively sampled distance field (Yin, Liu, Wu 2011) on the VDB tile hierarchy: a FloatGrid
whose samples reconstruct a continuous (C0, trilinear) signed distance. Made by mesh_to_adf(),
Adf.read(), Adf(grid) or csg() of two ADFs. Queries are thread-safe and release the GIL.
)doc")
        .def(py::init([](py::handle g) { return PyAdf{AdaptiveDistanceField(toGrid(g, "grid").grid)}; }),
             py::arg("grid"),
             "Wraps a Grid holding an ADF (levelforge:adf metadata). Raises InvalidArgumentError otherwise.")
        .def_property_readonly("grid", [](const PyAdf& a) {
            return PyGrid{openvdb::ConstPtrCast<openvdb::FloatGrid>(a.adf.grid())};
        }, "The ADF's grid (shared, not copied).")
        .def_property_readonly("voxel_size", [](const PyAdf& a) { return a.adf.voxelSize(); },
                               "The finest voxel edge length, world units.")
        .def_property_readonly("index_domain", [](const PyAdf& a) {
            const auto& d = a.adf.indexDomain();
            return py::make_tuple(py::make_tuple(d.min().x(), d.min().y(), d.min().z()),
                                  py::make_tuple(d.max().x(), d.max().y(), d.max().z()));
        }, "Domain of the reconstruction, index space (sample lattice, inclusive).")
        .def_property_readonly("world_domain", [](const PyAdf& a) {
            const openvdb::BBoxd d = a.adf.worldDomain();
            return py::make_tuple(py::make_tuple(d.min()[0], d.min()[1], d.min()[2]),
                                  py::make_tuple(d.max()[0], d.max()[1], d.max()[2]));
        }, "Domain of the reconstruction, world units ((xmin, ymin, zmin), (xmax, ymax, zmax)).")
        .def_property_readonly("level_bounds", [](const PyAdf& a) {
            py::list l;
            for (int i = 0; i < kAdfLevels; ++i) l.append(a.adf.levelBoundVoxels(i));
            return l;
        }, "Stated error bound of each level (cells 1, 2, 4, 8, 128 voxels), voxels; -1 when unknown.")
        .def("sample", [](const PyAdf& a, py::handle points) -> py::object {
            bool single = false;
            py::array_t<double> r = adfQuery(a.adf, points, 0, single);
            if (single) return py::float_(r.data()[0]);
            return std::move(r);
        }, py::arg("points"),
           "Signed distance (world units, negative inside) at world points ((N, 3) or (3,)): float64 (N,), or a "
           "float for one point. Outside the domain: the value at the nearest domain point plus the distance to it.")
        .def("gradient", [](const PyAdf& a, py::handle points) -> py::object {
            bool single = false;
            py::array_t<double> r = adfQuery(a.adf, points, 1, single);
            if (single) return r.attr("reshape")(3);
            return std::move(r);
        }, py::arg("points"), "Gradient of the reconstruction at world points: float64 (N, 3).")
        .def("level", [](const PyAdf& a, py::handle points) -> py::object {
            bool single = false;
            py::array_t<double> r = adfQuery(a.adf, points, 2, single);
            if (single) return py::int_(int(r.data()[0]));
            return r.attr("astype")("int32");
        }, py::arg("points"),
           "Level of the cell holding each point (index into cells 1, 2, 4, 8, 128 voxels; -1 outside): int32 (N,).")
        .def("to_level_set", [](const PyAdf& a, double halfWidth) {
            return PyGrid{runReleased([&] { return adaptiveDistanceFieldToLevelSet(a.adf, halfWidth); })};
        }, py::arg("half_width") = 3.0,
           "An ordinary narrow-band level set sampled from the ADF at the voxel centres (half_width in finest "
           "voxels).")
        .def("write", [](const PyAdf& a, py::handle path) { writeFloatGrids(toPath(path), {a.adf.grid()}); },
             py::arg("path"), "Writes the ADF's grid to a .vdb file atomically (as Grid.write).")
        .def_static("read", [](py::handle path, py::object name) {
            const std::string n = name.is_none() ? std::string() : name.cast<std::string>();
            return PyAdf{AdaptiveDistanceField(readFloatGridReleased(toPath(path), n))};
        }, py::arg("path"), py::arg("name") = py::none(),
           "Reads an ADF from a .vdb file (the float grid named name, default the first).")
        .def("__repr__", &adfRepr);

    m.def("mesh_to_adf", &meshToAdfPy, py::arg("vertices"), py::arg("faces"), py::kw_only(),
          py::arg("voxel_size") = py::none(), py::arg("voxel_count") = 256, py::arg("tolerance") = 0.0,
          py::arg("padding") = 8.0, py::arg("bounds") = true, py::arg("bound_stride") = 8,
          py::arg("max_voxels") = uint64_t(64) << 30, py::arg("grid_name") = "adf", py::arg("source") = py::none(),
          py::arg("progress") = py::none(), py::arg("return_stats") = false, R"doc(
Triangle mesh -> adaptively sampled distance field: `levelforge mesh-to-adf`
(levelforge::meshToAdaptiveDistanceField) with the operator's parameters and defaults.

voxel_size / voxel_count: the finest voxel (as in mesh_to_sdf; default 256 voxels along the
    longest side).
tolerance: Frisken refinement threshold, voxels (0: the paper's fixed sampling).
padding: margin of the domain around the mesh, finest voxels (at least 9 is used).
bounds: compute the stated error bound per level (the CLI's --no-bounds is bounds=False);
bound_stride: check every N-th finest cell for it (default 8, as the CLI).
max_voxels: the dense equivalent of the domain allowed (default 64 Gi). grid_name: "adf".
Returns an Adf, or (Adf, stats) with return_stats.
)doc");

    m.def("csg", &csgPy, py::arg("a"), py::arg("b"), py::arg("op") = "union", py::kw_only(),
          py::arg("level_set") = false, py::arg("band") = py::none(), R"doc(
Union, intersection or difference of two level sets or ADFs: `levelforge csg`.

op: "union" min(a, b), "intersection" max(a, b), "difference" max(a, -b) (a without b).
Two ADFs on the same transform give an Adf (unless level_set=True). Otherwise the result is a
level set Grid (openvdb::tools::csg*Copy); an ADF input is first resampled to a level set with
the other input's band (or band voxels; 3 when both are ADFs). Both inputs must have the same
transform. The inputs are not modified.
)doc");

    m.def("exact_signed_distance", &exactSignedDistancePy, py::arg("vertices"), py::arg("faces"), py::arg("points"),
          py::kw_only(), py::arg("brute_force") = false, py::arg("return_closest") = false, R"doc(
The exact signed distance from world points to a mesh (levelforge::ExactReference: a BVH, double
precision, sign by the angle-weighted pseudonormal rule): the oracle the tests and benchmarks
measure every converter against. Returns float64 (N,) (a float for one point of shape (3,));
with return_closest=True also the closest triangle (int64, -1 for a mesh of degenerate
triangles only) and closest point (float64 (N, 3)). brute_force=True tests every triangle.
)doc");
}

} // namespace levelforge::python_internal
