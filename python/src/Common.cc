// SPDX-License-Identifier: Apache-2.0
// Array conversion, the interrupter and the exception types of the Python module (Common.h).
#include "Common.h"

#include <levelforge/core/Exceptions.h>
#include <levelforge/io/VolumeIO.h> // InvalidVolumeError

#include <cmath>
#include <cstring>
#include <limits>
#include <sstream>

namespace levelforge::python_internal {

namespace {

ExceptionTypes gTypes;

std::string shapeText(const py::array& a)
{
    std::ostringstream os;
    os << "(";
    for (py::ssize_t d = 0; d < a.ndim(); ++d) os << (d ? ", " : "") << a.shape(d);
    if (a.ndim() == 1) os << ",";
    os << ")";
    return os.str();
}

std::string dtypeText(const py::array& a) { return py::str(a.dtype()).cast<std::string>(); }

/// numpy.asarray(obj); a ragged list raises numpy's ValueError.
py::array asArray(py::handle obj)
{
    // Leaked on purpose: a static py::object would be released after the interpreter is gone.
    static py::handle asarray = py::object(py::module_::import("numpy").attr("asarray")).release();
    return asarray(obj).cast<py::array>();
}

char dtypeKind(const py::array& a) { return a.dtype().kind(); }

} // namespace

// ---------------------------------------------------------------- arrays

py::array_t<double, py::array::c_style> asPointArray(py::handle obj, const char* what, bool allowEmpty)
{
    if (obj.is_none()) throw py::type_error(std::string(what) + " must be an (N, 3) array of numbers, got None");
    py::array a = asArray(obj);
    if (a.ndim() != 2 || a.shape(1) != 3) {
        throw py::value_error(std::string(what) + " must be an (N, 3) array, got shape " + shapeText(a));
    }
    const char kind = dtypeKind(a);
    if (kind != 'f' && kind != 'i' && kind != 'u') {
        throw py::value_error(std::string(what) + " must hold real numbers, got dtype " + dtypeText(a));
    }
    if (!allowEmpty && a.shape(0) == 0) throw py::value_error(std::string(what) + " is empty (shape (0, 3))");
    return py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(a);
}

py::array_t<double, py::array::c_style> asQueryPoints(py::handle obj, const char* what, bool& single)
{
    if (obj.is_none()) throw py::type_error(std::string(what) + " must be an (N, 3) array of numbers, got None");
    py::array a = asArray(obj);
    single = a.ndim() == 1 && a.shape(0) == 3;
    if (single) a = a.attr("reshape")(1, 3).cast<py::array>();
    auto p = asPointArray(a, what, true);
    const double* d = p.data();
    const size_t n = size_t(p.shape(0));
    for (size_t i = 0; i < n; ++i) {
        if (!std::isfinite(d[3 * i]) || !std::isfinite(d[3 * i + 1]) || !std::isfinite(d[3 * i + 2])) {
            std::ostringstream os;
            os.precision(17);
            os << what << "[" << i << "] = (" << d[3 * i] << ", " << d[3 * i + 1] << ", " << d[3 * i + 2]
               << ") is not finite";
            throw py::value_error(os.str());
        }
    }
    return p;
}

TriangleMesh toMesh(py::handle vertices, py::handle faces, const std::string& source)
{
    auto v = asPointArray(vertices, "vertices", true);
    if (faces.is_none()) throw py::type_error("faces must be an (M, 3) array of vertex indices, got None");
    py::array f = asArray(faces);
    if (f.ndim() != 2 || f.shape(1) != 3) {
        throw py::value_error("faces must be an (M, 3) array of vertex indices, got shape " + shapeText(f));
    }
    if (f.shape(0) > 0 && dtypeKind(f) != 'i' && dtypeKind(f) != 'u') {
        throw py::value_error("faces must hold integer vertex indices, got dtype " + dtypeText(f));
    }
    TriangleMesh mesh;
    mesh.source = source;
    const size_t nv = size_t(v.shape(0)), nf = size_t(f.shape(0));
    mesh.points.resize(nv);
    static_assert(sizeof(Vec3d) == 3 * sizeof(double), "Vec3d must be three packed doubles");
    if (nv) std::memcpy(static_cast<void*>(mesh.points.data()), v.data(), nv * sizeof(Vec3d));
    if (nf == 0) return mesh;
    mesh.triangles.resize(nf);
    const bool unsignedKind = dtypeKind(f) == 'u';
    if (unsignedKind) {
        auto fu = py::array_t<uint64_t, py::array::c_style | py::array::forcecast>::ensure(f);
        const uint64_t* d = fu.data();
        for (size_t t = 0; t < nf; ++t)
            for (int k = 0; k < 3; ++k) {
                const uint64_t x = d[3 * t + size_t(k)];
                if (x > std::numeric_limits<uint32_t>::max()) {
                    throw py::value_error("faces[" + std::to_string(t) + ", " + std::to_string(k) + "] = " +
                                          std::to_string(x) + " is too large (vertex indices must be < 2^32)");
                }
                mesh.triangles[t][k] = uint32_t(x);
            }
    } else {
        auto fi = py::array_t<int64_t, py::array::c_style | py::array::forcecast>::ensure(f);
        const int64_t* d = fi.data();
        for (size_t t = 0; t < nf; ++t)
            for (int k = 0; k < 3; ++k) {
                const int64_t x = d[3 * t + size_t(k)];
                if (x < 0) {
                    throw py::value_error("faces[" + std::to_string(t) + ", " + std::to_string(k) + "] = " +
                                          std::to_string(x) + ": vertex indices must be >= 0");
                }
                if (x > int64_t(std::numeric_limits<uint32_t>::max())) {
                    throw py::value_error("faces[" + std::to_string(t) + ", " + std::to_string(k) + "] = " +
                                          std::to_string(x) + " is too large (vertex indices must be < 2^32)");
                }
                mesh.triangles[t][k] = uint32_t(x);
            }
    }
    return mesh;
}

std::string toPath(py::handle obj)
{
    static py::handle fspath = py::object(py::module_::import("os").attr("fspath")).release();
    static py::handle fsdecode = py::object(py::module_::import("os").attr("fsdecode")).release();
    try {
        return fsdecode(fspath(obj)).cast<std::string>();
    } catch (py::error_already_set& e) {
        if (e.matches(PyExc_TypeError)) {
            throw py::type_error("expected a path (str, bytes or os.PathLike), got " +
                                 std::string(py::str(py::type::handle_of(obj).attr("__name__"))));
        }
        throw;
    }
}

openvdb::Vec3d toTriple(py::handle obj, const char* what)
{
    py::array a = asArray(obj);
    const char kind = dtypeKind(a);
    if (kind != 'f' && kind != 'i' && kind != 'u') {
        throw py::value_error(std::string(what) + " must be a number or three numbers, got dtype " + dtypeText(a));
    }
    auto d = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(a);
    if (d.ndim() == 0) {
        const double x = *d.data();
        return openvdb::Vec3d(x, x, x);
    }
    if (d.ndim() != 1 || d.shape(0) != 3) {
        throw py::value_error(std::string(what) + " must be a number or three numbers, got shape " + shapeText(a));
    }
    return openvdb::Vec3d(d.data()[0], d.data()[1], d.data()[2]);
}

PyGrid& toGrid(py::handle obj, const char* what)
{
    if (!py::isinstance<PyGrid>(obj)) {
        throw py::type_error(std::string(what) + " must be a levelforge.Grid, got " +
                             std::string(py::str(py::type::handle_of(obj).attr("__name__"))));
    }
    PyGrid& g = obj.cast<PyGrid&>();
    if (!g.grid) throw py::value_error(std::string(what) + " is an empty Grid");
    return g;
}

// ---------------------------------------------------------------- interrupter

PyInterrupter::PyInterrupter(py::object progress)
    : mProgress(std::move(progress)), mOwner(std::this_thread::get_id()), mLastCheck(std::chrono::steady_clock::now())
{
    if (!mProgress.is_none() && !PyCallable_Check(mProgress.ptr())) {
        throw py::type_error("progress must be a callable progress(stage: str, percent: int) or None");
    }
}

PyInterrupter::~PyInterrupter()
{
    // Destroyed by the binding with the GIL held (it lives on the binding's stack).
    Py_XDECREF(mType);
    Py_XDECREF(mValue);
    Py_XDECREF(mTraceback);
}

void PyInterrupter::start(const char* name)
{
    std::lock_guard<std::mutex> lock(mStageMutex);
    mStage = (name && *name) ? name : "levelforge";
    mPercent.store(-1, std::memory_order_relaxed);
    if (std::this_thread::get_id() == mOwner) mReported = -1;
}

void PyInterrupter::end()
{
    if (std::this_thread::get_id() == mOwner && !mProgress.is_none() && !mStop.load(std::memory_order_relaxed)) {
        // Report 100 % of the stage once, if it was not reported yet.
        int expected = mPercent.load(std::memory_order_relaxed);
        while (expected < 100 && !mPercent.compare_exchange_weak(expected, 100, std::memory_order_relaxed)) {
        }
        checkWithGil(100);
    }
}

bool PyInterrupter::wasInterrupted(int percent)
{
    if (percent >= 0) {
        percent = std::min(percent, 100);
        int seen = mPercent.load(std::memory_order_relaxed);
        while (percent > seen && !mPercent.compare_exchange_weak(seen, percent, std::memory_order_relaxed)) {
        }
    }
    if (mStop.load(std::memory_order_acquire)) return true;
    if (std::this_thread::get_id() != mOwner) return false;
    return checkWithGil(mPercent.load(std::memory_order_relaxed));
}

bool PyInterrupter::checkWithGil(int percent)
{
    // On the calling thread only (mReported, mLastCheck are not shared).
    const auto now = std::chrono::steady_clock::now();
    const bool report = !mProgress.is_none() && percent > mReported;
    if (!report && now - mLastCheck < std::chrono::milliseconds(20)) return false;
    mLastCheck = now;
    py::gil_scoped_acquire gil;
    bool failed = PyErr_CheckSignals() != 0;
    if (!failed && report) {
        mReported = percent;
        std::string stage;
        {
            std::lock_guard<std::mutex> lock(mStageMutex);
            stage = mStage;
        }
        PyObject* r = PyObject_CallFunction(mProgress.ptr(), "si", stage.c_str(), percent);
        if (r) Py_DECREF(r);
        else failed = true;
    }
    if (failed) {
        PyErr_Fetch(&mType, &mValue, &mTraceback);
        mStop.store(true, std::memory_order_release);
    }
    return failed;
}

void PyInterrupter::checkNow()
{
    if (PyErr_CheckSignals() != 0) throw py::error_already_set();
}

void PyInterrupter::raisePythonError()
{
    PyErr_Restore(mType, mValue, mTraceback); // steals the references
    mType = mValue = mTraceback = nullptr;
    throw py::error_already_set();
}

// ---------------------------------------------------------------- exceptions

namespace {

PyObject* newException(py::module_& m, const char* name, PyObject* bases, const char* doc)
{
    const std::string qualified = std::string("levelforge.") + name;
    PyObject* type = PyErr_NewExceptionWithDoc(qualified.c_str(), doc, bases, nullptr);
    if (!type) throw py::error_already_set();
    m.add_object(name, py::handle(type)); // the module keeps a reference for as long as it lives
    return type;
}

} // namespace

void registerExceptions(py::module_& m)
{
    gTypes.error = newException(m, "Error", PyExc_Exception,
                                "Base of every error levelforge raises (levelforge::Error).");
    auto bases = [](PyObject* a, PyObject* b) { return py::make_tuple(py::handle(a), py::handle(b)); };
    py::tuple t;
    t = bases(gTypes.error, PyExc_ValueError);
    gTypes.invalidArgument = newException(m, "InvalidArgumentError", t.ptr(),
                                          "A parameter is out of its valid range (levelforge::InvalidArgumentError); "
                                          "a ValueError.");
    t = bases(gTypes.error, PyExc_ValueError);
    gTypes.invalidMesh = newException(m, "InvalidMeshError", t.ptr(),
                                      "A mesh is unusable: no triangles, NaN/Inf coordinates, bad index, "
                                      "unreadable content (levelforge::InvalidMeshError); a ValueError.");
    t = bases(gTypes.error, PyExc_ValueError);
    gTypes.invalidVolume = newException(m, "InvalidVolumeError", t.ptr(),
                                        "A volume file's content is unusable (levelforge::InvalidVolumeError); "
                                        "a ValueError.");
    t = bases(gTypes.error, PyExc_OSError);
    gTypes.io = newException(m, "IoError", t.ptr(),
                             "Reading or writing a file failed (levelforge::IoError); an OSError.");
    t = bases(gTypes.error, PyExc_MemoryError);
    gTypes.resourceLimit = newException(m, "ResourceLimitError", t.ptr(),
                                        "The work would exceed the voxel budget (max_voxels) or memory "
                                        "(levelforge::ResourceLimitError); a MemoryError.");
    gTypes.interrupted = newException(m, "InterruptedError", gTypes.error,
                                      "The library's interrupter stopped the work (levelforge::InterruptedError). "
                                      "Ctrl-C and exceptions raised by a progress callback are re-raised as "
                                      "themselves (KeyboardInterrupt, ...) instead.");

    py::register_exception_translator([](std::exception_ptr p) {
        try {
            if (p) std::rethrow_exception(p);
        } catch (const InvalidMeshError& e) {
            PyErr_SetString(gTypes.invalidMesh, e.what());
        } catch (const InvalidVolumeError& e) {
            PyErr_SetString(gTypes.invalidVolume, e.what());
        } catch (const InvalidArgumentError& e) {
            PyErr_SetString(gTypes.invalidArgument, e.what());
        } catch (const IoError& e) {
            PyErr_SetString(gTypes.io, e.what());
        } catch (const ResourceLimitError& e) {
            PyErr_SetString(gTypes.resourceLimit, e.what());
        } catch (const InterruptedError& e) {
            PyErr_SetString(gTypes.interrupted, e.what());
        } catch (const Error& e) {
            PyErr_SetString(gTypes.error, e.what());
        } catch (const openvdb::Exception& e) {
            // OpenVDB's own errors (IoError of a corrupt file read elsewhere, ValueError, ...)
            PyErr_SetString(gTypes.error, e.what());
        }
    });
}

// ---------------------------------------------------------------- metadata

py::object metadataToPython(const openvdb::Metadata& m)
{
    const std::string type = m.typeName();
    if (type == openvdb::StringMetadata::staticTypeName())
        return py::str(static_cast<const openvdb::StringMetadata&>(m).value());
    if (type == openvdb::BoolMetadata::staticTypeName())
        return py::bool_(static_cast<const openvdb::BoolMetadata&>(m).value());
    if (type == openvdb::FloatMetadata::staticTypeName())
        return py::float_(static_cast<const openvdb::FloatMetadata&>(m).value());
    if (type == openvdb::DoubleMetadata::staticTypeName())
        return py::float_(static_cast<const openvdb::DoubleMetadata&>(m).value());
    if (type == openvdb::Int32Metadata::staticTypeName())
        return py::int_(static_cast<const openvdb::Int32Metadata&>(m).value());
    if (type == openvdb::Int64Metadata::staticTypeName())
        return py::int_(static_cast<const openvdb::Int64Metadata&>(m).value());
    if (type == openvdb::Vec3IMetadata::staticTypeName()) {
        const auto v = static_cast<const openvdb::Vec3IMetadata&>(m).value();
        return py::make_tuple(v[0], v[1], v[2]);
    }
    if (type == openvdb::Vec3SMetadata::staticTypeName()) {
        const auto v = static_cast<const openvdb::Vec3SMetadata&>(m).value();
        return py::make_tuple(v[0], v[1], v[2]);
    }
    if (type == openvdb::Vec3DMetadata::staticTypeName()) {
        const auto v = static_cast<const openvdb::Vec3DMetadata&>(m).value();
        return py::make_tuple(v[0], v[1], v[2]);
    }
    return py::str(m.str());
}

openvdb::Metadata::Ptr metadataFromPython(py::handle value, const openvdb::Metadata* existing)
{
    const std::string old = existing ? existing->typeName() : std::string();
    if (py::isinstance<py::bool_>(value)) return openvdb::BoolMetadata(value.cast<bool>()).copy();
    if (py::isinstance<py::int_>(value)) {
        if (old == openvdb::Int32Metadata::staticTypeName()) {
            const long long x = value.cast<long long>();
            if (x >= std::numeric_limits<int32_t>::min() && x <= std::numeric_limits<int32_t>::max())
                return openvdb::Int32Metadata(int32_t(x)).copy();
        }
        if (old == openvdb::FloatMetadata::staticTypeName()) return openvdb::FloatMetadata(value.cast<float>()).copy();
        if (old == openvdb::DoubleMetadata::staticTypeName()) return openvdb::DoubleMetadata(value.cast<double>()).copy();
        return openvdb::Int64Metadata(value.cast<int64_t>()).copy();
    }
    if (py::isinstance<py::float_>(value)) {
        if (old == openvdb::FloatMetadata::staticTypeName()) return openvdb::FloatMetadata(value.cast<float>()).copy();
        return openvdb::DoubleMetadata(value.cast<double>()).copy();
    }
    if (py::isinstance<py::str>(value)) return openvdb::StringMetadata(value.cast<std::string>()).copy();
    if (py::isinstance<py::tuple>(value) || py::isinstance<py::list>(value)) {
        py::sequence s = value.cast<py::sequence>();
        if (s.size() == 3) {
            bool allInt = true, allNumber = true;
            for (py::handle x : s) {
                const bool isInt = py::isinstance<py::int_>(x) && !py::isinstance<py::bool_>(x);
                allInt &= isInt;
                allNumber &= isInt || py::isinstance<py::float_>(x);
            }
            if (allInt) return openvdb::Vec3IMetadata(openvdb::Vec3i(s[0].cast<int>(), s[1].cast<int>(), s[2].cast<int>())).copy();
            if (allNumber) {
                const openvdb::Vec3d v(s[0].cast<double>(), s[1].cast<double>(), s[2].cast<double>());
                if (old == openvdb::Vec3SMetadata::staticTypeName()) return openvdb::Vec3SMetadata(openvdb::Vec3s(v)).copy();
                return openvdb::Vec3DMetadata(v).copy();
            }
        }
    }
    throw py::type_error("metadata values must be str, bool, int, float or a tuple of three numbers, got " +
                         std::string(py::str(py::type::handle_of(value).attr("__name__"))));
}

} // namespace levelforge::python_internal
