# SPDX-License-Identifier: Apache-2.0
"""expand, volume_to_sdf, read_volume, mesh_to_adf / Adf, csg: bit for bit the CLI's operators on
the same inputs, with the same parameters."""
import re

import numpy as np
import pytest

import levelforge as lf


def stamped(grid):
    return {k: v for k, v in grid.metadata.items() if k.startswith("levelforge:") and k != "levelforge:source"}


def sphere_field(n=40, radius=13.3, centre=(19.6, 20.2, 19.1), spacing=(1.0, 1.0, 1.0)):
    """radius - |x - centre| on an (n, n, n) lattice indexed [i, j, k] (positive inside)."""
    ijk = np.stack(np.meshgrid(*[np.arange(n)] * 3, indexing="ij"), -1) * np.array(spacing)
    return (radius - np.linalg.norm(ijk - np.array(centre), axis=-1)).astype(np.float32)


# ---------------------------------------------------------------- expand

@pytest.mark.parametrize("cli_args, kwargs", [
    ([], {}),
    (["--exterior-width", 8, "--interior-width", 5, "--method", "vector"],
     dict(exterior_width=8, interior_width=5, method="vector")),
    (["--exterior-width", 4, "--fill-interior"], dict(exterior_width=4, fill_interior=True)),
    (["--domain", "bbox", "--bbox-margin", 2], dict(domain="bbox", bbox_margin=2)),
    (["--exterior-width", 0.3, "--interior-width", 0.2, "--world-units", "--tolerance", 1e-3, "--max-iterations", 9],
     dict(exterior_width=0.3, interior_width=0.2, world_units=True, tolerance=1e-3, max_iterations=9)),
], ids=["defaults", "vector", "fill", "bbox", "world"])
def test_expand_bit_for_bit_with_cli(cli, tmp_path, knot, identical, cli_args, kwargs):
    band = lf.mesh_to_sdf(*knot, voxel_count=48)
    band.write(tmp_path / "band.vdb")
    cli("expand", tmp_path / "band.vdb", tmp_path / "wide.vdb", "--quiet", *cli_args)
    expected = lf.Grid.read(tmp_path / "wide.vdb")
    got = lf.expand(band, **kwargs)
    identical(got, expected)
    assert stamped(got) == stamped(expected)
    assert got.metadata["levelforge:source"] == band.metadata["levelforge:source"]
    assert band.active_voxel_count < got.active_voxel_count  # the input is not modified


# ---------------------------------------------------------------- volumes

@pytest.mark.parametrize("cli_args, kwargs", [
    (["--iso", 0.0], dict(iso=0.0)),
    (["--iso", 0.5, "--subvoxel", "--method", "vcvdt4", "--exterior-band", 5, "--interior-band", 2],
     dict(iso=0.5, subvoxel=True, method="vcvdt4", exterior_band=5, interior_band=2)),
    (["--iso", 0.0, "--subvoxel", "--method", "exact", "--fill-interior"],
     dict(iso=0.0, subvoxel=True, method="exact", fill_interior=True)),
    (["--iso", 0.0, "--method", "quasi-euclidean-3"], dict(iso=0.0, method="quasi-euclidean-3")),
    (["--iso", -2.0, "--invert", "--method", "evdt"], dict(iso=-2.0, invert=True, method="evdt")),
], ids=["binary", "subvoxel", "exact-fill", "chamfer", "invert"])
def test_volume_to_sdf_bit_for_bit_with_cli(cli, tmp_path, identical, cli_args, kwargs):
    spacing = (0.5, 0.5, 0.75)
    field = sphere_field(spacing=spacing)
    path = tmp_path / "field.raw"
    field.ravel(order="F").tofile(path)  # raw: x fastest
    n = field.shape
    cli("volume-to-sdf", path, tmp_path / "out.vdb", "--quiet", "--raw-dims", "%d,%d,%d" % n,
        "--raw-type", "float32", "--raw-spacing", "%g,%g,%g" % spacing, *cli_args)
    expected = lf.Grid.read(tmp_path / "out.vdb")
    got = lf.volume_to_sdf(field, spacing, **kwargs)
    identical(got, expected)
    assert stamped(got) == stamped(expected)
    # any array-like: C or Fortran order, float64, lists
    identical(lf.volume_to_sdf(np.asfortranarray(field.astype(np.float64)), spacing, **kwargs), expected)


def test_volume_from_a_grid_dense_and_sparse_with_cli(cli, tmp_path, knot, identical):
    """A .vdb scalar grid, densified (active box + band) or converted on its sparse topology."""
    fog = lf.mesh_to_sdf(*knot, voxel_count=64, exterior_band=5, interior_band=5)
    fog.write(tmp_path / "fog.vdb")
    for extra, kwargs in [([], {}), (["--sparse"], dict(sparse=True))]:
        cli("volume-to-sdf", tmp_path / "fog.vdb", tmp_path / "out.vdb", "--quiet", "--iso", 0.01, "--invert",
            "--subvoxel", *extra)
        expected = lf.Grid.read(tmp_path / "out.vdb")
        got = lf.volume_to_sdf(fog, iso=0.01, invert=True, subvoxel=True, **kwargs)
        identical(got, expected)
        assert stamped(got) == stamped(expected)


def test_read_volume_and_convert_like_the_cli(cli, tmp_path, identical, shared_data):
    path = shared_data / "volumes" / "cgal_skull_2.9.inr"
    samples, spacing, origin = lf.read_volume(path)
    assert samples.dtype == np.float32 and samples.ndim == 3
    cli("volume-to-sdf", path, tmp_path / "skull.vdb", "--quiet", "--iso", 2.9, "--subvoxel")
    identical(lf.volume_to_sdf(samples, spacing, origin, iso=2.9, subvoxel=True), lf.Grid.read(tmp_path / "skull.vdb"))


def test_volume_round_trip_through_to_dense(knot):
    """to_dense() and volume_to_sdf() agree on the [i, j, k] layout and the world position."""
    grid = lf.mesh_to_sdf(*knot, voxel_count=48, exterior_band=4, interior_band=4)
    lo, hi = grid.active_bbox
    dense = grid.to_dense()
    origin = grid.transform.index_to_world(lo)
    again = lf.volume_to_sdf(dense, grid.voxel_size, origin, iso=0.0, invert=True, subvoxel=True,
                             method="exact", exterior_band=2, interior_band=2)
    coords, values = again.active_voxels()
    pts = again.transform.index_to_world(coords)
    # the surface reconstructed from the samples is within a fraction of a voxel of the original
    assert np.abs(grid.sample(pts) - values).max() < 0.25 * grid.voxel_size
    assert again.voxel_size == pytest.approx(grid.voxel_size)


# ---------------------------------------------------------------- ADF and CSG

def test_mesh_to_adf_bit_for_bit_with_cli(cli, tmp_path, knot, identical):
    cli("mesh-to-adf", "builtin:torus-knot", tmp_path / "adf.vdb", "--quiet", "--voxel-count", 96)
    expected = lf.Adf.read(tmp_path / "adf.vdb")
    adf = lf.mesh_to_adf(*knot, voxel_count=96)
    identical(adf.grid, expected.grid)
    assert stamped(adf.grid) == stamped(expected.grid)
    assert adf.level_bounds == expected.level_bounds
    assert adf.index_domain == expected.index_domain
    # queries: the CLI's `sample` prints %.9g
    for p in [(0.1, 0.2, 0.3), (1.0, 0.0, 0.0), (-0.7, 0.4, -0.2)]:
        out = cli("sample", tmp_path / "adf.vdb", *p)
        printed = float(re.search(r"distance: (\S+)", out).group(1))
        assert adf.sample(p) == pytest.approx(printed, rel=1e-8, abs=1e-12)


def test_adf_queries_against_the_exact_reference(knot):
    vertices, faces = knot
    adf, stats = lf.mesh_to_adf(vertices, faces, voxel_count=64, return_stats=True)
    rng = np.random.default_rng(4)
    near = vertices[rng.integers(0, len(vertices), 500)] + rng.normal(scale=0.02, size=(500, 3))
    exact = lf.exact_signed_distance(vertices, faces, near)
    got = adf.sample(near)
    assert got.dtype == np.float64 and got.shape == (500,)
    assert np.abs(got - exact).max() < 2 * adf.voxel_size
    assert adf.gradient(near).shape == (500, 3)
    assert set(np.unique(adf.level(near))) <= {0, 1, 2, 3, 4}
    assert stats["type1"] > 0
    ls = adf.to_level_set(3.0)
    assert ls.is_level_set and ls.voxel_size == pytest.approx(adf.voxel_size)
    assert lf.Adf(adf.grid).index_domain == adf.index_domain
    with pytest.raises(ValueError):
        lf.Adf(ls)  # not an ADF


@pytest.mark.parametrize("op", ["union", "intersection", "difference"])
def test_csg_bit_for_bit_with_cli(cli, tmp_path, knot, sphere, identical, op):
    a = lf.mesh_to_sdf(*knot, voxel_size=0.03)
    b = lf.mesh_to_sdf(sphere[0] * 0.8 + [0.9, 0, 0], sphere[1], voxel_size=0.03)
    a.write(tmp_path / "a.vdb")
    b.write(tmp_path / "b.vdb")
    cli("csg", tmp_path / "a.vdb", tmp_path / "b.vdb", tmp_path / "c.vdb", "--op", op)
    identical(lf.csg(a, b, op), lf.Grid.read(tmp_path / "c.vdb"))
    # ADFs: an ADF result, and a level set with level_set=True
    fa = lf.mesh_to_adf(*knot, voxel_size=0.03, bounds=False)
    fb = lf.mesh_to_adf(sphere[0] * 0.8 + [0.9, 0, 0], sphere[1], voxel_size=0.03, bounds=False)
    fa.write(tmp_path / "fa.vdb")
    fb.write(tmp_path / "fb.vdb")
    cli("csg", tmp_path / "fa.vdb", tmp_path / "fb.vdb", tmp_path / "fc.vdb", "--op", op)
    got = lf.csg(fa, fb, op)
    assert isinstance(got, lf.Adf)
    identical(got.grid, lf.Grid.read(tmp_path / "fc.vdb"))
    cli("csg", tmp_path / "fa.vdb", tmp_path / "b.vdb", tmp_path / "mixed.vdb", "--op", op)
    identical(lf.csg(fa, b, op), lf.Grid.read(tmp_path / "mixed.vdb"))
    with pytest.raises(ValueError, match="unknown"):
        lf.csg(a, b, "xor")
