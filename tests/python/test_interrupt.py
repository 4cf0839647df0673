# SPDX-License-Identifier: Apache-2.0
"""Progress and interruption: progress(stage, percent) callbacks; an exception raised by the
callback (KeyboardInterrupt or any other) stops the work and propagates as itself; Ctrl-C (SIGINT)
raises KeyboardInterrupt through the library's interrupter. Nothing here depends on timing: the
interruptions are raised from the callbacks, and the Ctrl-C test waits for the child's own report
before it sends the signal to a child that converts in an endless loop."""
import signal
import subprocess
import sys
import textwrap
import threading

import numpy as np
import pytest

import levelforge as lf


class Stop(Exception):
    pass


def test_progress_reports_stages_and_percentages(knot):
    calls = []
    lf.mesh_to_sdf(*knot, voxel_count=128, progress=lambda stage, pct: calls.append((stage, pct)))
    assert calls, "progress was never called"
    assert all(isinstance(s, str) and isinstance(p, int) and 0 <= p <= 100 for s, p in calls)
    assert calls[-1][1] == 100
    by_stage = {}
    for stage, pct in calls:
        by_stage.setdefault(stage, []).append(pct)
    assert "mesh to level set" in by_stage
    for pcts in by_stage.values():
        assert pcts == sorted(pcts), "percentages go down within a stage"
        assert len(pcts) == len(set(pcts)), "a percentage was reported twice"


def interrupting(exc, after=1):
    state = {"calls": 0}

    def progress(stage, pct):
        state["calls"] += 1
        if state["calls"] >= after:
            raise exc

    progress.state = state
    return progress


CONVERSIONS = {
    "mesh_to_sdf": lambda mesh, p: lf.mesh_to_sdf(*mesh, voxel_count=200, progress=p),
    "mesh_to_sdf/sweep": lambda mesh, p: lf.mesh_to_sdf(*mesh, voxel_count=96, exterior_band=20,
                                                        expansion="sweep", progress=p),
    "mesh_to_sdf/scan": lambda mesh, p: lf.mesh_to_sdf(*mesh, voxel_count=96, method="scan", progress=p),
    "mesh_to_adf": lambda mesh, p: lf.mesh_to_adf(*mesh, voxel_count=128, progress=p),
    "expand": lambda mesh, p: lf.expand(lf.mesh_to_sdf(*mesh, voxel_count=64), progress=p),
    "volume_to_sdf": lambda mesh, p: lf.volume_to_sdf(
        lf.mesh_to_sdf(*mesh, voxel_count=48, exterior_band=40, interior_band=40).to_dense(), iso=0.0,
        invert=True, subvoxel=True, progress=p),
}


@pytest.mark.parametrize("name", sorted(CONVERSIONS))
def test_keyboard_interrupt_from_the_callback_stops_the_work(knot, name):
    progress = interrupting(KeyboardInterrupt)
    with pytest.raises(KeyboardInterrupt):
        CONVERSIONS[name](knot, progress)
    assert progress.state["calls"] == 1, "the callback was called again after it raised"


@pytest.mark.parametrize("name", sorted(CONVERSIONS))
def test_any_exception_from_the_callback_propagates_as_itself(knot, name):
    error = Stop("user pressed cancel")
    with pytest.raises(Stop) as info:
        CONVERSIONS[name](knot, interrupting(error, after=2))
    assert info.value is error


def test_sigint_in_the_callback_raises_keyboard_interrupt(knot):
    def progress(stage, pct):
        signal.raise_signal(signal.SIGINT)

    with pytest.raises(KeyboardInterrupt):
        lf.mesh_to_sdf(*knot, voxel_count=128, progress=progress)


def test_work_goes_on_after_an_interruption(knot, identical):
    with pytest.raises(KeyboardInterrupt):
        lf.mesh_to_sdf(*knot, voxel_count=64, progress=interrupting(KeyboardInterrupt))
    identical(lf.mesh_to_sdf(*knot, voxel_count=64), lf.mesh_to_sdf(*knot, voxel_count=64))


def test_callbacks_and_interruption_in_a_worker_thread(knot):
    result = {}

    def work():
        calls = []
        try:
            lf.mesh_to_sdf(*knot, voxel_count=96, progress=lambda s, p: calls.append(p))
            result["calls"] = len(calls)
            lf.mesh_to_sdf(*knot, voxel_count=96, progress=interrupting(Stop("in a thread")))
        except Stop as e:
            result["stopped"] = str(e)

    t = threading.Thread(target=work)
    t.start()
    t.join()
    assert result["calls"] > 0
    assert result["stopped"] == "in a thread"


CHILD = textwrap.dedent("""
    import sys, threading, time
    sys.stdout.reconfigure(line_buffering=True)
    import levelforge as lf
    v, f = lf.read_mesh("builtin:torus-knot")
    if sys.argv[1] == "print":
        progress = print  # a builtin: no Python code runs in the callback
    else:
        progress = None   # a helper thread says when the main thread computes
        def report():
            time.sleep(0.5)
            print("started")
        threading.Thread(target=report, daemon=True).start()
    try:
        while True:  # ends only when interrupted
            lf.mesh_to_sdf(v, f, voxel_count=256, exterior_band=4, progress=progress)  # CALL
    except KeyboardInterrupt as e:
        print("KeyboardInterrupt at line", e.__traceback__.tb_lineno)
        sys.exit(3)
""")
CALL_LINE = next(n for n, line in enumerate(CHILD.splitlines(), 1) if "# CALL" in line)


@pytest.mark.parametrize("mode", ["print", "none"])
def test_ctrl_c_from_outside_raises_keyboard_interrupt(mode):
    """A real SIGINT, as a terminal sends for Ctrl-C, to a child that converts in an endless loop
    (so it cannot finish first), sent once the child reports that it computes: with a builtin as
    the progress callback, or with none (then the interrupter's PyErr_CheckSignals() is the only
    way out). The KeyboardInterrupt comes out of the mesh_to_sdf call."""
    child = subprocess.Popen([sys.executable, "-c", CHILD, mode], stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True)
    try:
        line = child.stdout.readline()
        assert line.strip(), child.stderr.read()
        child.send_signal(signal.SIGINT)
        out, err = child.communicate(timeout=300)  # a safety net only: the child never ends by itself
    finally:
        if child.poll() is None:
            child.kill()
            child.wait()
    assert "KeyboardInterrupt at line %d" % CALL_LINE in out, out[-2000:] + err
    assert child.returncode == 3, err
