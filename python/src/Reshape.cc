// SPDX-License-Identifier: Apache-2.0
// levelforge.reshape: `levelforge reshape` (levelforge::reshapeLevelSet) for Python.
#include "Common.h"

#include <levelforge/levelset/ReshapeLevelSet.h>

namespace levelforge::python_internal {
namespace {

py::object reshapePy(py::handle gridObj, const std::string& op, double offset, bool worldUnits, py::object progress)
{
    const PyGrid& in = toGrid(gridObj, "grid");
    ReshapeOptions opt;
    opt.operation = reshapeOperationFromString(op);
    opt.offset = offset;
    opt.worldUnits = worldUnits;
    PyInterrupter interrupter(std::move(progress));
    opt.interrupter = &interrupter;
    const openvdb::FloatGrid& input = *in.grid;
    openvdb::FloatGrid::Ptr out = runReleased(interrupter, [&] { return reshapeLevelSet(input, opt); });
    return py::cast(PyGrid{out});
}

} // namespace

void bindReshape(py::module_& m)
{
    m.def("reshape", &reshapePy, py::arg("grid"), py::kw_only(), py::arg("op") = "dilate", py::arg("offset") = 1.0,
          py::arg("world_units") = false, py::arg("progress") = py::none(), R"doc(
Dilates, erodes, opens or closes a level set by an offset: `levelforge reshape`
(levelforge::reshapeLevelSet; OpenVDB's LevelSetFilter::offset, the band width kept).
The input is not modified; a new Grid is returned.

op: "dilate" (grow), "erode" (shrink), "open" (erode then dilate: removes features thinner than
    twice the offset) or "close" (dilate then erode: fills gaps narrower than twice the offset).
offset: how far the surface moves, voxels (world units with world_units=True), > 0.
progress: as in mesh_to_sdf (Ctrl-C raises KeyboardInterrupt).
Raises InvalidArgumentError (not a level set, a band under 2 voxels, a bad offset or op).
)doc");
}

} // namespace levelforge::python_internal
