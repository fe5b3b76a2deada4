"""The package's layers as the code has them: every top-level module or subpackage sits
in a layer of the architecture page's diagram, no import points up the layers, no two
groups import each other (directly or round about), and the 0.5 names of the modules
that moved in 0.6 still import, as the very modules under their new names."""

from __future__ import annotations

import importlib
import importlib.util
import sys
import warnings
from pathlib import Path

import pytest

from cmarlcd import _moved

ROOT = Path(__file__).resolve().parents[1]
HOOK = ROOT / "docs" / "hooks" / "import_graph.py"


def _import_graph():
    spec = importlib.util.spec_from_file_location("import_graph", HOOK)
    module = importlib.util.module_from_spec(spec)
    sys.modules.setdefault("import_graph", module)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def graph():
    hook = _import_graph()
    return hook, hook.build_graph(ROOT / "src" / "cmarlcd")


def test_every_group_is_in_a_layer(graph) -> None:
    hook, found = graph
    assert not [title for title, _ in found.layers if title == hook.UNLAYERED]


def test_no_import_points_up_the_layers(graph) -> None:
    _, found = graph
    up = [
        (source, target, edge.imports[0])
        for (source, target), edge in found.edges.items()
        if found.points_up(edge)
    ]
    assert up == []


def test_no_two_groups_import_each_other(graph) -> None:
    _, found = graph
    imports: dict[str, set[str]] = {}
    for source, target in found.edges:
        if source != target:
            imports.setdefault(source, set()).add(target)

    def reaches(start: str, goal: str) -> bool:
        seen, todo = set(), [start]
        while todo:
            for nxt in imports.get(todo.pop(), ()):
                if nxt == goal:
                    return True
                if nxt not in seen:
                    seen.add(nxt)
                    todo.append(nxt)
        return False

    cycles = [(a, b) for a, targets in imports.items() for b in targets if reaches(b, a)]
    assert cycles == []


@pytest.mark.parametrize("old", sorted(_moved.MOVED))
def test_a_moved_module_still_imports_under_its_old_name_with_a_warning(old: str) -> None:
    new = importlib.import_module(_moved.MOVED[old])
    sys.modules.pop(old, None)
    with pytest.warns(DeprecationWarning, match=f"{old} moved to {_moved.MOVED[old]}"):
        module = importlib.import_module(old)
    assert module is new


def test_a_module_under_a_moved_package_is_the_same_module() -> None:
    from cmarlcd.sweeps.backends import ray_address

    sys.modules.pop("cmarlcd.backends.ray_address", None)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        from cmarlcd.backends import ray_address as old  # type: ignore[import-not-found]
    assert old is ray_address
    assert _moved.new_name("cmarlcd.backends.ray_address") == "cmarlcd.sweeps.backends.ray_address"
    assert _moved.new_name("cmarlcd.storehouse") is None
