# SPDX-License-Identifier: Apache-2.0
"""device= of mesh_to_sdf and volume_to_sdf (docs/gpu.md): the Vulkan device's grid is the CPU's,
bit for bit; a bad name is an InvalidArgumentError; with every device hidden, "vulkan" raises and
"auto" runs on the CPU. Skips the device comparisons where no Vulkan device is usable."""
import os
import subprocess
import sys

import numpy as np
import pytest

import levelforge as lf


def have_vulkan(cli):
    return "float64:        yes" in cli("devices")


def test_bad_device_name_is_rejected(knot):
    with pytest.raises(lf.InvalidArgumentError, match="expected cpu, vulkan or auto"):
        lf.mesh_to_sdf(*knot, voxel_count=32, device="gpu")


def test_vulkan_and_cpu_give_the_same_grid(cli, knot, identical):
    if not have_vulkan(cli):
        pytest.skip("no usable Vulkan device (mesa-vulkan-drivers gives one on the CPU)")
    cpu = lf.mesh_to_sdf(*knot, voxel_count=48, device="cpu")
    gpu = lf.mesh_to_sdf(*knot, voxel_count=48, device="vulkan")
    identical(cpu, gpu)
    vol = np.fromfunction(lambda i, j, k: 12.0 - np.sqrt((i - 15.5) ** 2 + (j - 15.0) ** 2 + (k - 14.2) ** 2), (32, 30, 29))
    a = lf.volume_to_sdf(vol, iso=0.0, method="exact", device="cpu")
    b = lf.volume_to_sdf(vol, iso=0.0, method="exact", device="vulkan")
    identical(a, b)


def test_hidden_devices():
    code = ("import levelforge as lf\n"
            "m = lf.read_mesh('builtin:torus-knot')\n"
            "g = lf.mesh_to_sdf(*m, voxel_count=32, device='auto')\n"
            "print('auto', g.active_voxel_count)\n"
            "try:\n"
            "    lf.mesh_to_sdf(*m, voxel_count=32, device='vulkan')\n"
            "except lf.Error as e:\n"
            "    print('vulkan:', e)\n")
    env = dict(os.environ, LEVELFORGE_VULKAN_DEVICE="none")
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True).stdout
    assert "auto " in out
    assert "hidden" in out
