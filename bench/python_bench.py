#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""levelforge from Python: the overhead of the Python call over the C++ call, and levelforge
against pyopenvdb.FloatGrid.createLevelSetFromPolygons (OpenVDB's meshToLevelSet) on the same mesh
and voxel size, in time and in accuracy against the exact reference. docs/benchmarks.md, section
"Python", holds the numbers.

    PYTHONPATH=build/python /usr/bin/python3 bench/python_bench.py                 # torus knot, 256
    PYTHONPATH=build/python /usr/bin/python3 bench/python_bench.py --mesh ../shared/data/meshes/watertight/armadillo_100k.obj
    PYTHONPATH=build/python /usr/bin/python3 bench/python_bench.py --smoke         # 64 voxels, 2 repeats

What is measured, per mesh (voxel count N along the longest side, band 3 voxels each side, the
CLI's defaults):
  * overhead: the wall time of levelforge.mesh_to_sdf(vertices, faces, voxel_count=N) from
    Python (array checks and conversion into the library's mesh, GIL release, the returned Grid)
    against the time the library's own meshToSdf() call measured inside the same run
    (MeshToSdfStats::seconds, return_stats=True): overhead = (python - C++) / C++, the best of the
    repeats of each;
  * pyopenvdb: FloatGrid.createLevelSetFromPolygons(points, triangles, transform, halfWidth=3) with
    levelforge's voxel size, best of the repeats (pyopenvdb holds the GIL and takes float32 points);
  * accuracy: |phi - d| / voxel size at (a sample of) every active voxel of each grid, d the exact
    signed distance of levelforge.exact_signed_distance() (BVH, double precision, the oracle of the
    C++ tests); sign errors where |d| > 1e-6 voxel; and "missing": voxels of the other grid's band
    with |d| < 3 voxels that a grid leaves inactive (band completeness).
Times depend on the machine's load: run it on an otherwise idle machine.
"""
import argparse
import os
import platform
import statistics
import sys
import time

import numpy as np

import levelforge as lf


def machine():
    cpu = platform.machine()
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    mem = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") / 2**30
    return "%d cores (%s), %.0f GiB, Python %s, levelforge %s, OpenVDB %s" % (
        os.cpu_count(), cpu, mem, platform.python_version(), lf.__version__,
        ".".join(map(str, lf.openvdb_version)))


def errors(grid, vertices, faces, sample, rng):
    """max / mean |phi - d| in voxels and sign errors over (a sample of) the active voxels."""
    coords, values = grid.active_voxels()
    if sample and len(coords) > sample:
        pick = rng.choice(len(coords), sample, replace=False)
        coords, values = coords[pick], values[pick]
    h = grid.voxel_size
    exact = lf.exact_signed_distance(vertices, faces, grid.transform.index_to_world(coords))
    err = np.abs(values.astype(np.float64) - exact) / h
    sure = np.abs(exact) > 1e-6 * h
    signs = int(np.count_nonzero(np.sign(values[sure]) != np.sign(exact[sure])))
    return float(err.max()), float(err.mean()), signs, len(coords)


def missing(grid, other, vertices, faces, band, sample, rng):
    """Voxels active in `other` whose exact |d| < band voxels but inactive in `grid`."""
    coords = other.active_coords()
    if sample and len(coords) > sample:
        coords = coords[rng.choice(len(coords), sample, replace=False)]
    h = grid.voxel_size
    exact = lf.exact_signed_distance(vertices, faces, other.transform.index_to_world(coords))
    inside_band = np.abs(exact) < (band - 1e-6) * h
    vals = grid.values_at(coords[inside_band])
    return int(np.count_nonzero(np.abs(vals) >= np.float32(grid.background)))


def bench(name, vertices, faces, count, repeats, sample, vdb):
    rng = np.random.default_rng(7)
    py_times, cpp_times = [], []
    grid = None
    for _ in range(repeats):
        t0 = time.perf_counter()
        grid, stats = lf.mesh_to_sdf(vertices, faces, voxel_count=count, return_stats=True)
        py_times.append(time.perf_counter() - t0)
        cpp_times.append(stats["seconds"])
    h = grid.voxel_size
    row = {
        "mesh": name, "triangles": len(faces), "voxel_count": count, "voxel_size": h,
        "active": grid.active_voxel_count,
        "python_s": min(py_times), "cpp_s": min(cpp_times),
        "overhead_pct": 100.0 * (min(py_times) - min(cpp_times)) / min(cpp_times),
        "overhead_median_pct": 100.0 * statistics.median((p - c) / c for p, c in zip(py_times, cpp_times)),
    }
    row["lf_max"], row["lf_mean"], row["lf_signs"], row["lf_checked"] = errors(grid, vertices, faces, sample, rng)
    if vdb is not None:
        points = vertices.astype(np.float32)
        tris = faces.astype(np.int32)
        xform = vdb.createLinearTransform(voxelSize=h)
        vdb_times = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            vg = vdb.FloatGrid.createLevelSetFromPolygons(points, triangles=tris, transform=xform, halfWidth=3.0)
            vdb_times.append(time.perf_counter() - t0)
        og = lf.Grid.from_openvdb(vg)
        row["vdb_s"] = min(vdb_times)
        row["vdb_active"] = og.active_voxel_count
        row["vdb_max"], row["vdb_mean"], row["vdb_signs"], row["vdb_checked"] = errors(og, vertices, faces, sample, rng)
        row["lf_missing"] = missing(grid, og, vertices, faces, 3.0, sample, rng)
        row["vdb_missing"] = missing(og, grid, vertices, faces, 3.0, sample, rng)
    return row


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--mesh", action="append", help="mesh file or builtin:<shape> (repeatable; "
                    "default builtin:torus-knot, and armadillo_100k.obj when ../shared/data has it)")
    ap.add_argument("--voxel-count", type=int, default=256)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--sample", type=int, default=0, help="check at most this many voxels per grid (0: all)")
    ap.add_argument("--smoke", action="store_true", help="64 voxels, 2 repeats")
    args = ap.parse_args()
    if args.smoke:
        args.voxel_count, args.repeats = 64, 2
    meshes = args.mesh
    if not meshes:
        meshes = ["builtin:torus-knot"]
        data = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "shared", "data", "meshes",
                            "watertight", "armadillo_100k.obj")
        if os.path.exists(data):
            meshes.append(os.path.normpath(data))
    try:
        import pyopenvdb as vdb
    except ImportError:
        vdb = None
        print("pyopenvdb is not installed: the comparison with OpenVDB is skipped", file=sys.stderr)

    print("machine: %s" % machine())
    print("load average before: %.2f %.2f %.2f" % os.getloadavg())
    rows = []
    for m in meshes:
        v, f = lf.read_mesh(m)
        rows.append(bench(os.path.basename(m), v, f, args.voxel_count, args.repeats, args.sample, vdb))
    print("load average after:  %.2f %.2f %.2f" % os.getloadavg())
    print()
    print("| mesh | triangles | voxels (h) | active | levelforge from Python | C++ call | overhead "
          "| pyopenvdb | active | levelforge error max / mean (voxels) | pyopenvdb error max / mean | "
          "sign errors lf / vdb | band voxels missing lf / vdb |")
    print("|---|---:|---|---:|---:|---:|---:|---:|---:|---|---|---|---|")
    for r in rows:
        vdb_cols = ("%.3f s | %d | " % (r["vdb_s"], r["vdb_active"])) if "vdb_s" in r else "- | - | "
        print("| %s | %d | %d (%.4g) | %d | %.3f s | %.3f s | %+.2f %% (median %+.2f %%) | %s%.2g / %.2g | %s | %s | %s |" % (
            r["mesh"], r["triangles"], r["voxel_count"], r["voxel_size"], r["active"], r["python_s"], r["cpp_s"],
            r["overhead_pct"], r["overhead_median_pct"], vdb_cols, r["lf_max"], r["lf_mean"],
            ("%.3g / %.3g" % (r["vdb_max"], r["vdb_mean"])) if "vdb_max" in r else "-",
            ("%d / %d" % (r["lf_signs"], r["vdb_signs"])) if "vdb_signs" in r else str(r["lf_signs"]),
            ("%d / %d" % (r["lf_missing"], r["vdb_missing"])) if "lf_missing" in r else "-"))
    worst = max(r["overhead_pct"] for r in rows)
    print()
    print("overhead of the Python call: %.2f %% at worst (target <= 5 %%)" % worst)
    return 0 if worst <= 5.0 else 1


if __name__ == "__main__":
    sys.exit(main())
