# SPDX-License-Identifier: Apache-2.0
"""levelforge.mesh_to_sdf: bit for bit the C++ library (through the CLI, which calls
levelforge::meshToSdf), exact against the exact reference, the CLI's defaults, array-likes."""
import threading

import numpy as np
import pytest

import levelforge as lf

# CLI arguments -> the same keyword arguments of mesh_to_sdf
CONFIGS = [
    pytest.param([], {}, id="defaults"),
    pytest.param(["--voxel-count", 96], dict(voxel_count=96), id="count96"),
    pytest.param(["--voxel-size", 0.031, "--exterior-band", 0.1, "--interior-band", 0.05, "--world-units"],
                 dict(voxel_size=0.031, exterior_band=0.1, interior_band=0.05, world_units=True), id="world-units"),
    pytest.param(["--voxel-count", 64, "--exterior-band", 7, "--interior-band", 5, "--expansion", "sweep"],
                 dict(voxel_count=64, exterior_band=7, interior_band=5, expansion="sweep"), id="sweep"),
    pytest.param(["--voxel-count", 64, "--exterior-band", 7, "--expansion", "vector", "--exact-band", 2],
                 dict(voxel_count=64, exterior_band=7, expansion="vector", exact_band=2), id="vector"),
    pytest.param(["--voxel-count", 64, "--method", "scan", "--shell", "pseudonormal"],
                 dict(voxel_count=64, method="scan", shell="pseudonormal"), id="scan"),
    pytest.param(["--voxel-count", 48, "--grid-name", "knot", "--max-voxels", 10**9],
                 dict(voxel_count=48, grid_name="knot", max_voxels=10**9), id="name"),
]

SIGN_CONFIGS = [
    pytest.param(["--voxel-count", 64, "--sign", "winding"], dict(voxel_count=64, sign="winding"), id="winding"),
    pytest.param(["--voxel-count", 64, "--sign", "pseudonormal", "--fill-interior"],
                 dict(voxel_count=64, sign="pseudonormal", fill_interior=True), id="fill-interior"),
    pytest.param(["--voxel-count", 64, "--sign", "unsigned"], dict(voxel_count=64, sign="unsigned"), id="unsigned"),
]


def levelforge_metadata(grid):
    """The levelforge:* entries a conversion stamps, but the source (a path for the CLI)."""
    return {k: v for k, v in grid.metadata.items()
            if k.startswith("levelforge:") and k != "levelforge:source" or k in ("name", "class")}


def run_cli_and_python(cli, tmp_path, mesh_arg, vertices, faces, cli_args, kwargs):
    out = tmp_path / "cli.vdb"
    cli("mesh-to-sdf", mesh_arg, out, "--quiet", *cli_args)
    return lf.Grid.read(out), lf.mesh_to_sdf(vertices, faces, **kwargs)


@pytest.mark.parametrize("cli_args, kwargs", CONFIGS)
def test_torus_knot_bit_for_bit_with_cli(cli, tmp_path, knot, identical, cli_args, kwargs):
    expected, got = run_cli_and_python(cli, tmp_path, "builtin:torus-knot", *knot, cli_args, kwargs)
    identical(got, expected)
    assert levelforge_metadata(got) == levelforge_metadata(expected)
    assert got.name == expected.name


@pytest.mark.skipif(not lf._levelforge.HAVE_SIGN_MODES, reason="this library has no sign modes")
@pytest.mark.parametrize("cli_args, kwargs", SIGN_CONFIGS)
def test_sign_modes_bit_for_bit_with_cli(cli, tmp_path, identical, cli_args, kwargs, shared_data):
    path = shared_data / "meshes" / "open_or_broken" / "suzanne.obj"
    vertices, faces = lf.read_mesh(path)
    expected, got = run_cli_and_python(cli, tmp_path, path, vertices, faces, cli_args, kwargs)
    identical(got, expected)
    assert levelforge_metadata(got) == levelforge_metadata(expected)


@pytest.mark.parametrize("name, count", [("watertight/spot.obj", 128), ("open_or_broken/bunny.obj", 96),
                                         ("watertight/chess_knight_decimated.off", 64)])
def test_shared_meshes_bit_for_bit_with_cli(cli, tmp_path, identical, shared_data, name, count):
    path = shared_data / "meshes" / name
    vertices, faces = lf.read_mesh(str(path))
    expected, got = run_cli_and_python(cli, tmp_path, path, vertices, faces, ["--voxel-count", count],
                                       dict(voxel_count=count))
    identical(got, expected)


def test_band_is_exact_against_the_reference(knot):
    vertices, faces = knot
    grid = lf.mesh_to_sdf(vertices, faces, voxel_count=64, exterior_band=4, interior_band=2)
    coords, values = grid.active_voxels()
    points = grid.transform.index_to_world(coords)
    exact = lf.exact_signed_distance(vertices, faces, points)
    h = grid.voxel_size
    # the library stores the exact double distance as float
    assert np.max(np.abs(values - exact)) / h < 1e-5
    assert np.all(np.sign(values[np.abs(exact) > 1e-6 * h]) == np.sign(exact[np.abs(exact) > 1e-6 * h]))
    assert np.all(values / h < 4) and np.all(values / h > -2)


def test_defaults_are_the_clis(box):
    vertices, faces = box
    g = lf.mesh_to_sdf(vertices, faces)
    assert g.voxel_size == pytest.approx(2.0 / 256, rel=1e-12)  # the cube [-1, 1]^3, 256 voxels
    assert g.name == "surface"
    assert g.is_level_set
    md = g.metadata
    assert md["levelforge:exterior_band_voxels"] == 3.0
    assert md["levelforge:interior_band_voxels"] == 3.0
    assert md["levelforge:method"] == "chang2008-exact-band"
    assert md["levelforge:generator"] == lf.generator
    assert g.background == pytest.approx(3 * g.voxel_size, rel=1e-6)
    # voxel_size wins over voxel_count, as in the library
    assert lf.mesh_to_sdf(vertices, faces, voxel_size=0.1, voxel_count=7).voxel_size == pytest.approx(0.1)


def test_source_and_stats(box):
    vertices, faces = box
    g, stats = lf.mesh_to_sdf(vertices, faces, voxel_count=32, source="my box", return_stats=True)
    assert g.metadata["levelforge:source"] == "my box"
    assert stats["active_voxels"] == g.active_voxel_count
    assert stats["voxel_size"] == pytest.approx(g.voxel_size)
    assert stats["method"] == "chang2008-exact-band"
    assert stats["band"]["active_voxels"] == g.active_voxel_count
    assert stats["seconds"] > 0
    g2, stats2 = lf.mesh_to_sdf(vertices, faces, voxel_count=32, expansion="sweep", exterior_band=6,
                                return_stats=True)
    assert stats2["expansion"]["active_voxels"] == g2.active_voxel_count


def test_array_likes_give_the_same_grid(box, knot, identical):
    vertices, faces = knot
    reference = lf.mesh_to_sdf(vertices, faces, voxel_count=40)
    # lists
    identical(lf.mesh_to_sdf(vertices.tolist(), faces.tolist(), voxel_count=40), reference)
    # non-contiguous views, Fortran order, other integer types
    wide = np.zeros((len(vertices), 6))
    wide[:, ::2] = vertices
    identical(lf.mesh_to_sdf(wide[:, ::2], np.asfortranarray(faces).astype(np.int64), voxel_count=40), reference)
    identical(lf.mesh_to_sdf(vertices, faces.astype(np.uint32), voxel_count=40), reference)
    identical(lf.mesh_to_sdf(vertices[::-1][::-1], faces.astype(np.uint64), voxel_count=40), reference)
    # float32 vertices: converted exactly to float64
    v32 = vertices.astype(np.float32)
    identical(lf.mesh_to_sdf(v32, faces, voxel_count=40),
              lf.mesh_to_sdf(v32.astype(np.float64), faces, voxel_count=40))
    # integer vertices
    bv, bf = box
    identical(lf.mesh_to_sdf(bv.astype(np.int32), bf, voxel_count=20), lf.mesh_to_sdf(bv, bf, voxel_count=20))


def test_inputs_are_not_modified_or_kept(knot):
    vertices, faces = knot
    v, f = vertices.copy(), faces.copy()
    import sys
    rv, rf = sys.getrefcount(v), sys.getrefcount(f)
    lf.mesh_to_sdf(v, f, voxel_count=24)
    np.testing.assert_array_equal(v, vertices)
    np.testing.assert_array_equal(f, faces)
    assert sys.getrefcount(v) == rv and sys.getrefcount(f) == rf


def test_the_gil_is_released_while_computing(knot):
    """While a worker thread is inside mesh_to_sdf (after its first progress report, outside the
    callback), the main thread runs Python code."""
    vertices, faces = knot
    state = {"calls": 0, "in_callback": False, "done": False}
    observed = []

    def progress(stage, percent):
        state["in_callback"] = True
        state["calls"] += 1
        state["in_callback"] = False

    def work():
        try:
            lf.mesh_to_sdf(vertices, faces, voxel_count=320, exterior_band=4, progress=progress)
        finally:
            state["done"] = True

    t = threading.Thread(target=work)
    t.start()
    while not state["done"]:
        if state["calls"] >= 1 and not state["in_callback"] and not state["done"]:
            observed.append(True)
            if len(observed) > 1000:
                break
    t.join()
    assert observed, "the main thread never ran while the worker computed"
