# SPDX-License-Identifier: Apache-2.0
"""Reference counting and memory: 1,000 calls of each kind (conversions, queries, errors,
interruptions, pyopenvdb hand-overs; 300 of the slower ADF and expansion) leave the resident set
size and the Python heap (tracemalloc) where they were, and the reference counts of the arguments
unchanged. Any grid here weighs at least 2.5 MB (OpenVDB's upper internal nodes), so one leaked
grid per call would exceed the slack many times over."""
import gc
import os
import sys
import tracemalloc

import numpy as np
import pytest

import levelforge as lf

CALLS = 1000
#: growth allowed over 1,000 calls: far below what one leaked grid or mesh copy per call would
#: add (the sphere's arrays alone are 123 kB: 123 MB over 1,000 calls; its 16-voxel grid ~100 kB)
RSS_SLACK = 16 << 20
PY_SLACK = 256 << 10


def rss():
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


def measure(step, warmup=30, calls=CALLS):
    """Runs step() warmup times, then calls times; returns (RSS growth, Python heap growth)."""
    for _ in range(warmup):
        step()
    gc.collect()
    tracemalloc.start()
    rss0 = rss()
    heap0 = tracemalloc.get_traced_memory()[0]
    for _ in range(calls):
        step()
    gc.collect()
    heap1 = tracemalloc.get_traced_memory()[0]
    rss1 = rss()
    tracemalloc.stop()
    return rss1 - rss0, heap1 - heap0


def check(step, *refs, calls=CALLS):
    counts = [sys.getrefcount(r) for r in refs]
    grown, heap = measure(step, calls=calls)
    assert grown < RSS_SLACK, "RSS grew by %.1f MB over %d calls" % (grown / 2**20, calls)
    assert heap < PY_SLACK, "the Python heap grew by %d bytes over %d calls" % (heap, calls)
    assert [sys.getrefcount(r) for r in refs] == counts, "reference counts changed"


def test_conversions_and_queries_do_not_leak(sphere):
    vertices, faces = sphere
    points = np.random.default_rng(2).uniform(-1.5, 1.5, (256, 3))

    def progress(stage, pct):
        pass

    def step():
        g = lf.mesh_to_sdf(vertices, faces, voxel_count=16, progress=progress)
        g.sample(points)
        g.active_voxels()
        g.values_at(g.active_coords()[:10])
        dict(g.metadata)
        g.to_dense()
        g.transform.index_to_world([[1, 2, 3]])
        g.copy()

    check(step, vertices, faces, points, progress)


def test_read_mesh_views_are_freed():
    def step():
        v, f = lf.read_mesh("builtin:sphere")
        assert v.base is not None  # a view of the library's buffer, freed with the array

    check(step)


def test_adf_and_expand_do_not_leak(box):
    vertices, faces = box
    grid = lf.mesh_to_sdf(vertices, faces, voxel_count=12)
    points = np.zeros((16, 3))

    def step():
        lf.expand(grid, exterior_width=4, interior_width=4)
        adf = lf.mesh_to_adf(vertices, faces, voxel_count=12, bounds=False)
        adf.sample(points)

    # 300 rounds: a leaked ADF or expanded grid is megabytes (see the module docstring)
    check(step, grid, points, calls=300)


def test_errors_do_not_leak(knot):
    vertices, faces = knot
    bad = vertices.copy()
    bad[5, 0] = np.nan

    def interrupt(stage, pct):
        raise KeyboardInterrupt

    def step():
        with pytest.raises(ValueError):
            lf.mesh_to_sdf(bad, faces, voxel_count=16)
        with pytest.raises(ValueError):
            lf.mesh_to_sdf(vertices[:, :2], faces)
        with pytest.raises(KeyboardInterrupt):
            lf.mesh_to_sdf(vertices, faces, voxel_count=16, progress=interrupt)
        with pytest.raises(OSError):
            lf.read_mesh("/nonexistent/levelforge.obj")

    check(step, vertices, faces, bad, interrupt)


def test_pyopenvdb_hand_overs_do_not_leak(box):
    vdb = pytest.importorskip("pyopenvdb", reason="pyopenvdb (python3-openvdb) is not installed")
    grid = lf.mesh_to_sdf(*box, voxel_count=24)

    def step():
        g = grid.to_openvdb()
        assert isinstance(g, vdb.FloatGrid)
        back = lf.Grid.from_openvdb(g)
        del g
        back.sample([[0.0, 0.0, 0.0]])

    check(step, grid)
