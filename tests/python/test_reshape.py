# SPDX-License-Identifier: Apache-2.0
"""reshape: bit for bit the CLI's `levelforge reshape` on the same input, and its errors."""
import pytest

import levelforge as lf


@pytest.mark.parametrize("cli_args, kwargs", [
    ([], {}),
    (["--op", "erode", "--offset", 2], dict(op="erode", offset=2)),
    (["--op", "open", "--offset", 1.5], dict(op="open", offset=1.5)),
    (["--op", "close", "--offset", 0.05, "--world-units"], dict(op="close", offset=0.05, world_units=True)),
], ids=["defaults", "erode", "open", "close-world"])
def test_reshape_bit_for_bit_with_cli(cli, tmp_path, knot, identical, cli_args, kwargs):
    band = lf.mesh_to_sdf(*knot, voxel_count=48)
    band.write(tmp_path / "band.vdb")
    cli("reshape", tmp_path / "band.vdb", tmp_path / "out.vdb", "--quiet", *cli_args)
    expected = lf.Grid.read(tmp_path / "out.vdb")
    got = lf.reshape(band, **kwargs)
    identical(got, expected)


def test_reshape_moves_the_surface_and_refuses_bad_input(knot):
    band = lf.mesh_to_sdf(*knot, voxel_count=48)
    grown = lf.reshape(band, op="dilate", offset=2)
    assert grown.active_voxel_count > 0
    inside = lambda g: int((g.active_voxels()[1] < 0).sum())
    assert inside(grown) > inside(band)
    assert inside(lf.reshape(band, op="erode", offset=2)) < inside(band)
    with pytest.raises(lf.InvalidArgumentError):
        lf.reshape(band, op="grow")
    with pytest.raises(lf.InvalidArgumentError):
        lf.reshape(band, offset=-1)
