# SPDX-License-Identifier: Apache-2.0
"""Bad input never crashes: wrong shapes, NaN, out-of-range indices, empty arrays and bad options
raise ValueError (or TypeError for a wrong kind of object) with a message that says what is wrong;
library errors arrive as levelforge's typed exceptions with the library's messages."""
import math

import numpy as np
import pytest

import levelforge as lf

TRI_V = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
TRI_F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]], dtype=np.int32)  # a tetrahedron


def nan_vertices():
    v = TRI_V.copy()
    v[2, 1] = np.nan
    return v


def inf_vertices():
    v = TRI_V.copy()
    v[3, 0] = np.inf
    return v


BAD_MESHES = [
    # (vertices, faces, words the message must contain)
    pytest.param(TRI_V[:, :2], TRI_F, "vertices must be an (N, 3) array, got shape (4, 2)", id="2d-vertices"),
    pytest.param(TRI_V.ravel(), TRI_F, "vertices must be an (N, 3) array, got shape (12,)", id="flat-vertices"),
    pytest.param(TRI_V[None], TRI_F, "vertices must be an (N, 3) array, got shape (1, 4, 3)", id="3d-vertices"),
    pytest.param(TRI_V, TRI_F[:, :2], "faces must be an (M, 3) array of vertex indices, got shape (4, 2)",
                 id="quads-as-pairs"),
    pytest.param(TRI_V, TRI_F.ravel(), "faces must be an (M, 3)", id="flat-faces"),
    pytest.param(nan_vertices(), TRI_F, "vertex 2 has a non-finite coordinate", id="nan"),
    # an infinite vertex may first be met as a non-finite bounding box (voxel count)
    pytest.param(inf_vertices(), TRI_F, "non-finite", id="inf"),
    pytest.param(TRI_V, np.where(TRI_F == 3, 7, TRI_F), "mesh has 4 vertices",
                 id="index-out-of-range"),
    pytest.param(TRI_V, np.where(TRI_F == 3, -1, TRI_F), "vertex indices must be >= 0", id="negative-index"),
    pytest.param(TRI_V, TRI_F.astype(np.int64) + 2**32, "too large", id="index-beyond-uint32"),
    pytest.param(TRI_V, TRI_F.astype(np.float64), "faces must hold integer vertex indices, got dtype float64",
                 id="float-faces"),
    pytest.param(np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int32), "no triangles", id="empty"),
    pytest.param(TRI_V, np.zeros((0, 3), dtype=np.int32), "no triangles", id="no-faces"),
    pytest.param([], [], "got shape (0,)", id="empty-lists"),
    pytest.param([[0, 0, 0], [1, 0]], TRI_F, "", id="ragged"),
    pytest.param(np.array([["a", "b", "c"]] * 4), TRI_F, "must hold real numbers", id="strings"),
    pytest.param(TRI_V.astype(complex), TRI_F, "must hold real numbers", id="complex"),
]


@pytest.mark.parametrize("vertices, faces, words", BAD_MESHES)
@pytest.mark.parametrize("function", ["mesh_to_sdf", "mesh_to_adf", "exact_signed_distance", "validate_mesh",
                                      "write_mesh"])
def test_bad_meshes_raise_value_error(tmp_path, function, vertices, faces, words):
    if function == "exact_signed_distance":
        call = lambda: lf.exact_signed_distance(vertices, faces, [[0.0, 0.0, 0.0]])  # noqa: E731
    elif function == "write_mesh":
        call = lambda: lf.write_mesh(tmp_path / "m.obj", vertices, faces)  # noqa: E731
    elif function == "validate_mesh":
        call = lambda: lf.validate_mesh(vertices, faces)  # noqa: E731
    else:
        call = lambda: getattr(lf, function)(vertices, faces, voxel_count=16)  # noqa: E731
    with pytest.raises(ValueError) as info:
        call()
    assert words in str(info.value)
    if function == "write_mesh":
        assert not (tmp_path / "m.obj").exists()


def test_none_is_a_type_error():
    with pytest.raises(TypeError, match="vertices must be an"):
        lf.mesh_to_sdf(None, TRI_F)
    with pytest.raises(TypeError, match="faces must be an"):
        lf.mesh_to_sdf(TRI_V, None)


def test_library_messages_are_kept():
    v = nan_vertices()
    with pytest.raises(lf.InvalidMeshError) as info:
        lf.mesh_to_sdf(v, TRI_F, source="tet.obj")
    assert str(info.value) == "tet.obj: vertex 2 has a non-finite coordinate (0, nan, 0)"
    assert isinstance(info.value, ValueError) and isinstance(info.value, lf.Error)


BAD_OPTIONS = [
    (dict(voxel_size=0.0), "voxel_size must be a finite number > 0"),
    (dict(voxel_size=-1.0), "voxel_size must be a finite number > 0"),
    (dict(voxel_size=math.nan), "voxel_size must be a finite number > 0"),
    (dict(voxel_count=0), "voxel count"),
    (dict(exterior_band=0.0), "exterior"),
    (dict(interior_band=math.nan), "interior"),
    (dict(expansion="bogus"), "unknown expansion 'bogus' (none, exact, sweep, vector)"),
    (dict(method="bogus"), "unknown band method 'bogus' (chang, scan)"),
    (dict(shell="bogus"), "bogus"),
    (dict(shell_coverage="bogus"), "bogus"),
    (dict(expansion="sweep", exact_band=0.5), "the exact band must be at least 1 voxel, got 0.5"),
    (dict(sign="bogus"), "unknown sign mode 'bogus'"),
]


@pytest.mark.parametrize("kwargs, words", BAD_OPTIONS)
def test_bad_options_raise_value_error(kwargs, words):
    with pytest.raises(ValueError) as info:
        lf.mesh_to_sdf(TRI_V, TRI_F, **kwargs)
    assert words.lower() in str(info.value).lower()
    assert isinstance(info.value, lf.InvalidArgumentError) or "voxel count" in words


def test_wrong_types_raise_type_error():
    with pytest.raises(TypeError):
        lf.mesh_to_sdf(TRI_V, TRI_F, voxel_count="many")
    with pytest.raises(TypeError):
        lf.mesh_to_sdf(TRI_V, TRI_F, progress=42)
    with pytest.raises(TypeError):
        lf.mesh_to_sdf(TRI_V, TRI_F, 0.1)  # keyword-only options
    with pytest.raises(TypeError):
        lf.read_mesh(3.5)


def test_resource_limit_is_a_memory_error():
    with pytest.raises(lf.ResourceLimitError) as info:
        lf.mesh_to_sdf(TRI_V, TRI_F, voxel_count=512, max_voxels=1000)
    assert isinstance(info.value, MemoryError)


def test_io_errors_are_os_errors(tmp_path):
    with pytest.raises(lf.IoError) as info:
        lf.read_mesh(tmp_path / "missing.obj")
    assert isinstance(info.value, OSError)
    assert "missing.obj" in str(info.value)
    with pytest.raises(OSError):
        lf.read_mesh(tmp_path / "mesh.xyz")
    with pytest.raises(OSError):
        lf.Grid.read(tmp_path / "missing.vdb")
    (tmp_path / "notvdb.vdb").write_bytes(b"not a vdb file at all")
    with pytest.raises(OSError):
        lf.Grid.read(tmp_path / "notvdb.vdb")
    grid = lf.mesh_to_sdf(TRI_V, TRI_F, voxel_count=8)
    with pytest.raises(OSError):
        grid.write(tmp_path / "no" / "such" / "dir.vdb")


def test_broken_mesh_file_is_invalid_mesh_error(tmp_path):
    path = tmp_path / "broken.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n")
    with pytest.raises(lf.InvalidMeshError) as info:
        lf.read_mesh(path)
    assert "broken.obj" in str(info.value)


BAD_POINTS = [
    ([[0.0, 0.0]], ValueError, "points must be an (N, 3) array"),
    ([[0.0, np.nan, 0.0]], ValueError, "points[0] = (0, nan, 0) is not finite"),
    ([[0.0, 0.0, 0.0], [np.inf, 0.0, 0.0]], ValueError, "points[1]"),
    (np.zeros((2, 3, 3)), ValueError, "points must be an (N, 3) array"),
    ("abc", ValueError, ""),
    (None, TypeError, "points must be"),
]


@pytest.mark.parametrize("points, error, words", BAD_POINTS)
def test_bad_query_points(points, error, words):
    grid = lf.mesh_to_sdf(TRI_V, TRI_F, voxel_count=16)
    adf = lf.mesh_to_adf(TRI_V, TRI_F, voxel_count=16)
    for call in (grid.sample, adf.sample, adf.gradient, lambda p: lf.exact_signed_distance(TRI_V, TRI_F, p)):
        with pytest.raises(error) as info:
            call(points)
        assert words in str(info.value)


def test_bad_grid_arguments():
    grid = lf.mesh_to_sdf(TRI_V, TRI_F, voxel_count=16)
    with pytest.raises(ValueError, match="order must be 0"):
        grid.sample([[0.0, 0.0, 0.0]], order=3)
    with pytest.raises(ValueError, match="ijk must hold integers"):
        grid.values_at([[0.5, 0.0, 0.0]])
    with pytest.raises(ValueError, match="32-bit"):
        grid.values_at([[2**40, 0, 0]])
    with pytest.raises(ValueError, match="bbox"):
        grid.to_dense(((0, 0, 0), (1, 1)))
    with pytest.raises(ValueError, match="empty"):
        grid.to_dense(((5, 5, 5), (1, 1, 1)))
    with pytest.raises(lf.ResourceLimitError):
        grid.to_dense(((0, 0, 0), (10000, 10000, 10000)))
    with pytest.raises(TypeError, match="metadata values"):
        grid.metadata["x"] = object()
    with pytest.raises(KeyError):
        grid.metadata["no such key"]
    with pytest.raises(TypeError, match="must be a levelforge.Grid"):
        lf.expand("not a grid")
    with pytest.raises(ValueError, match="unknown domain"):
        lf.expand(grid, domain="sphere")


BAD_VOLUMES = [
    (np.zeros((4, 4)), "volume must be a 3-D array"),
    (np.zeros((0, 4, 4)), "volume is empty"),
    (np.array([[["x"]]]), "volume must hold real numbers"),
    (np.full((4, 4, 4), np.nan, dtype=np.float32), "NaN"),
]


@pytest.mark.parametrize("volume, words", BAD_VOLUMES)
def test_bad_volumes(volume, words):
    with pytest.raises(ValueError) as info:
        lf.volume_to_sdf(volume)
    assert words.lower() in str(info.value).lower()


def test_bad_volume_options():
    field = np.random.default_rng(1).random((8, 8, 8))
    with pytest.raises(ValueError, match="spacing"):
        lf.volume_to_sdf(field, spacing=(1.0, 2.0))
    with pytest.raises(ValueError, match="spacing"):
        lf.volume_to_sdf(field, spacing=0.0, iso=0.5)
    with pytest.raises(ValueError, match="origin must be finite"):
        lf.volume_to_sdf(field, origin=(0.0, math.nan, 0.0), iso=0.5)
    with pytest.raises(ValueError):
        lf.volume_to_sdf(field, method="bogus", iso=0.5)
    with pytest.raises(ValueError, match="sparse=True needs a Grid"):
        lf.volume_to_sdf(field, sparse=True, iso=0.5)
