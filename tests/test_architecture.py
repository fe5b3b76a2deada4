"""The package's layers as the code has them: every top-level module or subpackage sits
in a layer of the architecture page's diagram, no import points up the layers, no two
groups import each other (directly or round about), the learners are grouped by kind
(tabular and deep apart, the fused step and the shared rules below them), and the old
names of the modules that moved in 0.6 and 0.7 still import, as the very modules under
their new names."""

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


def test_the_learners_are_grouped_by_kind_and_import_one_way(graph) -> None:
    _, found = graph
    kinds = {"learners/tabular", "learners/deep", "learners/deep/fused", "learners/shared"}
    assert kinds <= set(found.groups)
    assert "learners/tabular/coordination.py" in found.groups["learners/tabular"].modules
    assert "learners/deep/fused/step.py" in found.groups["learners/deep/fused"].modules
    assert found.groups["learners/shared"].modules == [
        "learners/degree_rules.py",
        "learners/max_return.py",
        "learners/policy.py",
    ]
    learner_edges = {(s, t) for s, t in found.edges if s in kinds and t in kinds}
    assert ("learners/tabular", "learners/deep") not in learner_edges
    assert ("learners/deep", "learners/tabular") not in learner_edges
    assert not [(s, t) for s, t in learner_edges if s == "learners/deep/fused"]
    assert not [(s, t) for s, t in learner_edges if s == "learners/shared"]
    assert ("learners/deep", "learners/deep/fused") in learner_edges


def test_the_moved_learners_say_when_their_old_names_go() -> None:
    assert _moved.moved_in("cmarlcd.learners.fused_step") == "0.7"
    assert _moved.moved_in("cmarlcd.store") == "0.6"
    assert _moved.goes_in("0.7") == "0.8"
    sys.modules.pop("cmarlcd.learners.deep_config", None)
    with pytest.warns(DeprecationWarning, match="in cmarl-cd 0.7; the old name goes in 0.8"):
        importlib.import_module("cmarlcd.learners.deep_config")


def test_the_protocols_names_still_resolve_on_the_package_that_took_its_name() -> None:
    """``cmarlcd.learners.tabular`` was the protocol's module until 0.7."""
    import cmarlcd.learners.tabular as package
    from cmarlcd.learners.tabular import protocol

    with pytest.warns(DeprecationWarning, match="tabular.protocol.TabularConfig in cmarl-cd 0.7"):
        assert package.TabularConfig is protocol.TabularConfig
    with pytest.warns(DeprecationWarning, match="no_step_update"):
        assert package.no_step_update is protocol.no_step_update  # a compiled kernel
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for imported_there in ("np", "math", "require", "nothing_at_all", "_private"):
            with pytest.raises(AttributeError, match=imported_there):
                getattr(package, imported_there)


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
