// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Shared pieces of the Python module `levelforge._levelforge`: the Grid and Adf holders,
///        array conversion with the checks every entry point makes, the interrupter that turns
///        Ctrl-C and exceptions raised by a `progress` callback into Python exceptions, and the
///        helper that runs library work with the GIL released.
///
/// Rules every binding follows:
///  - arguments are converted and checked while the GIL is held; bad arrays raise ValueError
///    (TypeError for a wrong kind of object) before any work starts;
///  - library work runs with the GIL released, inside a TBB isolated region (so that a thread
///    waiting in it never picks up a task of another Python thread's TBB work), with a
///    PyInterrupter as the library's interrupter;
///  - no TBB parallel code ever runs while the GIL is held.
#pragma once

#include <levelforge/adf/AdaptiveDistanceField.h>
#include <levelforge/core/TriangleMesh.h>

#include <openvdb/openvdb.h>
#include <openvdb/util/NullInterrupter.h>

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <tbb/task_arena.h>

#include <atomic>
#include <chrono>
#include <cstdint>
#include <exception>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <utility>
#include <vector>

namespace levelforge::python_internal {

namespace py = pybind11;

/// The Python `levelforge.Grid`: a float grid, shared (never copied) with whoever else holds it.
struct PyGrid
{
    openvdb::FloatGrid::Ptr grid;
};

/// The Python `levelforge.Adf`.
struct PyAdf
{
    AdaptiveDistanceField adf;
};

// ---------------------------------------------------------------- arrays

/// @brief An (N, 3) float64 C-contiguous view of @p obj (any array-like; converted only when its
///        dtype or layout differs).
/// @param[in] obj        the array-like
/// @param[in] what       the argument's name, for messages ("vertices", "points")
/// @param[in] allowEmpty whether N = 0 is accepted
/// @throws py::value_error for a wrong shape, a non-numeric dtype, or (allowEmpty false) no rows
py::array_t<double, py::array::c_style> asPointArray(py::handle obj, const char* what, bool allowEmpty);

/// @brief The same for points to query: also accepts one point of shape (3,) and says so in
///        @p single (the caller then returns a scalar or a single row). Non-finite coordinates
///        raise ValueError naming the first.
py::array_t<double, py::array::c_style> asQueryPoints(py::handle obj, const char* what, bool& single);

/// @brief vertices (N, 3) and faces (M, 3) as a TriangleMesh.
///
/// Shapes and dtypes are checked here (faces must hold integers >= 0 and < 2^32); whether the
/// indices are in range and the coordinates finite is left to the library's
/// requireUsableMesh(), which every converter calls, so the messages are the library's.
/// @param[in] source  mesh.source (the library's messages start with it)
TriangleMesh toMesh(py::handle vertices, py::handle faces, const std::string& source);

/// @brief A path argument: str, bytes or os.PathLike, as a std::string.
std::string toPath(py::handle obj);

/// @brief A triple of floats from a number (all three equal) or a sequence of three numbers.
openvdb::Vec3d toTriple(py::handle obj, const char* what);

/// @brief The Grid held by @p obj.
/// @throws py::type_error when @p obj is not a levelforge.Grid
PyGrid& toGrid(py::handle obj, const char* what);

// ---------------------------------------------------------------- interruption

/// @brief The library's interrupter for one call from Python.
///
/// wasInterrupted() is called from any TBB thread. On the thread that made the call (the one
/// that released the GIL), at most every 20 ms and whenever the percentage of the current stage
/// has grown and a callback is set, it re-acquires the GIL, runs PyErr_CheckSignals() (Ctrl-C:
/// Python's SIGINT handler raises KeyboardInterrupt) and calls progress(stage, percent). Any
/// Python exception raised there is kept, the interrupter reports "interrupted" to every
/// thread from then on, and the caller re-raises the kept exception once the library has
/// stopped (run()). Other threads only read an atomic flag.
class PyInterrupter : public openvdb::util::NullInterrupter
{
public:
    /// @param[in] progress  None or a callable progress(stage: str, percent: int)
    explicit PyInterrupter(py::object progress);
    ~PyInterrupter() override;
    PyInterrupter(const PyInterrupter&) = delete;
    PyInterrupter& operator=(const PyInterrupter&) = delete;

    void start(const char* name = nullptr) override;
    void end() override;
    bool wasInterrupted(int percent = -1) override;

    /// True when a Python exception was kept (GIL not needed).
    bool hasPythonError() const { return mStop.load(std::memory_order_acquire); }
    /// Sets the kept exception as the current Python error (GIL held) and throws
    /// py::error_already_set.
    [[noreturn]] void raisePythonError();
    /// With the GIL held: the first check of a call (a Ctrl-C pressed before it), so that a
    /// pending KeyboardInterrupt is raised before any work starts.
    void checkNow();

private:
    bool checkWithGil(int percent);

    py::object mProgress;
    std::thread::id mOwner;
    std::atomic<bool> mStop{false};
    std::atomic<int> mPercent{-1};
    std::mutex mStageMutex;
    std::string mStage = "levelforge";
    int mReported = -1;
    std::chrono::steady_clock::time_point mLastCheck;
    PyObject* mType = nullptr;
    PyObject* mValue = nullptr;
    PyObject* mTraceback = nullptr;
};

/// @brief Runs @p work with the GIL released, in an isolated TBB region, with @p interrupter
///        polled by the library; then, with the GIL held again, raises the Python exception the
///        interrupter kept (KeyboardInterrupt, the callback's own exception) if there is one, else
///        rethrows the library's exception (translated by the module's exception translator), else
///        returns the result.
template<typename F>
auto runReleased(PyInterrupter& interrupter, F&& work) -> decltype(work())
{
    using R = decltype(work());
    interrupter.checkNow();
    std::exception_ptr error;
    std::optional<std::conditional_t<std::is_void_v<R>, int, R>> result;
    {
        py::gil_scoped_release release;
        try {
            tbb::this_task_arena::isolate([&] {
                if constexpr (std::is_void_v<R>) {
                    work();
                    result.emplace(0);
                } else {
                    result.emplace(work());
                }
            });
        } catch (...) {
            error = std::current_exception();
        }
    }
    if (interrupter.hasPythonError()) {
        result.reset();
        interrupter.raisePythonError();
    }
    if (error) std::rethrow_exception(error);
    if constexpr (!std::is_void_v<R>) return std::move(*result);
}

/// @brief Runs @p work with the GIL released in an isolated TBB region (no interrupter: short,
///        non-interruptible work such as sampling or copying values out).
template<typename F>
auto runReleased(F&& work) -> decltype(work())
{
    py::gil_scoped_release release;
    return tbb::this_task_arena::isolate(std::forward<F>(work));
}

// ---------------------------------------------------------------- misc

/// @brief The levelforge exception types of the module, registered by registerExceptions().
struct ExceptionTypes
{
    PyObject* error = nullptr;
    PyObject* invalidArgument = nullptr;
    PyObject* invalidMesh = nullptr;
    PyObject* invalidVolume = nullptr;
    PyObject* io = nullptr;
    PyObject* resourceLimit = nullptr;
    PyObject* interrupted = nullptr;
};

/// Creates the exception classes in @p m and installs the translator of the library's types.
void registerExceptions(py::module_& m);

/// @brief The grid's metadata value @p value as a Python object (str, bool, int, float, tuple;
///        other types as their string form).
py::object metadataToPython(const openvdb::Metadata& value);

/// @brief Python value → OpenVDB metadata. bool → bool, int → int64 (int32 when the existing
///        entry is int32), float → double (float when the existing entry is float), str →
///        string, 3 ints → vec3i, 3 floats → vec3d.
/// @param[in] existing  the current entry of the same name, or null
/// @throws py::type_error for other values
openvdb::Metadata::Ptr metadataFromPython(py::handle value, const openvdb::Metadata* existing);

/// @brief Writes float grids to a .vdb file atomically with the library's writer (Grid.cc): a
///        shallow copy of each (own metadata, shared tree) is taken with the GIL held, the file is
///        written with it released, with the CLI's "creator" file metadata.
void writeFloatGrids(const std::string& path, const std::vector<openvdb::FloatGrid::ConstPtr>& grids);
/// @brief The float grid named @p name (empty: the first float grid) of a .vdb file, read with
///        the GIL released (Grid.cc). Throws IoError as the CLI's `sample` / `csg` do.
openvdb::FloatGrid::Ptr readFloatGridReleased(const std::string& path, const std::string& name);
/// repr() of a Grid.
std::string gridRepr(const PyGrid& g);

/// Binds Grid and Transform (Grid.cc).
void bindGrid(py::module_& m);
/// Binds the conversions, I/O and Adf (Convert.cc).
void bindConvert(py::module_& m);
/// levelforge.reshape (python/src/Reshape.cc).
void bindReshape(py::module_& m);

/// @brief The boost.python bridge to pyopenvdb (OpenVdbBridge.cc, when built): the Python object
///        of @p grid as a pyopenvdb.FloatGrid sharing its tree; null with a Python error set when
///        boost.python has no converter (pyopenvdb not imported, or another OpenVDB).
PyObject* gridToPyOpenVdb(const openvdb::FloatGrid::Ptr& grid);
/// The FloatGrid a pyopenvdb.FloatGrid holds (shared); null when @p obj is not one.
openvdb::FloatGrid::Ptr gridFromPyOpenVdb(PyObject* obj);
/// Whether the bridge was compiled in.
bool haveOpenVdbBridge();

} // namespace levelforge::python_internal
