# SPDX-License-Identifier: Apache-2.0
"""Every ```python example of docs/python.md runs, in a scratch directory. The pyopenvdb example
needs python3-openvdb (skipped without it); the matplotlib example runs with a stand-in module
(accepting every call) when matplotlib is not installed."""
import importlib.util
import pathlib
import re
import sys
import types
from unittest import mock

import pytest

DOC = pathlib.Path(__file__).resolve().parents[2] / "docs" / "python.md"


def blocks():
    text = DOC.read_text()
    return [b for b in re.findall(r"```python\n(.*?)```", text, re.S)]


@pytest.mark.parametrize("index", range(len(blocks())))
def test_example_runs(index, tmp_path, monkeypatch):
    code = blocks()[index]
    monkeypatch.chdir(tmp_path)
    if "pyopenvdb" in code:
        pytest.importorskip("pyopenvdb", reason="python3-openvdb is not installed")
    if "matplotlib" in code and importlib.util.find_spec("matplotlib") is None:
        fake = types.ModuleType("matplotlib")
        fake.use = lambda *a, **k: None
        fake.pyplot = mock.MagicMock(name="matplotlib.pyplot")
        fake.pyplot.subplots.return_value = (mock.MagicMock(), mock.MagicMock())
        monkeypatch.setitem(sys.modules, "matplotlib", fake)
        monkeypatch.setitem(sys.modules, "matplotlib.pyplot", fake.pyplot)
    exec(compile(code, "%s[example %d]" % (DOC.name, index + 1), "exec"), {"__name__": "__doc_example__"})
