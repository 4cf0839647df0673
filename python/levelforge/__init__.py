# SPDX-License-Identifier: Apache-2.0
"""levelforge: triangle meshes and scalar volumes to signed distance fields in OpenVDB grids.

The Python face of the levelforge C++ library and of its command-line tool: every operator of
``levelforge`` on the command line is a function here, with the operator's parameters as keyword
arguments and the same defaults.

    >>> import numpy as np, levelforge
    >>> vertices, faces = levelforge.read_mesh("builtin:torus-knot")
    >>> grid = levelforge.mesh_to_sdf(vertices, faces, voxel_count=128)
    >>> grid.sample([[1.0, 0.0, 0.0]])          # signed distance, world units, negative inside
    >>> coords, values = grid.active_voxels()   # int32 (K, 3), float32 (K,)
    >>> grid.write("knot.vdb")

Functions: read_mesh, write_mesh, validate_mesh, mesh_to_sdf, expand, reshape, volume_to_sdf,
read_volume, mesh_to_adf, csg, exact_signed_distance, read_grids, write_grids. Classes: Grid, Transform, Adf.
Errors: Error and its subclasses InvalidArgumentError and InvalidMeshError (ValueError),
InvalidVolumeError (ValueError), IoError (OSError), ResourceLimitError (MemoryError),
InterruptedError. Ctrl-C during a computation raises KeyboardInterrupt.

See docs/python.md for a guide with examples.
"""

from collections.abc import MutableMapping as _MutableMapping
import importlib as _importlib
import os as _os
import sys as _sys
import tempfile as _tempfile

from . import _levelforge
from ._levelforge import (
    Adf,
    Error,
    Grid,
    InterruptedError,  # levelforge.InterruptedError; not in __all__ (it would shadow the builtin)
    InvalidArgumentError,
    InvalidMeshError,
    InvalidVolumeError,
    IoError,
    ResourceLimitError,
    Transform,
    csg,
    exact_signed_distance,
    expand,
    mesh_to_adf,
    mesh_to_sdf,
    read_grids,
    read_mesh,
    read_volume,
    reshape,
    validate_mesh,
    volume_to_sdf,
    write_grids,
    write_mesh,
)

__version__ = _levelforge.__version__
#: "levelforge <version>", the levelforge:generator metadata of the grids this module makes.
generator = _levelforge.generator
#: The OpenVDB library version this module was built against, (major, minor, patch).
openvdb_version = tuple(_levelforge.openvdb_version)
#: Whether the library has sign modes (mesh_to_sdf's sign, fill_interior, winding_accuracy).
HAVE_SIGN_MODES = bool(_levelforge.HAVE_SIGN_MODES)

__all__ = [
    "Adf",
    "Error",
    "Grid",
    "GridMetadata",
    "InvalidArgumentError",
    "InvalidMeshError",
    "InvalidVolumeError",
    "IoError",
    "ResourceLimitError",
    "Transform",
    "csg",
    "exact_signed_distance",
    "expand",
    "mesh_to_adf",
    "mesh_to_sdf",
    "read_grids",
    "read_mesh",
    "read_volume",
    "reshape",
    "validate_mesh",
    "volume_to_sdf",
    "write_grids",
    "write_mesh",
]


# ---------------------------------------------------------------- metadata


class GridMetadata(_MutableMapping):
    """The metadata of a Grid as a mutable mapping that writes through to the grid.

    Keys are str; values are str, bool, int, float or tuples of three numbers (OpenVDB's string,
    bool, int32/int64, float/double and vec3 metadata; other types read as their string form).
    Assigning a number to an existing float or int32 entry keeps that type. The grid's name and
    class live here too, as "name" and "class", as in OpenVDB.
    """

    __slots__ = ("_grid",)

    def __init__(self, grid):
        self._grid = grid

    def __getitem__(self, key):
        return self._grid._meta_get(key)

    def __setitem__(self, key, value):
        self._grid._meta_set(key, value)

    def __delitem__(self, key):
        self._grid._meta_del(key)

    def __iter__(self):
        return iter(self._grid._meta_keys())

    def __len__(self):
        return len(self._grid._meta_keys())

    def __repr__(self):
        return "GridMetadata(%r)" % (dict(self),)


def _get_metadata(self):
    return GridMetadata(self)


def _set_metadata(self, values):
    values = dict(values)
    view = GridMetadata(self)
    for key in list(view):
        if key not in ("name", "class") or key in values:
            del view[key]
    view.update(values)


Grid.metadata = property(
    _get_metadata,
    _set_metadata,
    doc="The grid's metadata, a GridMetadata mapping that writes through to the grid "
    "(levelforge:source, levelforge:method, the band widths, ...). Assigning a dict replaces "
    "every entry but the grid's name and class (unless the dict holds them).",
)


# ---------------------------------------------------------------- OpenVDB's Python module


def _openvdb_module(module=None):
    """The OpenVDB Python module to use: `module` (a module or its name), else pyopenvdb
    (OpenVDB <= 11, Debian 12's python3-openvdb), else openvdb (OpenVDB >= 12)."""
    if module is not None:
        return _importlib.import_module(module) if isinstance(module, str) else module
    errors = []
    for name in ("pyopenvdb", "openvdb"):
        try:
            return _importlib.import_module(name)
        except ImportError as e:
            errors.append("%s: %s" % (name, e))
    raise ImportError(
        "no OpenVDB Python module could be imported (install python3-openvdb on Debian, or the "
        "openvdb package); " + "; ".join(errors)
    )


def _bridge_usable(mod):
    """Whether pointers can be handed to and from `mod` directly: the boost.python pyopenvdb of
    the very OpenVDB version this module links (Debian 12: both use libopenvdb 10.0)."""
    if not _levelforge._have_openvdb_bridge or mod is None:
        return False
    if getattr(mod, "__name__", "") != "pyopenvdb":
        return False
    try:
        return tuple(mod.LIBRARY_VERSION) == openvdb_version
    except (AttributeError, TypeError):
        return False


def _to_openvdb(self, copy=False, module=None):
    """The grid as a FloatGrid of OpenVDB's own Python module (pyopenvdb on Debian 12, openvdb
    from OpenVDB 12; `module` picks one).

    With Debian's pyopenvdb (built against the same libopenvdb) the pyopenvdb grid shares this
    grid's tree: no copy is made unless copy=True, and changes made through either object are
    seen by both. With any other OpenVDB module the grid goes through a temporary .vdb file (a
    copy, metadata included).
    """
    mod = _openvdb_module(module)
    if _bridge_usable(mod):
        source = self.copy() if copy else self
        try:
            return source._bridge_to_pyopenvdb()
        except TypeError:
            pass  # no converter registered in this process: take the file road
    with _tempfile.TemporaryDirectory(prefix="levelforge-") as tmp:
        path = _os.path.join(tmp, "grid.vdb")
        self.write(path)
        grids = mod.readAll(path)[0]
        return grids[0]


def _from_openvdb(grid, copy=False):
    """A Grid from a FloatGrid of OpenVDB's Python module (pyopenvdb or openvdb).

    With Debian's pyopenvdb the Grid shares the pyopenvdb grid's tree (no copy unless
    copy=True); with another module the grid goes through a temporary .vdb file. Raises
    TypeError for other grid types (levelforge grids hold floats).
    """
    if isinstance(grid, Grid):
        return grid.copy() if copy else grid
    kind = type(grid)
    if kind.__name__ != "FloatGrid":
        raise TypeError(
            "from_openvdb needs an OpenVDB FloatGrid, got %s.%s" % (kind.__module__, kind.__name__)
        )
    mod = _sys.modules.get(kind.__module__.split(".")[0])
    if _bridge_usable(mod):
        shared = Grid._bridge_from_pyopenvdb(grid)
        if shared is not None:
            return shared.copy() if copy else shared
    if mod is None or not hasattr(mod, "write"):
        raise TypeError("from_openvdb: %r is not a grid of an OpenVDB Python module" % (grid,))
    with _tempfile.TemporaryDirectory(prefix="levelforge-") as tmp:
        path = _os.path.join(tmp, "grid.vdb")
        mod.write(path, [grid])
        return read_grids(path)[0]


Grid.to_openvdb = _to_openvdb
Grid.from_openvdb = staticmethod(_from_openvdb)

del _get_metadata, _set_metadata, _to_openvdb, _from_openvdb
