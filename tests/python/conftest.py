# SPDX-License-Identifier: Apache-2.0
"""Shared fixtures of the Python module's tests (tests/python/, run by ctest as Python.<file>).

Environment (set by python/CMakeLists.txt for ctest; optional when running pytest by hand with
PYTHONPATH=<build>/python):
  LEVELFORGE_CLI           the levelforge executable, for the bit-for-bit comparisons
  LEVELFORGE_SHARED_DATA   ../shared/data (real meshes and volumes); suites that need it skip
                           with a message when it is absent
"""
import os
import pathlib
import shutil
import subprocess
import sys

import numpy as np
import pytest

import levelforge

ROOT = pathlib.Path(__file__).resolve().parents[2]


def _find_cli():
    env = os.environ.get("LEVELFORGE_CLI")
    if env and os.access(env, os.X_OK):
        return env
    # by hand: the build folder next to the package being tested
    pkg = pathlib.Path(levelforge.__file__).resolve().parent
    candidate = pkg.parent.parent / "houdini_like_tools" / "levelforge"
    if candidate.is_file() and os.access(candidate, os.X_OK):
        return str(candidate)
    return None


@pytest.fixture(scope="session")
def cli():
    """Runs the levelforge CLI: cli("mesh-to-sdf", "builtin:sphere", "out.vdb", "--quiet")."""
    exe = _find_cli()
    if exe is None:
        pytest.skip("the levelforge CLI was not found (set LEVELFORGE_CLI); bit-for-bit comparisons skipped")

    def run(*args):
        r = subprocess.run([exe, *map(str, args)], capture_output=True, text=True)
        if r.returncode != 0:
            raise AssertionError("levelforge %s failed (%d):\n%s%s" % (" ".join(map(str, args)), r.returncode,
                                                                     r.stdout, r.stderr))
        return r.stdout

    run.exe = exe
    return run


@pytest.fixture(scope="session")
def shared_data():
    """../shared/data, or a clean skip."""
    env = os.environ.get("LEVELFORGE_SHARED_DATA")
    path = pathlib.Path(env) if env else ROOT.parent / "shared" / "data"
    if not path.is_dir():
        pytest.skip("shared test data not found at %s (set LEVELFORGE_SHARED_DATA); "
                    "tests on real meshes skipped" % path)
    return path


@pytest.fixture(scope="session")
def knot():
    """The built-in torus knot (the CLI's builtin:torus-knot)."""
    return levelforge.read_mesh("builtin:torus-knot")


@pytest.fixture(scope="session")
def box():
    return levelforge.read_mesh("builtin:box")


@pytest.fixture(scope="session")
def sphere():
    return levelforge.read_mesh("builtin:sphere")


def assert_grids_identical(a, b):
    """Bit for bit: active voxels (coordinates and the bits of their values), background,
    transform, class, and the inactive values over the active box (the signs of the flood fill)."""
    assert a.active_voxel_count == b.active_voxel_count
    assert a.grid_class == b.grid_class
    assert np.float32(a.background).view(np.uint32) == np.float32(b.background).view(np.uint32)
    assert a.transform == b.transform
    ca, va = a.active_voxels()
    cb, vb = b.active_voxels()
    # both in tree order: same topology gives the same order
    np.testing.assert_array_equal(ca, cb)
    np.testing.assert_array_equal(va.view(np.uint32), vb.view(np.uint32))
    if a.active_bbox is not None:
        bbox = np.array(a.active_bbox)
        bbox[0] -= 2
        bbox[1] += 2
        da = a.to_dense(bbox)
        db = b.to_dense(bbox)
        np.testing.assert_array_equal(da.view(np.uint32), db.view(np.uint32))


@pytest.fixture
def identical():
    return assert_grids_identical


def python_exe():
    return sys.executable
