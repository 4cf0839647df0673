# SPDX-License-Identifier: Apache-2.0
"""The module's face: the type stubs match the module (names, parameters, defaults), every
public callable has a docstring, every CLI operator parameter is a keyword argument with the CLI's
default (read from `levelforge <operator> --help`), the exception hierarchy, and a clean import."""
import ast
import pathlib
import pydoc
import re
import subprocess
import sys

import pytest

import levelforge as lf

STUB = pathlib.Path(lf.__file__).with_name("__init__.pyi")


# ---------------------------------------------------------------- signatures

def split_top(text):
    """Splits at the commas not nested in brackets or quotes."""
    parts, depth, quote, cur = [], 0, None, ""
    for ch in text:
        if quote:
            quote = None if ch == quote else quote
        elif ch in "'\"":
            quote = ch
        elif ch in "([{":
            depth += 1
        elif ch in ")]}":
            depth -= 1
        elif ch == "," and depth == 0:
            parts.append(cur.strip())
            cur = ""
            continue
        cur += ch
    if cur.strip():
        parts.append(cur.strip())
    return parts


def literal(text):
    try:
        return ast.literal_eval(text)
    except ValueError:
        return text


def runtime_params(func):
    """[(name, default or NO)] from a pybind11 docstring signature, or inspect for Python code."""
    import inspect

    try:
        sig = inspect.signature(func)
        return [(p.name, p.default if p.default is not p.empty else NO) for p in sig.parameters.values()
                if p.kind is not p.VAR_KEYWORD and p.name != "self"]
    except (ValueError, TypeError):
        pass
    first = func.__doc__.splitlines()[0]
    inner = first[first.index("(") + 1:first.rindex(") ->")]
    out = []
    for part in split_top(inner):
        if part == "*":
            continue
        name, _, rest = part.partition(":")
        default = rest.partition("=")[2].strip()
        out.append((name.strip(), literal(default) if default else NO))
    return [(n, d) for n, d in out if n != "self"]


NO = object()


def stub_params(node):
    args = node.args
    positional = args.posonlyargs + args.args
    defaults = [NO] * (len(positional) - len(args.defaults)) + [ast.literal_eval(d) for d in args.defaults]
    out = list(zip([a.arg for a in positional], defaults))
    out += [(a.arg, ast.literal_eval(d) if d is not None else NO) for a, d in zip(args.kwonlyargs, args.kw_defaults)]
    return [(n, d) for n, d in out if n != "self"]


def stub_tree():
    return ast.parse(STUB.read_text())


def stub_functions():
    return {n.name: n for n in stub_tree().body if isinstance(n, ast.FunctionDef)}


def stub_classes():
    return {n.name: n for n in stub_tree().body if isinstance(n, ast.ClassDef)}


@pytest.mark.parametrize("name", sorted(stub_functions()))
def test_stub_functions_match_the_module(name):
    node = stub_functions()[name]
    assert hasattr(lf, name), "the stub names %s, the module has no such function" % name
    assert runtime_params(getattr(lf, name)) == stub_params(node)


def test_every_public_name_is_in_the_stub():
    stubbed = set(stub_functions()) | set(stub_classes())
    stubbed |= {t.id for n in stub_tree().body if isinstance(n, ast.AnnAssign) for t in [n.target]}
    public = {n for n in dir(lf) if not n.startswith("_")} - {"annotations"}
    modules = {n for n in public if type(getattr(lf, n)).__name__ == "module"}
    assert public - modules - stubbed == set()


@pytest.mark.parametrize("cls", ["Grid", "Transform", "Adf"])
def test_stub_methods_match_the_classes(cls):
    runtime = getattr(lf, cls)
    for node in stub_classes()[cls].body:
        if isinstance(node, ast.FunctionDef):
            attr = getattr(runtime, node.name, None)
            assert attr is not None, "%s.%s is in the stub only" % (cls, node.name)
            if node.name.startswith("__") or any(getattr(d, "id", "") in ("property", "overload")
                                                 for d in node.decorator_list):
                continue
            assert runtime_params(attr) == stub_params(node), "%s.%s" % (cls, node.name)
        elif isinstance(node, ast.AnnAssign):
            assert hasattr(runtime, node.target.id)
    public = {n for n in dir(runtime) if not n.startswith("_")}
    stubbed = {n.name for n in stub_classes()[cls].body if isinstance(n, ast.FunctionDef)}
    stubbed |= {n.target.id for n in stub_classes()[cls].body if isinstance(n, ast.AnnAssign)}
    assert public - stubbed == set(), "%s: not in the stub" % cls


def test_docstrings_and_help():
    for name in lf.__all__:
        obj = getattr(lf, name)
        assert obj.__doc__ and len(obj.__doc__.strip()) > 20, name
    for cls in (lf.Grid, lf.Transform, lf.Adf):
        for name in dir(cls):
            if not name.startswith("_"):
                assert getattr(cls, name).__doc__, "%s.%s has no docstring" % (cls.__name__, name)
    text = pydoc.render_doc(lf.mesh_to_sdf)
    assert "voxel_count: int = 256" in text and "exterior_band" in text and "progress" in text
    assert "Grid" in pydoc.render_doc(lf)


# ---------------------------------------------------------------- the CLI's defaults

OPERATORS = {
    # operator: (function, CLI parameters that are not keyword arguments (and why), renamed)
    # distributed, distributed-output, brick-size: one conversion across the ranks of mpirun
    # (docs/distributed.md); a Python call converts in its own process
    "mesh-to-sdf": ("mesh_to_sdf", {"quiet", "report", "distributed", "distributed-output", "brick-size"}, {}),
    "expand": ("expand", {"quiet", "grid-name"}, {}),  # grid-name picks the grid in a file
    "reshape": ("reshape", {"quiet", "grid-name"}, {}),  # grid-name picks the grid in a file
    "volume-to-sdf": ("volume_to_sdf", {"quiet", "vdb-grid", "raw-dims", "raw-type", "raw-spacing",
                                        "raw-header-bytes", "raw-big-endian"}, {}),  # read_volume's
    "mesh-to-adf": ("mesh_to_adf", {"quiet", "report"}, {"no-bounds": ("bounds", lambda v: not v)}),
    # band: None = the CLI's "not given" (the other input's band); grid picks the grid in a file
    "csg": ("csg", {"grid", "band"}, {}),
}


def cli_parameters(cli, op):
    """{name: default} of `levelforge <op> --help` (False for flags, None for no default)."""
    text = cli(op, "--help")
    section = text.split("Parameters:", 1)[1]
    section = re.split(r"\n\S", section, maxsplit=1)[0]  # up to the next heading (Examples:)
    params = {}
    for block in re.split(r"\n(?=  --)", section):
        m = re.match(r"\s*--([\w-]+)(?:\s+(\S+))?", block)
        if not m:
            continue
        takes_value = m.group(2) in ("INT", "FLOAT", "TEXT") or (m.group(2) or "").startswith("{")
        d = re.search(r"\[default\s+([^;\]]+)", block)
        if not takes_value:
            params[m.group(1)] = False
        else:
            params[m.group(1)] = " ".join(d.group(1).split()) if d else None
    return params


@pytest.mark.parametrize("op", sorted(OPERATORS))
def test_every_cli_parameter_is_a_keyword_with_the_cli_default(cli, op):
    fname, skipped, renamed = OPERATORS[op]
    py = dict(runtime_params(getattr(lf, fname)))
    for name, default in cli_parameters(cli, op).items():
        if name in skipped:
            continue
        pname, convert = renamed.get(name, (name.replace("-", "_"), lambda v: v))
        assert pname in py, "%s --%s has no keyword argument %s" % (op, name, pname)
        want = py[pname]
        if default is None:
            assert want is None, "--%s has no default but %s=%r" % (name, pname, want)
        elif default is False:
            assert want is convert(False), "flag --%s: %s=%r" % (name, pname, want)
        elif isinstance(want, (int, float)) and not isinstance(want, bool):
            assert float(default) == float(want), "--%s default %s, %s=%r" % (name, default, pname, want)
        else:
            assert default == want, "--%s default %s, %s=%r" % (name, default, pname, want)


# ---------------------------------------------------------------- errors, import

def test_exception_hierarchy():
    assert issubclass(lf.InvalidMeshError, ValueError) and issubclass(lf.InvalidMeshError, lf.Error)
    assert issubclass(lf.InvalidArgumentError, ValueError)
    assert issubclass(lf.InvalidVolumeError, ValueError)
    assert issubclass(lf.IoError, OSError) and issubclass(lf.IoError, lf.Error)
    assert issubclass(lf.ResourceLimitError, MemoryError)
    assert issubclass(lf.InterruptedError, lf.Error)
    assert lf.InvalidMeshError.__module__ == "levelforge"
    assert "InterruptedError" not in lf.__all__  # `from levelforge import *` keeps the builtin


@pytest.mark.parametrize("code", [
    "import levelforge",
    "import levelforge, pyopenvdb",
    "import pyopenvdb, levelforge",
])
def test_clean_import_in_a_fresh_interpreter(code):
    """Regression: importing levelforge before pyopenvdb crashed in openvdb::initialize() when the
    module let libopenvdb bind to its own hidden copies of OpenVDB's statics (python/CMakeLists.txt)."""
    if "pyopenvdb" in code:
        pytest.importorskip("pyopenvdb")
    run = code + "; v, f = levelforge.read_mesh('builtin:box'); g = levelforge.mesh_to_sdf(v, f, voxel_count=8);" \
                 " print(g.active_voxel_count)"
    r = subprocess.run([sys.executable, "-c", run], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert int(r.stdout) > 0


def test_read_volume_takes_the_cli_volume_input_parameters(cli):
    py = dict(runtime_params(lf.read_volume))
    cli_params = cli_parameters(cli, "volume-to-sdf")
    for name in ("vdb-grid", "raw-dims", "raw-type", "raw-spacing", "raw-header-bytes", "raw-big-endian"):
        pname = name.replace("-", "_")
        want, default = py[pname], cli_params[name]
        if default is None or default is False:
            assert want is default or (default is None and want is None), name
        elif name == "raw-spacing":
            assert tuple(float(x) for x in default.split(",")) == tuple(want)
        elif isinstance(want, int):
            assert int(default) == want, name
        else:
            assert default == want, name


def test_cmake_install_puts_a_working_package_in_site_packages(tmp_path):
    """`cmake --install` (into a DESTDIR) gives an importable package that needs neither the build
    tree nor LD_LIBRARY_PATH: the extension finds the installed liblevelforge.so through its
    $ORIGIN-relative RPATH."""
    import os
    import shutil

    build = os.environ.get("LEVELFORGE_BUILD_DIR")
    if not build or shutil.which("cmake") is None:
        pytest.skip("LEVELFORGE_BUILD_DIR (set by ctest) or cmake is missing")
    env = dict(os.environ, DESTDIR=str(tmp_path))
    for component in ("python", "Unspecified"):  # the package; the library it links
        r = subprocess.run(["cmake", "--install", build, "--component", component], capture_output=True,
                           text=True, env=env)
        assert r.returncode == 0, r.stdout + r.stderr
    cache = pathlib.Path(build, "CMakeCache.txt").read_text()
    site = re.search(r"^LEVELFORGE_PYTHON_INSTALL_DIR:\w+=(.*)$", cache, re.M).group(1)
    prefix = re.search(r"^CMAKE_INSTALL_PREFIX:PATH=(.*)$", cache, re.M).group(1)
    if not os.path.isabs(site):
        site = os.path.join(prefix, site)
    pkg = pathlib.Path(str(tmp_path) + site, "levelforge")
    assert {p.name for p in pkg.iterdir()} >= {"__init__.py", "__init__.pyi", "py.typed"}
    assert any(p.name.startswith("_levelforge") and p.suffix == ".so" for p in pkg.iterdir())
    run_env = {k: v for k, v in os.environ.items()
               if k not in ("PYTHONPATH", "LEVELFORGE_BUILD_DIR", "LD_LIBRARY_PATH")}
    run_env["PYTHONPATH"] = str(pkg.parent)
    code = ("import levelforge; assert levelforge.__file__.startswith(%r), levelforge.__file__; "
            "v, f = levelforge.read_mesh('builtin:box'); n = levelforge.mesh_to_sdf(v, f, voxel_count=8)"
            ".active_voxel_count; "
            "libs = [l.split()[-1] for l in open('/proc/self/maps') if 'liblevelforge.so' in l]; "
            "print(n, libs[0])" % str(tmp_path))
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=run_env,
                       cwd=str(tmp_path))
    assert r.returncode == 0, r.stderr
    count, lib = r.stdout.split()
    assert int(count) > 0
    assert lib.startswith(str(tmp_path)), "the installed module loaded %s, not the installed library" % lib
