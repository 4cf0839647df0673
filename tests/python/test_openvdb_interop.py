# SPDX-License-Identifier: Apache-2.0
"""Grid.to_openvdb() / Grid.from_openvdb() with the installed OpenVDB Python module (Debian 12's
pyopenvdb): round trips keep every value and the metadata; with the boost.python bridge the two
objects share one tree (no copy); the .vdb file road gives the same values."""
import gc
import threading

import numpy as np
import pytest

import levelforge as lf

vdb = pytest.importorskip("pyopenvdb", reason="pyopenvdb (python3-openvdb) is not installed")

BRIDGE = lf._bridge_usable(vdb)


@pytest.fixture
def grid(knot):
    g = lf.mesh_to_sdf(*knot, voxel_count=64)
    g.metadata["shot"] = "sh030"
    return g


def dense_of(vgrid, bbox):
    lo, hi = bbox
    a = np.zeros(tuple(np.array(hi) - np.array(lo) + 1), dtype=np.float32)
    vgrid.copyToArray(a, ijk=tuple(lo))
    return a


def test_to_openvdb_keeps_values_and_metadata(grid):
    g = grid.to_openvdb()
    assert isinstance(g, vdb.FloatGrid)
    assert g.name == grid.name
    assert g.activeVoxelCount() == grid.active_voxel_count
    assert g.gridClass == vdb.GridClass.LEVEL_SET
    assert g.background == pytest.approx(grid.background)
    assert g.transform.voxelSize()[0] == pytest.approx(grid.voxel_size)
    assert g["shot"] == "sh030"
    assert g["levelforge:method"] == "chang2008-exact-band"
    bbox = grid.active_bbox
    np.testing.assert_array_equal(dense_of(g, bbox), grid.to_dense(bbox))
    acc = g.getConstAccessor()
    coords, values = grid.active_voxels()
    for c, v in zip(coords[::997], values[::997]):
        assert acc.getValue(tuple(int(x) for x in c)) == v


def test_round_trip(grid, identical):
    back = lf.Grid.from_openvdb(grid.to_openvdb())
    identical(back, grid)
    assert back.metadata["shot"] == "sh030"


@pytest.mark.skipif(not BRIDGE, reason="no boost.python bridge to this pyopenvdb: the file road is used")
def test_bridge_shares_the_tree(grid):
    g = grid.to_openvdb()
    assert lf.Grid.from_openvdb(g)._shares_tree_with(grid)
    # a change made through pyopenvdb is seen by levelforge: one tree
    g.getAccessor().setValueOn((1000, 1000, 1000), 42.0)
    assert grid.values_at([1000, 1000, 1000]) == 42.0
    assert grid.active_voxel_count == g.activeVoxelCount()
    # copy=True: independent
    c = grid.to_openvdb(copy=True)
    c.getAccessor().setValueOn((2000, 0, 0), 7.0)
    assert grid.values_at([2000, 0, 0]) != 7.0
    assert not lf.Grid.from_openvdb(g, copy=True)._shares_tree_with(grid)


def test_file_road_gives_the_same_grid(grid, identical, monkeypatch):
    monkeypatch.setattr(lf, "_bridge_usable", lambda mod: False)
    g = grid.to_openvdb()
    assert isinstance(g, vdb.FloatGrid)
    back = lf.Grid.from_openvdb(g)
    identical(back, grid)
    assert not back._shares_tree_with(grid)
    assert back.metadata["shot"] == "sh030"


def test_from_openvdb_level_set_sphere():
    s = vdb.createLevelSetSphere(radius=1.0, center=(0.25, 0, 0), voxelSize=0.05, halfWidth=3.0)
    g = lf.Grid.from_openvdb(s)
    assert g.is_level_set and g.voxel_size == pytest.approx(0.05)
    assert g.sample([0.25, 0.0, 0.0]) == pytest.approx(-g.background)  # deep inside: -background
    assert g.sample([1.25, 0.0, 0.0]) == pytest.approx(0.0, abs=1e-3)
    pts = np.random.default_rng(3).normal(size=(200, 3))
    pts = 0.25 * np.array([1, 0, 0]) + pts / np.linalg.norm(pts, axis=1)[:, None]  # on the sphere
    assert np.abs(g.sample(pts)).max() < 0.05 * 0.1
    # and levelforge's own operations accept it
    wide = lf.expand(g, exterior_width=6, interior_width=6)
    assert wide.active_voxel_count > g.active_voxel_count


def test_lifetimes(grid):
    # the pyopenvdb object outlives the Grid it came from
    g = grid.copy().to_openvdb()
    gc.collect()
    assert g.activeVoxelCount() == grid.active_voxel_count
    # the Grid outlives the pyopenvdb object it came from, and is used from other threads
    s = vdb.createLevelSetSphere(radius=1.0, voxelSize=0.05)
    lgrid = lf.Grid.from_openvdb(s)
    del s
    gc.collect()
    out = []

    def work():
        out.append(lgrid.sample([[1.0, 0.0, 0.0]] * 100))

    threads = [threading.Thread(target=work) for _ in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert len(out) == 4 and all(np.abs(o).max() < 1e-3 for o in out)
    del lgrid  # the last reference: the pyopenvdb object is released with the GIL held
    gc.collect()


def test_from_openvdb_rejects_other_grids():
    with pytest.raises(TypeError, match="FloatGrid"):
        lf.Grid.from_openvdb(vdb.Vec3SGrid())
    with pytest.raises(TypeError):
        lf.Grid.from_openvdb("not a grid")


def test_pyopenvdb_reads_what_levelforge_writes(grid, tmp_path):
    path = str(tmp_path / "knot.vdb")
    grid.write(path)
    g = vdb.read(path, "surface")
    assert g.activeVoxelCount() == grid.active_voxel_count
    assert g["levelforge:generator"] == lf.generator
    vdb.write(str(tmp_path / "again.vdb"), [g])
    assert lf.Grid.read(tmp_path / "again.vdb").active_voxel_count == grid.active_voxel_count
