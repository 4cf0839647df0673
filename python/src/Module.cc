// SPDX-License-Identifier: Apache-2.0
// levelforge._levelforge: the compiled part of the `levelforge` Python package (python/levelforge/
// __init__.py re-exports it). See docs/python.md.
#include "Common.h"

#include <levelforge/io/VdbIO.h>

#include <openvdb/version.h>

PYBIND11_MODULE(_levelforge, m)
{
    namespace lf = levelforge::python_internal;
    m.doc() = "levelforge: meshes and volumes to signed distance fields in OpenVDB grids "
              "(the compiled module; import levelforge).";
    openvdb::initialize();
    lf::registerExceptions(m);
    lf::bindGrid(m);
    lf::bindConvert(m);
    lf::bindReshape(m);
    m.attr("__version__") = LEVELFORGE_PYTHON_VERSION;
    m.attr("generator") = levelforge::generatorString();
    m.attr("openvdb_version") = pybind11::make_tuple(openvdb::OPENVDB_LIBRARY_MAJOR_VERSION, openvdb::OPENVDB_LIBRARY_MINOR_VERSION,
                                                     openvdb::OPENVDB_LIBRARY_PATCH_VERSION);
    m.attr("_have_openvdb_bridge") = lf::haveOpenVdbBridge();
}
