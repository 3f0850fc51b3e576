"""The package structure the developers' guide and docs/ARCHITECTURE.md set: `drivers` and `firmware_sim` meet only
on the wire (neither imports the other; from the host package `rig` both take only its generic utilities), and no module imports itself back through others (no import circles, counting the imports
inside functions; those under ``if TYPE_CHECKING:`` are for the type checker only and not counted)."""
from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PACKAGES = ("rig", "drivers", "firmware_sim")
#: what `drivers` and `firmware_sim` may import from `rig` (docs/ARCHITECTURE.md)
GENERIC = {"rig", "rig.units", "rig.scene", "rig.blockbus", "rig.dbc", "rig.lazy"}


def _modules() -> dict[str, Path]:
    found = {}
    for package in PACKAGES:
        for path in (ROOT / package).rglob("*.py"):
            name = ".".join(path.relative_to(ROOT).with_suffix("").parts)
            found[name.removesuffix(".__init__")] = path
    return found


MODULES = _modules()


def _type_checking_only(node: ast.AST) -> bool:
    return isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test)


def _lazy_exports() -> dict[str, dict[str, str]]:
    """The packages that export lazily (rig.lazy): package → {name: the module it comes from} (read from the package,
    whose import is light by design)."""
    import importlib
    return {m: dict(importlib.import_module(m)._WHERE) for m, path in MODULES.items()
            if path.name == "__init__.py" and "exports(__name__, _WHERE)" in path.read_text(encoding="utf-8")}


def _imports(module: str) -> set[str]:
    """The project modules ``module`` imports (a name imported from a package counts as its submodule when it is
    one, as the module a lazily exporting package takes it from (rig.lazy), else as the package); a lazily exporting
    package imports the modules of its names (on first use)."""
    path = MODULES[module]
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    found: set[str] = set()

    def visit(node: ast.AST) -> None:
        if _type_checking_only(node):
            return
        if isinstance(node, ast.Import):
            found.update(a.name for a in node.names if a.name in MODULES)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                parts = package.split(".")
                base = ".".join(parts[: len(parts) - node.level + 1] + ([node.module] if node.module else []))
            else:
                base = node.module or ""
            subs = [f"{base}.{a.name}" for a in node.names]
            found.update(s for s in subs if s in MODULES)
            lazy = LAZY.get(base, {})
            found.update(lazy[a.name] for a in node.names if a.name in lazy)
            if base in MODULES and not all(s in MODULES or s.rpartition(".")[2] in lazy for s in subs):
                found.add(base)
        for child in ast.iter_child_nodes(node):
            visit(child)

    visit(ast.parse(path.read_text(encoding="utf-8")))
    return (found | set(LAZY.get(module, {}).values())) - {module}


LAZY = _lazy_exports()
GRAPH = {m: _imports(m) for m in MODULES}


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found = []
    for root in graph:
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = len(index)
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = len(index)
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph[child]))))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.append(member)
                    if member == node:
                        break
                if len(component) > 1:
                    found.append(sorted(component))
    return found


def test_the_import_graph_is_read():
    # through a lazily exporting package: the module it takes the name from, and the package imports its names' modules
    assert "drivers.can.host" in GRAPH["rig.runner.host"] and "rig.runner.session" in GRAPH["rig.runner"]
    assert "rig.analysis.report_blocks" in GRAPH["rig.analysis.report"]
    assert "drivers.can.timebase" in GRAPH["drivers.can.host"]
    # a function-level import counts, one for the type checker does not
    assert "rig.plants.cam_bar.mechanism" in GRAPH["rig.plants.cam_bar.scene_io"]


def test_the_cycle_finder_finds_a_cycle():
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert _cycles({"a": {"b"}, "b": set()}) == []


@pytest.mark.parametrize(("side", "other"), [("drivers", "firmware_sim"), ("firmware_sim", "drivers")])
def test_drivers_and_simulated_firmware_meet_only_on_the_wire(side, other):
    crossing = sorted(f"{m} imports {d}" for m, deps in GRAPH.items() if m.split(".")[0] == side
                      for d in deps if d.split(".")[0] == other)
    assert crossing == []


@pytest.mark.parametrize("side", ["drivers", "firmware_sim"])
def test_the_wire_sides_take_only_the_generic_utilities_from_the_host(side):
    taken = {d for m, deps in GRAPH.items() if m.split(".")[0] == side for d in deps if d.split(".")[0] == "rig"}
    assert taken <= GENERIC


def test_no_import_circles():
    assert _cycles(GRAPH) == []


def test_naming_the_errors_imports_neither_the_runner_nor_the_can_stack():
    """The command line catches the runner's and the recorder's errors for every command: naming them must not import
    the runner (scipy.signal, the simulated unit) or python-can (with asammdf and pandas), 1–1.5 s of every
    `rig report`, `rig summary`, `rig export-can` before (lazy package exports, rig.lazy)."""
    code = ("import sys; from rig.runner.errors import RunError; from rig.recorder.errors import RecordingError; "
            "from drivers.can.process_values import PROCESS_VALUES; import rig.recorder.schemas; "
            "print(sorted(m for m in ('rig.runner.session', 'can', 'scipy.signal', 'firmware_sim.digiforce') "
            "if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=ROOT)
    assert out.stdout.strip() == "[]"


def test_lazy_package_exports_resolve_and_refuse_unknown_names():
    import drivers.can
    import rig.recorder
    import rig.runner
    for package in (rig.runner, rig.recorder, drivers.can):
        for name in package.__all__:
            assert getattr(package, name).__name__ == name
        with pytest.raises(AttributeError, match="has no attribute 'nope'"):
            package.nope
