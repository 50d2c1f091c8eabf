"""The package's import graph, read from the source: no cycle, no private name imported across modules.

Every ``import`` counts, including those inside functions (a late import hides a cycle, it does
not remove it). A name starting with one underscore is private to its module.
"""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
FOLDERS = {
    "soiltrack": "soiltrack",
    "soilmodel": "soiltrack.soilmodel",
    "identify": "soiltrack.identify",
    "planning": "soiltrack.planning",
}


def _modules() -> dict[str, tuple[Path, bool]]:
    mods = {}
    for folder, pkg in FOLDERS.items():
        for path in sorted((ROOT / folder).rglob("*.py")):
            parts = list(path.relative_to(ROOT / folder).with_suffix("").parts)
            is_pkg = parts[-1] == "__init__"
            if is_pkg:
                parts = parts[:-1]
            mods[".".join([pkg, *parts])] = (path, is_pkg)
    return mods


def _imports(name: str, path: Path, is_pkg: bool, mods) -> list[tuple[str, str | None, int]]:
    """(imported module, imported name or None, line) for each project import of one module."""
    out = []
    base = name.split(".") if is_pkg else name.split(".")[:-1]
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            out += [(a.name, None, node.lineno) for a in node.names if a.name.split(".")[0] == "soiltrack"]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                root = base[: len(base) - node.level + 1]
                target = ".".join(root + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            if target.split(".")[0] != "soiltrack":
                continue
            for a in node.names:
                sub = f"{target}.{a.name}"
                if sub in mods:  # `from pkg import module`
                    out.append((sub, None, node.lineno))
                else:
                    out.append((target, a.name, node.lineno))
    return out


def _graph():
    mods = _modules()
    edges: dict[str, set[str]] = {m: set() for m in mods}
    private = []
    for m, (path, is_pkg) in mods.items():
        for target, nm, line in _imports(m, path, is_pkg, mods):
            if target in mods and target != m:
                edges[m].add(target)
            if nm is not None and nm.startswith("_") and not nm.startswith("__") and target != m:
                private.append(f"{path.relative_to(ROOT)}:{line} imports {nm} from {target}")
    return edges, private


def _cycles(edges: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out = []
    counter = [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in edges[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in edges:
        if v not in index:
            visit(v)
    return out


def _without_packages(edges):
    """Module graph without the edges into package ``__init__`` modules (re-export faces)."""
    mods = _modules()
    return {m: {t for t in ts if not mods[t][1]} for m, ts in edges.items()}


def test_no_import_cycle_between_modules():
    edges, _ = _graph()
    assert _cycles(_without_packages(edges)) == []


def test_no_private_name_imported_from_another_module():
    _, private = _graph()
    assert private == []


def test_layers_flow_one_way():
    """soilmodel <- identify <- planning <- the command-line face."""
    edges, _ = _graph()
    rank = {"soiltrack.soilmodel": 0, "soiltrack.identify": 1, "soiltrack.planning": 2}

    def layer(m):
        for k, r in rank.items():
            if m == k or m.startswith(k + "."):
                return r
        return 3

    bad = [(m, t) for m, ts in edges.items() for t in ts if layer(t) > layer(m)]
    assert bad == []


def test_checker_sees_a_cycle_and_a_private_import():
    """The checks above can fail: a hand-made cycle is found."""
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": set()}) == [["a", "b", "c"]]


#: The data-kind packages of identify: each fits one kind of data (and may use the record), never the reverse.
DATA_KINDS = ("sweep", "drivelog", "wheel", "soiltests", "online", "turning")
#: The record and its statistics, and the outcome rules: they know no data kind.
KIND_FREE = ("soiltrack.identify.estimates", "soiltrack.identify.outcome")


def _inside(module: str, prefix: str) -> bool:
    return module == prefix or module.startswith(prefix + ".")


def kind_imports(edges) -> list[str]:
    """Imports of a data-kind package by the record, its statistics or the outcome rules."""
    kinds = [f"soiltrack.identify.{k}" for k in DATA_KINDS]
    return sorted(
        f"{m} imports {t}"
        for m, ts in edges.items()
        if any(_inside(m, p) for p in KIND_FREE)
        for t in ts
        if any(_inside(t, k) for k in kinds)
    )


def _public_names(path: Path) -> set[str] | None:
    """A package ``__init__``'s ``__all__`` (None when it has none)."""
    for node in ast.parse(path.read_text()).body:
        if isinstance(node, ast.Assign) and any(getattr(t, "id", None) == "__all__" for t in node.targets):
            return {ast.literal_eval(e) for e in node.value.elts}  # type: ignore[attr-defined]
    return None


def planning_internals() -> list[str]:
    """Imports by planning of identify's internals: an internal module, or a name outside a package's __all__."""
    mods = _modules()
    bad = []
    for m, (path, is_pkg) in mods.items():
        if not _inside(m, "soiltrack.planning"):
            continue
        for target, name, line in _imports(m, path, is_pkg, mods):
            if not _inside(target, "soiltrack.identify"):
                continue
            where = f"{path.relative_to(ROOT)}:{line}"
            if target not in mods or not mods[target][1]:
                bad.append(f"{where} imports the internal module {target}")
                continue
            public = _public_names(mods[target][0])
            if name is None or public is None or name not in public:
                bad.append(f"{where} imports {name or 'the package'} from {target}, not in its __all__")
    return sorted(bad)


def test_the_record_and_the_outcome_import_no_data_kind():
    """identify/estimates and identify/outcome.py: the one record and its rules know no data kind."""
    edges, _ = _graph()
    assert kind_imports(edges) == []


def test_planning_imports_only_identify_public_surfaces():
    """planning takes from identify only what a package's __init__ lists in its __all__."""
    assert planning_internals() == []


def test_the_layer_checks_can_fail():
    edges = {"soiltrack.identify.estimates.result": {"soiltrack.identify.sweep.model"}}
    assert kind_imports(edges) == ["soiltrack.identify.estimates.result imports soiltrack.identify.sweep.model"]
    assert kind_imports({"soiltrack.identify.sweep.model": {"soiltrack.identify.estimates.result"}}) == []
