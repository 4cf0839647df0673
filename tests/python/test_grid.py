# SPDX-License-Identifier: Apache-2.0
"""levelforge.Grid: active voxels, sampling (at voxel centres: the stored values), dense copies,
the transform, metadata, .vdb files."""
import os

import numpy as np
import pytest

import levelforge as lf


@pytest.fixture(scope="module")
def grid(knot):
    return lf.mesh_to_sdf(*knot, voxel_count=80, exterior_band=3, interior_band=2)


def test_active_voxels(grid):
    coords, values = grid.active_voxels()
    assert coords.dtype == np.int32 and coords.shape == (grid.active_voxel_count, 3)
    assert values.dtype == np.float32 and values.shape == (grid.active_voxel_count,)
    np.testing.assert_array_equal(grid.active_coords(), coords)
    np.testing.assert_array_equal(grid.active_values(), values)
    assert len({tuple(c) for c in coords[:50000]}) == min(50000, len(coords))  # no duplicates
    np.testing.assert_array_equal(grid.values_at(coords), values)
    lo, hi = grid.active_bbox
    np.testing.assert_array_equal(coords.min(axis=0), lo)
    np.testing.assert_array_equal(coords.max(axis=0), hi)
    h = grid.voxel_size
    assert np.all(values < 3 * h) and np.all(values > -2 * h)


@pytest.mark.parametrize("order", [0, 1, 2])
def test_sample_at_voxel_centres_returns_the_stored_values(grid, order):
    coords, values = grid.active_voxels()
    points = grid.transform.index_to_world(coords)
    samples = grid.sample(points, order=order)
    assert samples.dtype == np.float32
    np.testing.assert_array_equal(samples, values)
    # also from world positions computed in NumPy, index * voxel size
    np.testing.assert_array_equal(grid.sample(coords * grid.voxel_size, order=order), values)


def test_sample_single_point_and_lists(grid):
    coords, values = grid.active_voxels()
    p = grid.transform.index_to_world(coords[7])
    assert p.shape == (3,)
    assert isinstance(grid.sample(p), float)
    assert grid.sample(p) == values[7]
    assert grid.sample(p.tolist()) == values[7]
    assert grid.sample(np.zeros((0, 3))).shape == (0,)
    assert grid.values_at(coords[7]) == values[7]


def test_trilinear_between_voxels(grid):
    coords, values = grid.active_voxels()
    # halfway between two active neighbours along x: the mean of the two values
    index = {tuple(c): v for c, v in zip(coords[:200000].tolist(), values[:200000])}
    pairs = [(c, (c[0] + 1, c[1], c[2])) for c in list(index)[:2000] if (c[0] + 1, c[1], c[2]) in index]
    assert pairs
    mid = np.array([[a[0] + 0.5, a[1], a[2]] for a, _ in pairs])
    got = grid.sample(grid.transform.index_to_world(mid))
    want = np.array([(index[a] + index[b]) / 2 for a, b in pairs], dtype=np.float64)
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-6 * grid.voxel_size)


def test_far_points_give_the_background(grid):
    far = np.array([[1e6, 0, 0], [0, -1e12, 0], [1e300, 1e300, -1e300]])
    np.testing.assert_array_equal(grid.sample(far), np.float32(grid.background))


def test_to_dense(grid):
    lo, hi = grid.active_bbox
    dense = grid.to_dense()
    assert dense.dtype == np.float32 and dense.flags["C_CONTIGUOUS"]
    assert dense.shape == tuple(np.array(hi) - np.array(lo) + 1)
    coords, values = grid.active_voxels()
    np.testing.assert_array_equal(dense[tuple((coords - np.array(lo)).T)], values)
    # inactive voxels hold +-background
    mask = np.ones(dense.shape, bool)
    mask[tuple((coords - np.array(lo)).T)] = False
    assert set(np.unique(np.abs(dense[mask]))) == {np.float32(grid.background)}
    # a box of my own
    box = ((lo[0] - 2, 0, 0), (lo[0] + 3, 4, 5))
    sub = grid.to_dense(box)
    assert sub.shape == (6, 5, 6)
    ijk = np.stack(np.meshgrid(*[np.arange(a, b + 1) for a, b in zip(*box)], indexing="ij"), -1).reshape(-1, 3)
    np.testing.assert_array_equal(sub.reshape(-1), grid.values_at(ijk))


def test_transform(grid):
    t = grid.transform
    h = grid.voxel_size
    assert t.voxel_size == pytest.approx((h, h, h))
    assert t.is_linear
    m = t.matrix
    assert m.shape == (4, 4)
    ijk = np.array([[1, 2, 3], [-4, 5, 6]])
    world = t.index_to_world(ijk)
    np.testing.assert_allclose(world, np.c_[ijk, np.ones(2)] @ m[:, :3])
    np.testing.assert_allclose(t.world_to_index(world), ijk, atol=1e-9)
    assert t == grid.transform
    assert "UniformScaleMap" in repr(t)


def test_metadata_view(grid):
    g = grid.copy()
    md = g.metadata
    assert md["levelforge:method"] == "chang2008-exact-band"
    assert md["name"] == "surface" and md["class"] == "level set"
    assert set(md) >= {"levelforge:exterior_band_voxels", "levelforge:source", "levelforge:generator"}
    md["shot"] = "sh010"
    md["frame"] = 1001
    md["scale"] = 0.5
    md["flag"] = True
    md["offset"] = (1.0, 2.0, 3.0)
    md["cell"] = (1, 2, 3)
    md["levelforge:exterior_band_voxels"] = 4  # stays a float entry
    assert g.metadata["shot"] == "sh010" and g.metadata["frame"] == 1001
    assert g.metadata["scale"] == 0.5 and g.metadata["flag"] is True
    assert g.metadata["offset"] == (1.0, 2.0, 3.0) and g.metadata["cell"] == (1, 2, 3)
    assert g.metadata["levelforge:exterior_band_voxels"] == 4.0
    del g.metadata["shot"]
    assert "shot" not in g.metadata
    g.name = "renamed"
    assert g.metadata["name"] == "renamed"
    g.metadata = {"only": "this"}
    assert dict(g.metadata) == {"only": "this", "name": "renamed", "class": "level set"}
    assert "only" not in grid.metadata  # the copy is independent
    assert "GridMetadata" in repr(g.metadata)


def test_write_read_round_trip(grid, tmp_path, identical):
    g = grid.copy()
    g.metadata["shot"] = "sh020"
    path = tmp_path / "knot.vdb"
    g.write(path)
    back = lf.Grid.read(path)
    identical(back, g)
    assert back.metadata["shot"] == "sh020"
    assert back.metadata["levelforge:method"] == "chang2008-exact-band"
    assert lf.Grid.read(str(path), name="surface").active_voxel_count == g.active_voxel_count
    with pytest.raises(lf.IoError, match="no float grid named 'nope'"):
        lf.Grid.read(path, name="nope")
    # no temporary files left behind
    assert os.listdir(tmp_path) == ["knot.vdb"]


def test_several_grids_in_one_file(grid, box, tmp_path):
    other = lf.mesh_to_sdf(*box, voxel_count=20, grid_name="box")
    path = tmp_path / "two.vdb"
    lf.write_grids(path, [grid, other])
    grids = lf.read_grids(path)
    assert sorted(g.name for g in grids) == ["box", "surface"]  # in the order OpenVDB lists them (by name)
    assert lf.Grid.read(path, "box").active_voxel_count == other.active_voxel_count
    with pytest.raises(ValueError):
        lf.write_grids(path, [])


def test_copy_is_deep(grid):
    c = grid.copy()
    assert not c._shares_tree_with(grid)
    assert grid._shares_tree_with(grid)
    c.name = "other"
    assert grid.name == "surface"


def test_repr_and_properties(grid):
    assert repr(grid).startswith("<levelforge.Grid 'surface': level set, voxel size")
    assert grid.grid_class == "level set" and grid.is_level_set
    assert grid.background == pytest.approx(3 * grid.voxel_size, rel=1e-6)
    assert grid.memory_bytes > 0


def test_grid_has_no_public_constructor():
    with pytest.raises(TypeError):
        lf.Grid()
