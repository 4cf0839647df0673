# SPDX-License-Identifier: Apache-2.0
# Type stubs of the levelforge package (python/levelforge/__init__.py + the compiled
# levelforge._levelforge). tests/python/test_api.py checks that every name, parameter and default
# here matches the module.
from collections.abc import Iterable, Iterator, Mapping, MutableMapping, Sequence
from os import PathLike
from typing import Any, Callable, Literal, Optional, Union, overload

import numpy as np
import numpy.typing as npt

__version__: str
generator: str
openvdb_version: tuple[int, int, int]
HAVE_SIGN_MODES: bool

_Path = Union[str, bytes, PathLike[str], PathLike[bytes]]
_Points = npt.ArrayLike  # (N, 3) real numbers, or one point (3,)
_Triple = Union[float, Sequence[float], npt.ArrayLike]
_Progress = Optional[Callable[[str, int], Any]]
_IndexBox = tuple[tuple[int, int, int], tuple[int, int, int]]
_MetaValue = Union[str, bool, int, float, tuple[int, int, int], tuple[float, float, float]]

# ---------------------------------------------------------------- errors

class Error(Exception):
    """Base of every error levelforge raises (levelforge::Error)."""

class InvalidArgumentError(Error, ValueError):
    """A parameter is out of its valid range."""

class InvalidMeshError(Error, ValueError):
    """A mesh is unusable: no triangles, NaN/Inf coordinates, bad index, unreadable content."""

class InvalidVolumeError(Error, ValueError):
    """A volume file's content is unusable."""

class IoError(Error, OSError):
    """Reading or writing a file failed."""

class ResourceLimitError(Error, MemoryError):
    """The work would exceed the voxel budget (max_voxels) or memory."""

class InterruptedError(Error):  # levelforge.InterruptedError (not exported by `import *`)
    """The library's interrupter stopped the work (Ctrl-C raises KeyboardInterrupt instead)."""

# ---------------------------------------------------------------- classes

class Transform:
    """The index <-> world map of a grid (OpenVDB's math::Transform)."""
    @property
    def voxel_size(self) -> tuple[float, float, float]: ...
    @property
    def is_linear(self) -> bool: ...
    @property
    def matrix(self) -> npt.NDArray[np.float64]:
        """4x4, row-vector convention: [x y z 1] = [i j k 1] @ matrix."""
    def index_to_world(self, ijk: _Points) -> npt.NDArray[np.float64]:
        """World positions, float64 (N, 3) (or (3,) for one point)."""
    def world_to_index(self, xyz: _Points) -> npt.NDArray[np.float64]:
        """Fractional index coordinates, float64 (N, 3) (or (3,) for one point)."""
    def __eq__(self, other: object) -> bool: ...

class GridMetadata(MutableMapping[str, _MetaValue]):
    """A Grid's metadata; writes through to the grid."""
    def __init__(self, grid: Grid) -> None: ...
    def __getitem__(self, key: str) -> _MetaValue: ...
    def __setitem__(self, key: str, value: _MetaValue) -> None: ...
    def __delitem__(self, key: str) -> None: ...
    def __iter__(self) -> Iterator[str]: ...
    def __len__(self) -> int: ...

class Grid:
    """A sparse float grid (openvdb::FloatGrid), usually a narrow-band signed distance level set."""
    name: str
    metadata: GridMetadata
    @property
    def voxel_size(self) -> float: ...
    @property
    def transform(self) -> Transform: ...
    @property
    def background(self) -> float: ...
    @property
    def grid_class(self) -> str: ...
    @property
    def is_level_set(self) -> bool: ...
    @property
    def active_voxel_count(self) -> int: ...
    @property
    def active_bbox(self) -> Optional[_IndexBox]: ...
    @property
    def memory_bytes(self) -> int: ...
    def active_coords(self) -> npt.NDArray[np.int32]:
        """Index coordinates of the active voxels, int32 (K, 3)."""
    def active_values(self) -> npt.NDArray[np.float32]:
        """Values of the active voxels, float32 (K,), in the order of active_coords()."""
    def active_voxels(self) -> tuple[npt.NDArray[np.int32], npt.NDArray[np.float32]]:
        """(active_coords(), active_values()) in one pass."""
    @overload
    def values_at(self, ijk: Sequence[int]) -> float: ...
    @overload
    def values_at(self, ijk: npt.ArrayLike) -> npt.NDArray[np.float32]: ...
    @overload
    def sample(self, points: Sequence[float], order: int = 1) -> float: ...
    @overload
    def sample(self, points: npt.ArrayLike, order: int = 1) -> npt.NDArray[np.float32]: ...
    def to_dense(self, bbox: Optional[_IndexBox] = None, max_voxels: int = 2147483648) -> npt.NDArray[np.float32]:
        """Dense float32 array indexed [i, j, k] over bbox (default: active_bbox)."""
    def copy(self) -> Grid: ...
    def write(self, path: _Path) -> None:
        """Writes a .vdb file atomically."""
    @staticmethod
    def read(path: _Path, name: Optional[str] = None) -> Grid: ...
    def to_openvdb(self, copy: bool = False, module: Any = None) -> Any:
        """A FloatGrid of pyopenvdb / openvdb (sharing the tree with Debian's pyopenvdb)."""
    @staticmethod
    def from_openvdb(grid: Any, copy: bool = False) -> Grid: ...

class Adf:
    """An adaptively sampled distance field (continuous reconstruction on the VDB hierarchy)."""
    def __init__(self, grid: Grid) -> None: ...
    @property
    def grid(self) -> Grid: ...
    @property
    def voxel_size(self) -> float: ...
    @property
    def index_domain(self) -> _IndexBox: ...
    @property
    def world_domain(self) -> tuple[tuple[float, float, float], tuple[float, float, float]]: ...
    @property
    def level_bounds(self) -> list[float]: ...
    @overload
    def sample(self, points: Sequence[float]) -> float: ...
    @overload
    def sample(self, points: npt.ArrayLike) -> npt.NDArray[np.float64]: ...
    def gradient(self, points: _Points) -> npt.NDArray[np.float64]: ...
    def level(self, points: _Points) -> npt.NDArray[np.int32]: ...
    def to_level_set(self, half_width: float = 3.0) -> Grid: ...
    def write(self, path: _Path) -> None: ...
    @staticmethod
    def read(path: _Path, name: Optional[str] = None) -> Adf: ...

# ---------------------------------------------------------------- functions

def read_mesh(path: _Path, *, attribute: Union[str, Sequence[str], None] = None) -> tuple[Any, ...]:
    """(vertices float64 (N, 3), faces int32 (M, 3)) of a mesh file or "builtin:<shape>"; with
    attribute="Cd,N" also {name: float32 (M, 3, C)} per-corner values."""

def write_mesh(path: _Path, vertices: npt.ArrayLike, faces: npt.ArrayLike) -> None: ...
def validate_mesh(vertices: npt.ArrayLike, faces: npt.ArrayLike, source: Optional[str] = None) -> dict[str, Any]: ...
def mesh_to_sdf(
    vertices: npt.ArrayLike,
    faces: npt.ArrayLike,
    *,
    voxel_size: Optional[float] = None,
    voxel_count: int = 256,
    exterior_band: float = 3.0,
    interior_band: float = 3.0,
    world_units: bool = False,
    expansion: Literal["none", "exact", "sweep", "vector"] = "none",
    exact_band: float = 3.0,
    method: Literal["chang", "scan"] = "chang",
    shell: Literal["obb", "pseudonormal", "thin", "offset"] = "obb",
    shell_coverage: Literal["complete", "paper"] = "complete",
    conservative: bool = False,
    sign: Literal["auto", "pseudonormal", "winding", "unsigned"] = "auto",
    fill_interior: bool = False,
    winding_accuracy: float = 2.0,
    device: Literal["auto", "cpu", "vulkan"] = "auto",
    max_voxels: int = 2000000000,
    grid_name: str = "surface",
    source: Optional[str] = None,
    fog_grid: Optional[str] = None,
    reference: Optional[_Path] = None,
    primitive_index_grid: Optional[str] = None,
    attribute: Optional[Mapping[str, npt.ArrayLike]] = None,
    progress: _Progress = None,
    return_stats: bool = False,
) -> Any:
    """Triangle mesh -> narrow-band signed distance level set (`levelforge mesh-to-sdf`).
    Returns a Grid, or (Grid, stats dict) with return_stats=True; with fog_grid,
    primitive_index_grid or attribute a dict {grid name: Grid or (coords, values)}."""

def expand(
    grid: Grid,
    *,
    exterior_width: float = 20.0,
    interior_width: float = 20.0,
    world_units: bool = False,
    fill_interior: bool = False,
    domain: Literal["band", "bbox"] = "band",
    bbox_margin: float = 10.0,
    method: Literal["sweep", "vector"] = "sweep",
    tolerance: float = 0.0001,
    max_iterations: int = 50,
    max_voxels: int = 2000000000,
    source: Optional[str] = None,
    progress: _Progress = None,
    return_stats: bool = False,
) -> Any:
    """Widen (or narrow) a level set's band (`levelforge expand`). Grid, or (Grid, stats)."""

def reshape(
    grid: Grid,
    *,
    op: Literal["dilate", "erode", "open", "close"] = "dilate",
    offset: float = 1.0,
    world_units: bool = False,
    progress: _Progress = None,
) -> Grid:
    """Dilate, erode, open or close a level set by an offset (`levelforge reshape`)."""

def volume_to_sdf(
    volume: Union[npt.ArrayLike, Grid],
    spacing: _Triple = (1.0, 1.0, 1.0),
    origin: _Triple = (0.0, 0.0, 0.0),
    *,
    iso: float = 0.0,
    invert: bool = False,
    method: str = "vcvdt8",
    subvoxel: bool = False,
    exterior_band: float = 3.0,
    interior_band: float = 3.0,
    fill_interior: bool = False,
    sparse: bool = False,
    device: Literal["auto", "cpu", "vulkan"] = "auto",
    max_voxels: int = 2000000000,
    grid_name: str = "surface",
    source: Optional[str] = None,
    progress: _Progress = None,
    return_stats: bool = False,
) -> Any:
    """Scalar volume (array [i, j, k] or Grid) -> level set (`levelforge volume-to-sdf`)."""

def read_volume(
    path: _Path,
    *,
    vdb_grid: Optional[str] = None,
    padding: int = 0,
    raw_dims: Optional[Sequence[int]] = None,
    raw_type: str = "uint8",
    raw_spacing: _Triple = (1.0, 1.0, 1.0),
    raw_header_bytes: int = 0,
    raw_big_endian: bool = False,
    max_voxels: int = 2147483648,
) -> tuple[npt.NDArray[np.float32], tuple[float, float, float], tuple[float, float, float]]:
    """(samples float32 [i, j, k], spacing, origin) of a volume file."""

def mesh_to_adf(
    vertices: npt.ArrayLike,
    faces: npt.ArrayLike,
    *,
    voxel_size: Optional[float] = None,
    voxel_count: int = 256,
    tolerance: float = 0.0,
    padding: float = 8.0,
    bounds: bool = True,
    bound_stride: int = 8,
    max_voxels: int = 68719476736,
    grid_name: str = "adf",
    source: Optional[str] = None,
    progress: _Progress = None,
    return_stats: bool = False,
) -> Any:
    """Triangle mesh -> adaptively sampled distance field (`levelforge mesh-to-adf`). Adf, or (Adf, stats)."""

def csg(
    a: Union[Grid, Adf],
    b: Union[Grid, Adf],
    op: Literal["union", "intersection", "difference"] = "union",
    *,
    level_set: bool = False,
    band: Optional[float] = None,
) -> Union[Grid, Adf]:
    """Union, intersection or difference (`levelforge csg`)."""

def exact_signed_distance(
    vertices: npt.ArrayLike,
    faces: npt.ArrayLike,
    points: _Points,
    *,
    brute_force: bool = False,
    return_closest: bool = False,
) -> Any:
    """Exact signed distances (float64 (N,)); with return_closest also triangles and points."""

def read_grids(path: _Path) -> list[Grid]: ...
def write_grids(path: _Path, grids: Iterable[Grid]) -> None: ...
