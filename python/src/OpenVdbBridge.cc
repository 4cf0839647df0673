// SPDX-License-Identifier: Apache-2.0
// Grid.to_openvdb() / Grid.from_openvdb() without a copy: pyopenvdb (OpenVDB <= 10, Debian 12's
// python3-openvdb) is a boost.python module whose FloatGrid holds an openvdb::FloatGrid::Ptr. When
// it is loaded in the same process, links the same libopenvdb and the same libboost_python (the
// Python side checks the OpenVDB version before calling these), boost.python's converter registry
// hands the shared pointer across in both directions: both modules then share one tree.
// Built only when libboost_python is found (LEVELFORGE_WITH_BOOST_PYTHON); otherwise the Python
// side falls back to a .vdb file round trip (levelforge/__init__.py).
#include "Common.h"

#ifdef LEVELFORGE_WITH_BOOST_PYTHON
#include <boost/python.hpp>
#endif

namespace levelforge::python_internal {

#ifdef LEVELFORGE_WITH_BOOST_PYTHON

namespace bp = boost::python;

bool haveOpenVdbBridge() { return true; }

PyObject* gridToPyOpenVdb(const openvdb::FloatGrid::Ptr& grid)
{
    try {
        bp::object o(grid); // boost.python's to-python converter of std::shared_ptr<FloatGrid>
        return bp::incref(o.ptr());
    } catch (const bp::error_already_set&) {
        return nullptr; // the Python error (no converter registered) is set
    }
}

openvdb::FloatGrid::Ptr gridFromPyOpenVdb(PyObject* obj)
{
    try {
        bp::object o(bp::handle<>(bp::borrowed(obj)));
        bp::extract<openvdb::FloatGrid::Ptr> ex(o);
        if (!ex.check()) return nullptr;
        openvdb::FloatGrid::Ptr held = ex();
        // boost.python's pointer keeps the Python object alive and drops it without taking the
        // GIL; ours may be released on any thread, so the last release takes the GIL first.
        openvdb::FloatGrid* raw = held.get();
        return openvdb::FloatGrid::Ptr(raw, [keep = std::move(held)](openvdb::FloatGrid*) mutable {
            PyGILState_STATE s = PyGILState_Ensure();
            keep.reset();
            PyGILState_Release(s);
        });
    } catch (const bp::error_already_set&) {
        PyErr_Clear();
        return nullptr;
    }
}

#else

bool haveOpenVdbBridge() { return false; }

PyObject* gridToPyOpenVdb(const openvdb::FloatGrid::Ptr&)
{
    PyErr_SetString(PyExc_RuntimeError, "levelforge was built without the boost.python bridge to pyopenvdb");
    return nullptr;
}

openvdb::FloatGrid::Ptr gridFromPyOpenVdb(PyObject*) { return nullptr; }

#endif

} // namespace levelforge::python_internal
