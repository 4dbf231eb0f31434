"""foam_bridge stands alone: the solver plugin imports neither the trainer (jaxsimrl) nor JAX, and a user
of the plugin alone (SB3, RLlib) gets every public name from ``import foam_bridge``."""

from __future__ import annotations

import ast
import json
import subprocess
import sys
from pathlib import Path

import pytest

import foam_bridge

PACKAGE = Path(__file__).parent.parent / "foam_bridge"
MODULES = ["foam_bridge", "foam_bridge._batched", "foam_bridge._env", "foam_bridge._grid",
           "foam_bridge._gym_envs", "foam_bridge._backends.local", "foam_bridge._backends.ray_backend",
           "foam_bridge._template", "foam_bridge._user_case", "foam_bridge._export"]
HEAVY = ("jax", "jaxlib", "jaxsimrl")


def _python(code: str) -> str:
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                          timeout=120).stdout


def _modules() -> list[tuple[str, ast.Module]]:
    return [(str(path.relative_to(PACKAGE.parent)), ast.parse(path.read_text()))
            for path in sorted(PACKAGE.rglob("*.py"))]


@pytest.mark.parametrize("module", MODULES)
def test_import_pulls_in_neither_jax_nor_jaxsimrl(module):
    code = (f"import sys, {module}\n"
            f"print(sorted(m for m in sys.modules if m.split('.')[0] in {HEAVY!r}))")
    assert _python(code).strip() == "[]"


def test_no_foam_bridge_source_imports_jaxsimrl_or_jax_anywhere():
    """Every import statement, function-level ones included (a line scan would miss ``import jax as j``
    inside a function, or a ``from jax import ...`` in a try block)."""
    offenders = []
    for name, tree in _modules():
        for node in ast.walk(tree):
            targets = ([alias.name for alias in node.names] if isinstance(node, ast.Import) else
                       [node.module or ""] if isinstance(node, ast.ImportFrom) and node.level == 0 else [])
            offenders += [f"{name}:{node.lineno} {t}" for t in targets if t.split(".")[0] in HEAVY]
    assert offenders == []


def test_a_plugin_user_gets_every_public_name_from_the_package_without_jax():
    """In a fresh interpreter: ``import foam_bridge`` alone loads no submodule but registers the gymnasium
    id; every name of ``__all__`` then resolves (to the object its home module defines), still without
    JAX or jaxsimrl."""
    code = (
        "import sys, importlib, gymnasium, foam_bridge\n"
        "loaded = sorted(m for m in sys.modules if m.startswith('foam_bridge.'))\n"
        "registered = foam_bridge.ENV_ID in gymnasium.registry\n"
        "homes = {n: getattr(importlib.import_module(m), n) is getattr(foam_bridge, n)\n"
        "         for n, m in foam_bridge._EXPORTS.items()}\n"
        "from foam_bridge import *  # noqa\n"
        f"heavy = sorted(m for m in sys.modules if m.split('.')[0] in {HEAVY!r})\n"
        "import json; print(json.dumps([loaded, registered, homes, heavy, sorted(foam_bridge.__all__)]))\n")
    loaded, registered, homes, heavy, names = json.loads(_python(code))
    assert loaded == [] and registered
    assert all(homes.values()) and heavy == []
    assert names == sorted(["ENV_ID", *foam_bridge._EXPORTS, *foam_bridge._MODULES])
    for wanted in ("FoamEnvConfig", "K_OMEGA_ACTION", "TEST_CONVERGENCE", "FoamCaseEnv", "BatchedFoamEnv",
                   "RelaxationControlEnv", "RelaxationControlVecEnv", "make_backend", "run_grid",
                   "export_case", "case_defaults", "CaseError", "PoolLostError", "OpenFOAMNotFoundError"):
        assert wanted in names


def test_an_unknown_name_is_an_attribute_error():
    with pytest.raises(AttributeError, match="no attribute 'FoamEnv'"):
        foam_bridge.FoamEnv  # noqa: B018 (the protocol-form env is gone: FoamCaseEnv is the one)


def test_the_type_checking_imports_list_the_same_names_as_the_lazy_exports():
    (init,) = [tree for name, tree in _modules() if name == "foam_bridge/__init__.py"]
    (block,) = [node for node in init.body if isinstance(node, ast.If)
                and getattr(node.test, "id", "") == "TYPE_CHECKING"]
    seen = {alias.name: f"{node.module}" for node in block.body for alias in node.names}
    assert seen == {**foam_bridge._EXPORTS, **{name: "foam_bridge" for name in foam_bridge._MODULES}}


def test_every_all_names_what_its_module_defines():
    stale = []
    for name, tree in _modules():
        defined = set()
        declared: list[str] = []
        for node in tree.body:
            if isinstance(node, ast.FunctionDef | ast.ClassDef):
                defined.add(node.name)
            elif isinstance(node, ast.Assign | ast.AnnAssign):
                for target in node.targets if isinstance(node, ast.Assign) else [node.target]:
                    if getattr(target, "id", None) == "__all__":
                        declared = [ast.literal_eval(item) for item in node.value.elts]
                    defined.add(getattr(target, "id", ""))
            elif isinstance(node, ast.Import | ast.ImportFrom):
                defined |= {(alias.asname or alias.name).split(".")[0] for alias in node.names}
        if name == "foam_bridge/__init__.py":
            defined |= {*foam_bridge._EXPORTS, *foam_bridge._MODULES}
        stale += [f"{name}: {item}" for item in declared if item not in defined]
    assert stale == []


def test_no_module_of_the_package_imports_another_in_a_circle():
    graph: dict[str, set[str]] = {}
    for name, tree in _modules():
        module = name[:-3].replace("/", ".").removesuffix(".__init__")
        edges = graph.setdefault(module, set())
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("foam_bridge"):
                edges |= {f"{node.module}.{a.name}" if f"{node.module}.{a.name}" in _all_modules() else
                          node.module for a in node.names}
            elif isinstance(node, ast.Import):
                edges |= {a.name for a in node.names if a.name.startswith("foam_bridge")}
    graph["foam_bridge"] = set()  # the package's own imports are the lazy exports (TYPE_CHECKING)
    assert _cycles(graph) == []


def _all_modules() -> set[str]:
    return {str(p.relative_to(PACKAGE.parent))[:-3].replace("/", ".").removesuffix(".__init__")
            for p in PACKAGE.rglob("*.py")}


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    found, state = [], {}

    def visit(node: str, path: list[str]) -> None:
        state[node] = "open"
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == "open":
                found.append(path[path.index(nxt):] + [nxt] if nxt in path else [node, nxt])
            elif nxt not in state:
                visit(nxt, [*path, nxt])
        state[node] = "done"

    for start in sorted(graph):
        if start not in state:
            visit(start, [start])
    return found
