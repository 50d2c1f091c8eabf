"""The house: every benchmark script answers ``--help``, every docstring reference resolves."""

from __future__ import annotations

import ast
import importlib
import os
import pathlib
import re
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
BENCHMARKS = sorted((ROOT / "benchmarks").glob("*.py"))
#: source folder -> package of the installed library (pyproject.toml's package-dir)
PACKAGES = {
    "soiltrack": "soiltrack",
    "soilmodel": "soiltrack.soilmodel",
    "identify": "soiltrack.identify",
    "planning": "soiltrack.planning",
}
REF = re.compile(r":(mod|func|class):`([^`]+)`")
ABSOLUTE = ("soiltrack.", "numpy.", "casadi.", "scipy.", "matplotlib.", "dask.", "concurrent.")


@pytest.mark.slow
@pytest.mark.parametrize("script", BENCHMARKS, ids=[p.name for p in BENCHMARKS])
def test_every_benchmark_answers_help(script):
    """An import smoke test: ``--help`` imports the script and exits 0 without running it."""
    p = subprocess.run(
        [sys.executable, str(script), "--help"],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=str(ROOT / "benchmarks"),
    )
    assert p.returncode == 0 and "usage" in p.stdout.lower(), (p.stdout[-500:], p.stderr[-2000:])


def _modules() -> list[tuple[str, pathlib.Path]]:
    out = []
    for folder, pkg in PACKAGES.items():
        for f in sorted((ROOT / folder).rglob("*.py")):
            rel = f.relative_to(ROOT / folder).with_suffix("")
            parts = [p for p in rel.parts if p != "__init__"]
            out.append((".".join([pkg, *parts]), f))
    return out


def _lookup(parts: list[str]) -> bool:
    """Whether ``a.b.c`` names a module or an attribute (a dataclass field counts) of one."""
    for k in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:k]))
        except ImportError:
            continue
        for a in parts[k:]:
            fields = getattr(obj, "__dataclass_fields__", {}) if isinstance(obj, type) else {}
            if a in fields:
                return True
            if not hasattr(obj, a):
                return False
            obj = getattr(obj, a)
        return True
    return False


def _resolves(target: str, module: str, is_package: bool, cls: str | None) -> bool:
    t = target.lstrip("~").removesuffix("()")
    here = module.split(".") if is_package else module.split(".")[:-1]
    if t.startswith("."):  # relative, as Python's relative imports
        n = len(t) - len(t.lstrip("."))
        base = here[: len(here) - (n - 1)] if n > 1 else here
        return _lookup(base + t.lstrip(".").split("."))
    parts = t.split(".")
    if t.startswith(ABSOLUTE):
        return _lookup(parts)
    tries = [module.split(".") + parts, here + parts, ["soiltrack", *parts], parts]
    if cls:
        tries.insert(0, module.split(".") + [cls, *parts])
    return any(_lookup(c) for c in tries)


def stale_references() -> list[str]:
    """Every ``:mod:``/``:func:``/``:class:`` reference in a library docstring that names nothing."""
    bad = []
    for module, path in _modules():
        is_package = path.name == "__init__.py"
        tree = ast.parse(path.read_text())

        def visit(node, cls):
            if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
                for kind, target in REF.findall(ast.get_docstring(node, clean=False) or ""):
                    if not _resolves(target, module, is_package, cls):
                        bad.append(f"{os.path.relpath(path, ROOT)}:{getattr(node, 'lineno', 1)}: :{kind}:`{target}`")
            for child in ast.iter_child_nodes(node):
                visit(child, node.name if isinstance(node, ast.ClassDef) else cls)

        visit(tree, None)
    return bad


def test_every_docstring_reference_resolves():
    assert stale_references() == []


def test_the_reference_check_finds_a_stale_one():
    assert not _resolves(".drivelog_joint", "soiltrack.identify.drivelog.fit", False, None)
    assert _resolves(".joint", "soiltrack.identify.drivelog.fit", False, None)
    assert _resolves("~.result.FitResult", "soiltrack.identify.estimates.report", False, None)
    assert not _resolves("step_kernel", "soiltrack.identify.online.kernels", False, None)


#: The longest a library function may be (lines from ``def`` to its last line, docstring included).
MAX_FUNCTION_LINES = 120
#: Functions allowed over :data:`MAX_FUNCTION_LINES`, as ``folder/file.py:name``: none.
LONG_FUNCTIONS_ALLOWED: set[str] = set()


def long_functions(root: pathlib.Path = ROOT, limit: int = MAX_FUNCTION_LINES) -> list[str]:
    """``folder/file.py:name (lines)`` of every library function longer than ``limit`` lines."""
    out = []
    for folder in PACKAGES:
        for path in sorted((root / folder).rglob("*.py")):
            for node in ast.walk(ast.parse(path.read_text(), str(path))):
                if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                    n = node.end_lineno - node.lineno + 1
                    if n > limit:
                        out.append(f"{path.relative_to(root).as_posix()}:{node.name} ({n})")
    return out


def test_no_library_function_over_120_lines():
    long = [f for f in long_functions() if f.rsplit(" ", 1)[0] not in LONG_FUNCTIONS_ALLOWED]
    assert long == [], "split these into named steps: " + ", ".join(long)


def test_the_length_check_sees_a_long_function(tmp_path):
    (tmp_path / "identify").mkdir()
    body = "\n".join(f"    x{k} = {k}" for k in range(MAX_FUNCTION_LINES))
    (tmp_path / "identify" / "m.py").write_text(f"def short():\n    return 1\n\n\ndef long():\n{body}\n")
    assert long_functions(tmp_path) == [f"identify/m.py:long ({MAX_FUNCTION_LINES + 1})"]
