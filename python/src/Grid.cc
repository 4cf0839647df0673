// SPDX-License-Identifier: Apache-2.0
// levelforge.Grid and levelforge.Transform: a float grid seen from NumPy (active voxels, sampling,
// dense copies, metadata, .vdb files). See docs/python.md.
#include "Common.h"

#include <levelforge/core/Exceptions.h>
#include <levelforge/io/VdbIO.h>

#include <openvdb/tools/Dense.h>
#include <openvdb/tools/Interpolation.h>
#include <openvdb/tree/LeafManager.h>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <pybind11/stl.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <sstream>
#include <vector>

namespace levelforge::python_internal {

namespace {

using FloatTree = openvdb::FloatTree;
using LeafT = FloatTree::LeafNodeType;
using ConstAccessor = openvdb::tree::ValueAccessor<const FloatTree, /*IsSafe=*/false>;

/// Index coordinates beyond this (in magnitude) lie outside every tree OpenVDB can hold; samples
/// there return the background instead of converting an out-of-range double to int.
constexpr double kMaxIndex = double(1 << 30);

struct PyTransform
{
    openvdb::math::Transform::Ptr xform;
};

// ---------------------------------------------------------------- active voxels

/// Where each leaf's active voxels go in the output arrays, and the active tiles after them.
struct ActiveLayout
{
    std::vector<const LeafT*> leaves;
    std::vector<size_t> offsets; // leaves.size() + 1
    struct Tile
    {
        openvdb::CoordBBox box;
        float value;
        size_t offset;
    };
    std::vector<Tile> tiles;
    size_t total = 0;
};

ActiveLayout activeLayout(const FloatTree& tree)
{
    ActiveLayout L;
    tree.getNodes(L.leaves);
    L.offsets.assign(L.leaves.size() + 1, 0);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, L.leaves.size()), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t i = r.begin(); i < r.end(); ++i) L.offsets[i + 1] = L.leaves[i]->onVoxelCount();
    });
    for (size_t i = 0; i < L.leaves.size(); ++i) L.offsets[i + 1] += L.offsets[i];
    L.total = L.offsets.back();
    FloatTree::ValueOnCIter it = tree.cbeginValueOn();
    it.setMaxDepth(FloatTree::ValueOnCIter::LEAF_DEPTH - 1); // tiles only
    for (; it; ++it) {
        if (it.getDepth() == FloatTree::ValueOnCIter::LEAF_DEPTH) continue;
        openvdb::CoordBBox box;
        it.getBoundingBox(box);
        L.tiles.push_back({box, *it, L.total});
        L.total += size_t(box.volume());
    }
    return L;
}

void fillActive(const ActiveLayout& L, int32_t* coords, float* values)
{
    tbb::parallel_for(tbb::blocked_range<size_t>(0, L.leaves.size()), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t i = r.begin(); i < r.end(); ++i) {
            size_t o = L.offsets[i];
            for (auto v = L.leaves[i]->cbeginValueOn(); v; ++v, ++o) {
                if (coords) {
                    const openvdb::Coord c = v.getCoord();
                    coords[3 * o] = c.x();
                    coords[3 * o + 1] = c.y();
                    coords[3 * o + 2] = c.z();
                }
                if (values) values[o] = *v;
            }
        }
    });
    for (const ActiveLayout::Tile& t : L.tiles) {
        size_t o = t.offset;
        for (auto c = t.box.begin(); c; ++c, ++o) {
            if (coords) {
                coords[3 * o] = (*c).x();
                coords[3 * o + 1] = (*c).y();
                coords[3 * o + 2] = (*c).z();
            }
            if (values) values[o] = t.value;
        }
    }
}

/// coords (K, 3) int32 and/or values (K,) float32 of the active voxels, in the same order.
py::tuple activeVoxels(const PyGrid& g, bool wantCoords, bool wantValues)
{
    const FloatTree& tree = g.grid->tree();
    ActiveLayout L = runReleased([&] { return activeLayout(tree); });
    const py::ssize_t k = py::ssize_t(L.total);
    py::array_t<int32_t> coords = wantCoords ? py::array_t<int32_t>({k, py::ssize_t(3)}) : py::array_t<int32_t>();
    py::array_t<float> values = wantValues ? py::array_t<float>(k) : py::array_t<float>();
    int32_t* c = wantCoords ? coords.mutable_data() : nullptr;
    float* v = wantValues ? values.mutable_data() : nullptr;
    runReleased([&] { fillActive(L, c, v); });
    return py::make_tuple(coords, values);
}

// ---------------------------------------------------------------- sampling

/// Index coordinates within kSnap of an integer are moved onto it: a world position computed from
/// a voxel centre (index * voxel size + origin) comes back from worldToIndex() a few ulps off the
/// integer, and the trilinear weights would then mix in a neighbour's value at the 1e-9 level. With
/// the snap, sampling at voxel centres returns the stored values exactly; elsewhere the sample moves
/// by at most kSnap voxels.
constexpr double kSnap = 1e-9;

openvdb::Vec3d snapToCentres(openvdb::Vec3d ijk)
{
    for (int a = 0; a < 3; ++a) {
        const double r = std::round(ijk[a]);
        if (std::abs(ijk[a] - r) <= kSnap) ijk[a] = r;
    }
    return ijk;
}

template<typename Sampler>
void sampleInto(const openvdb::FloatGrid& grid, const double* p, float* out, size_t n)
{
    const openvdb::math::Transform& xform = grid.transform();
    const float background = grid.background();
    tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 1024), [&](const tbb::blocked_range<size_t>& r) {
        ConstAccessor acc(grid.tree());
        for (size_t i = r.begin(); i < r.end(); ++i) {
            const openvdb::Vec3d ijk = xform.worldToIndex(openvdb::Vec3d(p[3 * i], p[3 * i + 1], p[3 * i + 2]));
            if (!(std::abs(ijk[0]) < kMaxIndex && std::abs(ijk[1]) < kMaxIndex && std::abs(ijk[2]) < kMaxIndex)) {
                out[i] = background;
                continue;
            }
            float v = 0.0f;
            Sampler::sample(acc, snapToCentres(ijk), v);
            out[i] = v;
        }
    });
}

py::object sampleGrid(const PyGrid& g, py::handle points, int order)
{
    if (order < 0 || order > 2) {
        throw py::value_error("order must be 0 (nearest voxel), 1 (trilinear) or 2 (triquadratic), got " +
                              std::to_string(order));
    }
    bool single = false;
    auto pts = asQueryPoints(points, "points", single);
    const size_t n = size_t(pts.shape(0));
    py::array_t<float> out(static_cast<py::ssize_t>(n));
    const double* p = pts.data();
    float* o = out.mutable_data();
    const openvdb::FloatGrid& grid = *g.grid;
    runReleased([&] {
        if (order == 0) sampleInto<openvdb::tools::PointSampler>(grid, p, o, n);
        else if (order == 1) sampleInto<openvdb::tools::BoxSampler>(grid, p, o, n);
        else sampleInto<openvdb::tools::QuadraticSampler>(grid, p, o, n);
    });
    if (single) return py::float_(double(o[0]));
    return std::move(out);
}

/// Integer index coordinates (K, 3) (or one (3,)) as int32.
py::array_t<int32_t, py::array::c_style> asIndexCoords(py::handle obj, bool& single)
{
    py::array a = py::module_::import("numpy").attr("asarray")(obj).cast<py::array>();
    single = a.ndim() == 1 && a.shape(0) == 3;
    if (single) a = a.attr("reshape")(1, 3).cast<py::array>();
    if (a.ndim() != 2 || a.shape(1) != 3) {
        throw py::value_error("ijk must be an (N, 3) array of integer index coordinates, got shape " +
                              std::string(py::str(py::tuple(a.attr("shape")))));
    }
    const char kind = a.dtype().kind();
    if (a.shape(0) > 0 && kind != 'i' && kind != 'u') {
        throw py::value_error("ijk must hold integers, got dtype " + std::string(py::str(a.dtype())));
    }
    auto wide = py::array_t<int64_t, py::array::c_style | py::array::forcecast>::ensure(a);
    const int64_t* d = wide.data();
    const py::ssize_t n = wide.shape(0);
    py::array_t<int32_t, py::array::c_style> out({n, py::ssize_t(3)});
    int32_t* o = out.mutable_data();
    for (py::ssize_t i = 0; i < 3 * n; ++i) {
        if (d[i] < std::numeric_limits<int32_t>::min() || d[i] > std::numeric_limits<int32_t>::max()) {
            throw py::value_error("ijk[" + std::to_string(i / 3) + "] is outside the 32-bit index range");
        }
        o[i] = int32_t(d[i]);
    }
    return out;
}

py::object valuesAt(const PyGrid& g, py::handle ijk)
{
    bool single = false;
    auto c = asIndexCoords(ijk, single);
    const size_t n = size_t(c.shape(0));
    py::array_t<float> out(static_cast<py::ssize_t>(n));
    const int32_t* d = c.data();
    float* o = out.mutable_data();
    const FloatTree& tree = g.grid->tree();
    runReleased([&] {
        tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 4096), [&](const tbb::blocked_range<size_t>& r) {
            ConstAccessor acc(tree);
            for (size_t i = r.begin(); i < r.end(); ++i)
                o[i] = acc.getValue(openvdb::Coord(d[3 * i], d[3 * i + 1], d[3 * i + 2]));
        });
    });
    if (single) return py::float_(double(o[0]));
    return std::move(out);
}

// ---------------------------------------------------------------- dense

openvdb::CoordBBox toBBox(py::handle obj)
{
    py::array a;
    try {
        a = py::module_::import("numpy").attr("asarray")(obj).cast<py::array>();
    } catch (py::error_already_set& e) {
        if (!e.matches(PyExc_ValueError)) throw;
        a = py::array();
    }
    if (a.ndim() != 2 || a.shape(0) != 2 || a.shape(1) != 3 || (a.dtype().kind() != 'i' && a.dtype().kind() != 'u')) {
        throw py::value_error("bbox must be ((imin, jmin, kmin), (imax, jmax, kmax)): two integer index "
                              "triples, inclusive");
    }
    auto d = py::array_t<int64_t, py::array::c_style | py::array::forcecast>::ensure(a);
    const int64_t* v = d.data();
    for (int i = 0; i < 6; ++i)
        if (std::abs(double(v[i])) > kMaxIndex) throw py::value_error("bbox lies outside the index range +-2^30");
    const openvdb::CoordBBox box{openvdb::Coord(int(v[0]), int(v[1]), int(v[2])), openvdb::Coord(int(v[3]), int(v[4]), int(v[5]))};
    if (box.empty()) throw py::value_error("bbox is empty: every min must be <= its max (inclusive bounds)");
    return box;
}

py::array toDense(const PyGrid& g, py::handle bboxObj, uint64_t maxVoxels)
{
    openvdb::CoordBBox box;
    if (bboxObj.is_none()) {
        box = g.grid->evalActiveVoxelBoundingBox();
        if (box.empty() || g.grid->activeVoxelCount() == 0) return py::array_t<float>({0, 0, 0});
    } else {
        box = toBBox(bboxObj);
    }
    const openvdb::Coord d = box.dim();
    const double count = double(d.x()) * double(d.y()) * double(d.z());
    if (maxVoxels > 0 && count > double(maxVoxels)) {
        std::ostringstream os;
        os << "to_dense: the box " << box.min() << " - " << box.max() << " holds " << uint64_t(count)
           << " voxels, more than max_voxels = " << maxVoxels << " (pass a larger max_voxels, or 0 for no limit)";
        throw ResourceLimitError(os.str());
    }
    py::array_t<float> out({py::ssize_t(d.x()), py::ssize_t(d.y()), py::ssize_t(d.z())});
    float* data = out.mutable_data();
    const openvdb::FloatGrid& grid = *g.grid;
    runReleased([&] {
        // LayoutZYX: z fastest, i.e. a C-ordered array indexed [x, y, z] (as pyopenvdb's copyToArray)
        openvdb::tools::Dense<float, openvdb::tools::LayoutZYX> dense(box, data);
        openvdb::tools::copyToDense(grid, dense);
    });
    return std::move(out);
}

// ---------------------------------------------------------------- transforms

py::array_t<double> mapPoints(const openvdb::math::Transform& xf, py::handle pts, bool toWorld, py::object& scalarShape)
{
    py::array a = py::module_::import("numpy").attr("asarray")(pts).cast<py::array>();
    const bool single = a.ndim() == 1 && a.shape(0) == 3;
    if (single) a = a.attr("reshape")(1, 3).cast<py::array>();
    auto p = asPointArray(a, toWorld ? "ijk" : "xyz", true);
    const py::ssize_t n = p.shape(0);
    py::array_t<double> out({n, py::ssize_t(3)});
    const double* s = p.data();
    double* o = out.mutable_data();
    for (py::ssize_t i = 0; i < n; ++i) {
        const openvdb::Vec3d v(s[3 * i], s[3 * i + 1], s[3 * i + 2]);
        const openvdb::Vec3d r = toWorld ? xf.indexToWorld(v) : xf.worldToIndex(v);
        o[3 * i] = r[0];
        o[3 * i + 1] = r[1];
        o[3 * i + 2] = r[2];
    }
    scalarShape = py::bool_(single);
    return out;
}

py::object mapPointsResult(const openvdb::math::Transform& xf, py::handle pts, bool toWorld)
{
    py::object single;
    py::array_t<double> r = mapPoints(xf, pts, toWorld, single);
    if (single.cast<bool>()) return r.attr("reshape")(3);
    return std::move(r);
}

std::string transformRepr(const openvdb::math::Transform& xf)
{
    std::ostringstream os;
    const openvdb::Vec3d vs = xf.voxelSize();
    const openvdb::Vec3d o = xf.indexToWorld(openvdb::Vec3d(0.0));
    os << "levelforge.Transform(" << xf.mapType() << ", voxel_size=(" << vs[0] << ", " << vs[1] << ", " << vs[2]
       << "), index (0,0,0) at world (" << o[0] << ", " << o[1] << ", " << o[2] << "))";
    return os.str();
}

// ---------------------------------------------------------------- files

openvdb::FloatGrid::Ptr readFloatGrid(const std::string& path, const std::string& name)
{
    openvdb::GridPtrVecPtr grids = readGrids(path);
    for (const auto& g : *grids) {
        if (!g) continue;
        if (!name.empty() && g->getName() != name) continue;
        if (!g->isType<openvdb::FloatGrid>()) {
            if (name.empty()) continue;
            throw IoError(path + ": grid '" + name + "' is not a float grid (it holds " + g->valueType() + ")");
        }
        return openvdb::gridPtrCast<openvdb::FloatGrid>(g);
    }
    throw IoError(path + ": no float grid" + (name.empty() ? std::string() : " named '" + name + "'"));
}

} // namespace

/// The file writer shared by Grid.write, Adf.write and write_grids: a shallow copy of each grid
/// (its own metadata and transform, the tree shared) is taken with the GIL held, then written
/// atomically with the GIL released, the CLI's "creator" file metadata included.
void writeFloatGrids(const std::string& path, const std::vector<openvdb::FloatGrid::ConstPtr>& grids)
{
    openvdb::GridPtrVec copies;
    for (const auto& g : grids) copies.push_back(openvdb::ConstPtrCast<openvdb::FloatGrid>(g)->copyGrid());
    openvdb::MetaMap fileMeta;
    fileMeta.insertMeta("creator", openvdb::StringMetadata(generatorString()));
    runReleased([&] { writeGridsAtomic(path, copies, fileMeta); });
}

openvdb::FloatGrid::Ptr readFloatGridReleased(const std::string& path, const std::string& name)
{
    return runReleased([&] { return readFloatGrid(path, name); });
}

py::list readAllFloatGrids(const std::string& path)
{
    openvdb::GridPtrVecPtr grids = runReleased([&] { return readGrids(path); });
    py::list out;
    for (const auto& g : *grids)
        if (g && g->isType<openvdb::FloatGrid>()) out.append(PyGrid{openvdb::gridPtrCast<openvdb::FloatGrid>(g)});
    return out;
}

std::string gridRepr(const PyGrid& g)
{
    if (!g.grid) return "<levelforge.Grid (empty)>";
    std::ostringstream os;
    os << "<levelforge.Grid '" << g.grid->getName() << "': "
       << openvdb::GridBase::gridClassToString(g.grid->getGridClass()) << ", voxel size " << g.grid->voxelSize()[0]
       << ", " << g.grid->activeVoxelCount() << " active voxels, background " << g.grid->background() << ">";
    return os.str();
}

void bindGrid(py::module_& m)
{
    py::class_<PyTransform>(m, "Transform", R"doc(
The map between a grid's index space (integer voxel coordinates, voxel centres) and world
space, OpenVDB's math::Transform. levelforge's grids use linear transforms: world = index *
voxel_size + translation (anisotropic spacing for volumes). Obtain one from Grid.transform.
)doc")
        .def_property_readonly("voxel_size", [](const PyTransform& t) {
            const openvdb::Vec3d v = t.xform->voxelSize();
            return py::make_tuple(v[0], v[1], v[2]);
        }, "Voxel edge lengths along x, y, z (world units), a tuple of three floats.")
        .def_property_readonly("is_linear", [](const PyTransform& t) { return t.xform->isLinear(); },
                               "True for affine maps (every map levelforge makes).")
        .def_property_readonly("matrix", [](const PyTransform& t) {
            if (!t.xform->isLinear()) throw py::value_error("the transform is not linear (a frustum map): no 4x4 matrix");
            const openvdb::Mat4d mat = t.xform->baseMap()->getAffineMap()->getMat4();
            py::array_t<double> out({4, 4});
            for (int i = 0; i < 4; ++i)
                for (int j = 0; j < 4; ++j) out.mutable_at(i, j) = mat(i, j);
            return out;
        }, "The 4x4 affine matrix in OpenVDB's row-vector convention: [x y z 1] = [i j k 1] @ matrix "
           "(the translation is the last row).")
        .def("index_to_world", [](const PyTransform& t, py::handle ijk) { return mapPointsResult(*t.xform, ijk, true); },
             py::arg("ijk"),
             "World positions (float64 (N, 3), or (3,) for one point) of index coordinates ijk ((N, 3) or (3,), "
             "integers or fractions; integers are voxel centres).")
        .def("world_to_index", [](const PyTransform& t, py::handle xyz) { return mapPointsResult(*t.xform, xyz, false); },
             py::arg("xyz"),
             "Fractional index coordinates (float64 (N, 3), or (3,) for one point) of world positions xyz. "
             "numpy.rint() of the result gives the nearest voxel.")
        .def("__eq__", [](const PyTransform& a, const PyTransform& b) { return *a.xform == *b.xform; })
        .def("__repr__", [](const PyTransform& t) { return transformRepr(*t.xform); });

    py::class_<PyGrid>(m, "Grid", R"doc(
A sparse float grid (openvdb::FloatGrid), usually a narrow-band signed distance level set:
values in world units, negative inside, inactive voxels +-background.

A Grid shares its tree with whoever else holds it (no copies are made: mesh_to_sdf() hands the
library's result over as it is; to_openvdb() shares it with pyopenvdb). Use copy() for an
independent grid. Reading a Grid from several threads is safe; the methods release the GIL.

Make one with mesh_to_sdf(), volume_to_sdf(), expand(), csg(), Adf.to_level_set(),
Grid.read() or Grid.from_openvdb().
)doc")
        .def_property("name", [](const PyGrid& g) { return g.grid->getName(); },
                      [](PyGrid& g, const std::string& n) { g.grid->setName(n); }, "The grid name (str).")
        .def_property_readonly("voxel_size", [](const PyGrid& g) { return g.grid->voxelSize()[0]; },
                               "Voxel edge length along x, world units (float). For anisotropic grids (volumes "
                               "with unequal spacing) see transform.voxel_size.")
        .def_property_readonly("transform", [](const PyGrid& g) { return PyTransform{g.grid->transform().copy()}; },
                               "The index <-> world map (a Transform, a copy of the grid's).")
        .def_property_readonly("background", [](const PyGrid& g) { return double(g.grid->background()); },
                               "The background value (a level set's exterior band width, world units).")
        .def_property_readonly("grid_class", [](const PyGrid& g) {
            return openvdb::GridBase::gridClassToString(g.grid->getGridClass());
        }, "'level set', 'fog volume', 'staggered' or 'unknown'.")
        .def_property_readonly("is_level_set", [](const PyGrid& g) { return g.grid->getGridClass() == openvdb::GRID_LEVEL_SET; },
                               "Whether the grid class is 'level set'.")
        .def_property_readonly("active_voxel_count", [](const PyGrid& g) { return uint64_t(g.grid->activeVoxelCount()); },
                               "Number of active voxels (int).")
        .def_property_readonly("active_bbox", [](const PyGrid& g) -> py::object {
            const openvdb::CoordBBox b = g.grid->evalActiveVoxelBoundingBox();
            if (b.empty() || g.grid->activeVoxelCount() == 0) return py::none();
            return py::make_tuple(py::make_tuple(b.min().x(), b.min().y(), b.min().z()),
                                  py::make_tuple(b.max().x(), b.max().y(), b.max().z()));
        }, "Bounding box of the active voxels, ((imin, jmin, kmin), (imax, jmax, kmax)), index space, inclusive; "
           "None for a grid without active voxels.")
        .def_property_readonly("memory_bytes", [](const PyGrid& g) { return uint64_t(g.grid->memUsage()); },
                               "Memory used by the grid's tree, bytes.")
        .def("active_coords", [](const PyGrid& g) -> py::object { return activeVoxels(g, true, false)[0]; },
             "Index coordinates of the active voxels, int32 (K, 3), K = active_voxel_count. Same order as "
             "active_values(): each leaf node's voxels, leaves in tree order, then voxels of active tiles.")
        .def("active_values", [](const PyGrid& g) -> py::object { return activeVoxels(g, false, true)[1]; },
             "Values of the active voxels, float32 (K,), in the order of active_coords().")
        .def("active_voxels", [](const PyGrid& g) { return activeVoxels(g, true, true); },
             "(active_coords(), active_values()) in one pass over the tree.")
        .def("values_at", &valuesAt, py::arg("ijk"),
             "The stored values at integer index coordinates ijk ((N, 3) or (3,)): float32 (N,), or a float for "
             "one coordinate. Inactive voxels give their +-background.")
        .def("sample", &sampleGrid, py::arg("points"), py::arg("order") = 1,
             "Values at world positions points ((N, 3), or (3,) for one point, any real dtype): float32 (N,), or a "
             "float for one point. order: 0 nearest voxel, 1 trilinear (default, OpenVDB's BoxSampler), 2 "
             "triquadratic. At voxel centres every order returns the stored values (index coordinates within 1e-9 "
             "voxel of an integer are snapped to it, so that rounding in the world-to-index map does not mix in "
             "a neighbour). Points beyond the index range +-2^30 give the background. Non-finite points raise "
             "ValueError.")
        .def("to_dense", &toDense, py::arg("bbox") = py::none(), py::arg("max_voxels") = uint64_t(1) << 31,
             "A dense float32 array of the voxels of bbox, indexed [i, j, k] (x, y, z; C order), with "
             "inactive voxels at their +-background. bbox: ((imin, jmin, kmin), (imax, jmax, kmax)), index space, "
             "inclusive; None (default): active_bbox. More than max_voxels voxels (0: no limit) raise "
             "ResourceLimitError. The world position of a[i, j, k] is transform.index_to_world(bbox[0] + (i, j, k)).")
        .def("copy", [](const PyGrid& g) { return PyGrid{g.grid->deepCopy()}; },
             "An independent deep copy of the grid (tree, transform and metadata).")
        .def("write", [](const PyGrid& g, py::handle path) { writeFloatGrids(toPath(path), {g.grid}); }, py::arg("path"),
             "Writes the grid to a .vdb file atomically (the library's writer: Blosc compression, a temporary "
             "file renamed over path; on failure nothing is left behind). Raises IoError.")
        .def_static("read", [](py::handle path, py::object name) {
            const std::string n = name.is_none() ? std::string() : name.cast<std::string>();
            return PyGrid{readFloatGridReleased(toPath(path), n)};
        }, py::arg("path"), py::arg("name") = py::none(),
           "Reads the float grid named name (default: the first float grid) of a .vdb file. Raises IoError.")
        .def("_meta_keys", [](const PyGrid& g) {
            py::list keys;
            for (auto it = g.grid->beginMeta(); it != g.grid->endMeta(); ++it) keys.append(it->first);
            return keys;
        })
        .def("_meta_get", [](const PyGrid& g, const std::string& key) -> py::object {
            openvdb::Metadata::ConstPtr v = (*g.grid)[key];
            if (!v) throw py::key_error(key);
            return metadataToPython(*v);
        })
        .def("_meta_set", [](PyGrid& g, const std::string& key, py::handle value) {
            openvdb::Metadata::Ptr old = (*g.grid)[key];
            openvdb::Metadata::Ptr v = metadataFromPython(value, old.get());
            g.grid->removeMeta(key);
            g.grid->insertMeta(key, *v);
        })
        .def("_meta_del", [](PyGrid& g, const std::string& key) {
            if (!(*g.grid)[key]) throw py::key_error(key);
            g.grid->removeMeta(key);
        })
        .def("_bridge_to_pyopenvdb", [](const PyGrid& g) {
            PyObject* o = gridToPyOpenVdb(g.grid);
            if (!o) throw py::error_already_set();
            return py::reinterpret_steal<py::object>(o);
        })
        .def_static("_bridge_from_pyopenvdb", [](py::handle obj) -> py::object {
            openvdb::FloatGrid::Ptr g = gridFromPyOpenVdb(obj.ptr());
            if (!g) return py::none();
            return py::cast(PyGrid{g});
        })
        .def("_shares_tree_with", [](const PyGrid& a, const PyGrid& b) { return &a.grid->tree() == &b.grid->tree(); })
        .def("__repr__", &gridRepr);

    m.def("read_grids", [](py::handle path) { return readAllFloatGrids(toPath(path)); }, py::arg("path"),
          "Every float grid of a .vdb file, as a list of Grid, in the order OpenVDB lists them (by name; grids "
          "of other value types are skipped). "
          "Raises IoError.");
    m.def("write_grids", [](py::handle path, py::iterable grids) {
        std::vector<openvdb::FloatGrid::ConstPtr> v;
        for (py::handle g : grids) v.push_back(toGrid(g, "grids[]").grid);
        if (v.empty()) throw py::value_error("write_grids: no grids given");
        writeFloatGrids(toPath(path), v);
    }, py::arg("path"), py::arg("grids"),
       "Writes several grids to one .vdb file atomically (see Grid.write).");
}

} // namespace levelforge::python_internal
