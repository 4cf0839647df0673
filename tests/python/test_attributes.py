# SPDX-License-Identifier: Apache-2.0
"""mesh_to_sdf's fog_grid, reference, primitive_index_grid and attribute (the CLI's --fog-grid,
--reference, --primitive-index-grid, --attribute), and read_mesh(attribute=...): the same grids
as the CLI, attribute transfer exact on a linear ramp."""
import numpy as np
import pytest

import levelforge as lf

# a unit box of 6 quads, colour = position + 0.5 (linear on every face), a uv per face corner
BOX_OBJ = (
    "v -0.5 -0.5 -0.5 0 0 0\nv 0.5 -0.5 -0.5 1 0 0\nv 0.5 0.5 -0.5 1 1 0\nv -0.5 0.5 -0.5 0 1 0\n"
    "v -0.5 -0.5 0.5 0 0 1\nv 0.5 -0.5 0.5 1 0 1\nv 0.5 0.5 0.5 1 1 1\nv -0.5 0.5 0.5 0 1 1\n"
    "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
    "f 1/1 4/2 3/3 2/4\nf 5/1 6/2 7/3 8/4\nf 1/1 2/2 6/3 5/4\n"
    "f 2/1 3/2 7/3 6/4\nf 3/1 4/2 8/3 7/4\nf 4/1 1/2 5/3 8/4\n")


@pytest.fixture
def box_obj(tmp_path):
    path = tmp_path / "box.obj"
    path.write_text(BOX_OBJ)
    return path


def test_read_mesh_attributes(box_obj):
    vertices, faces, attrs = lf.read_mesh(box_obj, attribute="Cd,uv")
    assert sorted(attrs) == ["Cd", "uv"]
    assert attrs["Cd"].shape == (len(faces), 3, 3) and attrs["Cd"].dtype == np.float32
    # the colour of every corner is its vertex's position + 0.5
    np.testing.assert_array_equal(attrs["Cd"], (vertices[faces] + 0.5).astype(np.float32))
    assert np.all(attrs["uv"][:, :, 2] == 0)
    assert len(lf.read_mesh(box_obj)) == 2
    with pytest.raises(lf.InvalidArgumentError, match=r"no vertex attribute 'N' \(it has: Cd, uv\)"):
        lf.read_mesh(box_obj, attribute=["N"])
    with pytest.raises(lf.InvalidArgumentError, match="it has none"):
        lf.read_mesh("builtin:sphere", attribute="Cd")


def test_attribute_grids_match_the_cli(cli, tmp_path, box_obj, identical):
    out = tmp_path / "box.vdb"
    # (no primitive index in the file: pyopenvdb reads no Int32 grid)
    cli("mesh-to-sdf", box_obj, out, "--voxel-size", 0.05, "--quiet", "--attribute", "Cd,uv", "--fog-grid", "density")
    vertices, faces, attrs = lf.read_mesh(box_obj, attribute="Cd,uv")
    grids = lf.mesh_to_sdf(vertices, faces, voxel_size=0.05, attribute=attrs, primitive_index_grid="prim",
                           fog_grid="density")
    assert list(grids) == ["surface", "density", "prim", "Cd", "uv"]
    identical(grids["surface"], lf.Grid.read(out, "surface"))
    identical(grids["density"], lf.Grid.read(out, "density"))
    coords, cd = grids["Cd"]
    assert len(coords) == grids["surface"].active_voxel_count
    # outside the box the closest point is the clamped voxel centre: Cd = clamp(p) + 0.5 exactly
    p = grids["surface"].transform.index_to_world(coords)
    outside = np.any(np.abs(p) > 0.5, axis=1)
    np.testing.assert_allclose(cd[outside], np.clip(p[outside], -0.5, 0.5) + 0.5, atol=1e-5)
    prim_coords, prim = grids["prim"]
    # rows of faces (the arrays do not know the file's quads, the CLI's file says 0..5)
    assert prim.dtype == np.int32 and prim.min() == 0 and prim.max() == len(faces) - 1
    pyopenvdb = pytest.importorskip("pyopenvdb")
    if pyopenvdb.LIBRARY_VERSION[0] != lf.openvdb_version[0]:
        pytest.skip("pyopenvdb was built against another OpenVDB")
    assert {g.name for g in pyopenvdb.readAllGridMetadata(str(out))} == {"surface", "density", "Cd", "uv"}
    cd_grid = pyopenvdb.read(str(out), "Cd")
    assert cd_grid.activeVoxelCount() == len(coords)
    acc = cd_grid.getConstAccessor()
    got = np.array([acc.getValue(tuple(int(v) for v in ijk)) for ijk in coords[:500]], dtype=np.float32)
    np.testing.assert_array_equal(got, cd[:500])


def test_per_vertex_arrays_and_float_attributes(box_obj):
    vertices, faces = lf.read_mesh(box_obj)
    height = vertices[:, 2].astype(np.float32)  # (N,): a float grid
    colour = (vertices + 0.5).astype(np.float32)  # (N, 3)
    grids = lf.mesh_to_sdf(vertices, faces, voxel_size=0.1, attribute={"height": height, "Cd": colour})
    assert isinstance(grids["height"], lf.Grid)
    assert grids["height"].active_voxel_count == grids["surface"].active_voxel_count
    coords, values = grids["height"].active_voxels()
    p = grids["height"].transform.index_to_world(coords)
    outside = np.any(np.abs(p) > 0.5, axis=1)
    np.testing.assert_allclose(values[outside], np.clip(p[outside, 2], -0.5, 0.5), atol=1e-5)
    with pytest.raises(lf.InvalidArgumentError, match="per-corner"):
        lf.mesh_to_sdf(vertices, faces, voxel_size=0.1, attribute={"bad": np.zeros((5, 2))})
    with pytest.raises(lf.InvalidArgumentError, match="dict"):
        lf.mesh_to_sdf(vertices, faces, voxel_size=0.1, attribute="Cd")
    with pytest.raises(lf.InvalidArgumentError, match="attribute transfer"):
        lf.mesh_to_sdf(vertices, faces, voxel_size=0.1, attribute={"Cd": colour}, expansion="sweep",
                       exterior_band=6)


def test_reference_matches_the_cli(cli, tmp_path, box, identical):
    ref = tmp_path / "ref.vdb"
    cli("mesh-to-sdf", "builtin:sphere", ref, "--voxel-size", 0.07, "--exterior-band", 4, "--quiet")
    out = tmp_path / "aligned.vdb"
    cli("mesh-to-sdf", "builtin:box", out, "--reference", ref, "--quiet")
    got = lf.mesh_to_sdf(*box, reference=ref, source="builtin:box")
    identical(got, lf.Grid.read(out))
    assert got.transform == lf.Grid.read(ref).transform
    with pytest.raises(lf.InvalidArgumentError, match="voxel_size"):
        lf.mesh_to_sdf(*box, reference=ref, voxel_size=0.1)
    with pytest.raises(lf.IoError):
        lf.mesh_to_sdf(*box, reference=tmp_path / "missing.vdb")
