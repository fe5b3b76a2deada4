"""The modules that moved, still importable under their old names for one release:
``import cmarlcd.store`` gives :mod:`cmarlcd.sweeps.store` itself (the same module
object, so its state is shared), with a :class:`DeprecationWarning` naming the new place.

0.6 moved the ``sweeps`` and ``reports`` packages (the old names go in 0.7); 0.7 grouped
the learners by kind, ``cmarlcd.learners.coordination`` becoming
``cmarlcd.learners.tabular.coordination`` and ``cmarlcd.learners.fused_step``
``cmarlcd.learners.deep.fused.step`` (the old names go in 0.8). A package that took an
old module's own name (``cmarlcd.learners.tabular``, once the protocol's module) hands
out that module's names through :func:`moved_attribute`.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import importlib.util
import sys
import warnings
from types import ModuleType

#: The release each old name moved in; it goes in the next (the old name warns until then).
SINCE_0_6 = "0.6"
SINCE_0_7 = "0.7"
MISSING = object()

_LEARNERS_0_7 = {
    **{
        f"cmarlcd.learners.{name}": f"cmarlcd.learners.tabular.{name}"
        for name in (
            "coordination",
            "automata",
            "independent",
            "q_learning",
            "distributed_q",
            "fmq",
            "hysteretic",
            "joint_action",
            "lenient",
        )
    },
    "cmarlcd.learners.deep_config": "cmarlcd.learners.deep.config",
    "cmarlcd.learners.replay": "cmarlcd.learners.deep.replay",
    "cmarlcd.learners.value_decomposition": "cmarlcd.learners.deep.value_decomposition",
    "cmarlcd.learners.deep_agent": "cmarlcd.learners.deep.agent",
    "cmarlcd.learners.deep_coordination": "cmarlcd.learners.deep.coordination",
    "cmarlcd.learners.degree_memory": "cmarlcd.learners.deep.degree_memory",
    "cmarlcd.learners.degree_model": "cmarlcd.learners.deep.degree_model",
    "cmarlcd.learners.degree_agent": "cmarlcd.learners.deep.degree_agent",
    "cmarlcd.learners.fused_step": "cmarlcd.learners.deep.fused.step",
    "cmarlcd.learners.fused_kernels": "cmarlcd.learners.deep.fused.kernels",
    "cmarlcd.learners.fused_degree_kernels": "cmarlcd.learners.deep.fused.degree_kernels",
    "cmarlcd.learners.fused_layers": "cmarlcd.learners.deep.fused.layers",
    "cmarlcd.learners.fused_mixers": "cmarlcd.learners.deep.fused.mixers",
}

#: Old module (and everything under it) -> where it lives now.
MOVED = {
    "cmarlcd.backends": "cmarlcd.sweeps.backends",
    "cmarlcd.claims": "cmarlcd.sweeps.claims",
    "cmarlcd.runner": "cmarlcd.sweeps.runner",
    "cmarlcd.store": "cmarlcd.sweeps.store",
    "cmarlcd.report": "cmarlcd.reports",
    "cmarlcd.section": "cmarlcd.reports.section",
    "cmarlcd.document": "cmarlcd.reports.document",
    "cmarlcd.render": "cmarlcd.reports.render",
    "cmarlcd.figures": "cmarlcd.reports.figures",
    "cmarlcd.compare_report": "cmarlcd.reports.compare",
    "cmarlcd.readings_report": "cmarlcd.reports.readings",
    "cmarlcd.scaling_report": "cmarlcd.reports.scaling",
    "cmarlcd.environment_report": "cmarlcd.reports.environment",
    "cmarlcd.training.replay": "cmarlcd.learners.deep.replay",
    **_LEARNERS_0_7,
}
#: The release an old name moved in (0.6 unless named here).
MOVED_IN = dict.fromkeys(_LEARNERS_0_7, SINCE_0_7)


def new_name(name: str) -> str | None:
    """Where module ``name`` lives now, or None if it did not move."""
    old = _old_key(name)
    return None if old is None else MOVED[old] + name[len(old) :]


def moved_in(old: str) -> str:
    """The release in which module ``old`` (a key of :data:`MOVED`) moved."""
    return MOVED_IN.get(old, SINCE_0_6)


def goes_in(since: str) -> str:
    """The release after ``since`` ("0.6" -> "0.7"), when a name moved in it goes."""
    major, minor = since.split(".")
    return f"{major}.{int(minor) + 1}"


def moved_attribute(package: str, module: str, name: str, since: str):
    """``package.name``, a name of ``module`` that ``package`` held before release
    ``since`` (``package`` was that module then): the value, with a
    :class:`DeprecationWarning`; for a module's ``__getattr__``."""
    value = getattr(importlib.import_module(module), name, MISSING)
    # a class or function imported into ``module`` from elsewhere is not one of its names
    imported = callable(value) and getattr(value, "__module__", module) != module
    if name.startswith("_") or value is MISSING or isinstance(value, ModuleType) or imported:
        raise AttributeError(f"module {package!r} has no attribute {name!r}")
    warnings.warn(
        f"{package}.{name} moved to {module}.{name} in cmarl-cd {since}; "
        f"the old name goes in {goes_in(since)}",
        DeprecationWarning,
        stacklevel=3,
    )
    return value


def _old_key(name: str) -> str | None:
    """The key of :data:`MOVED` that module ``name`` falls under (None: it did not move)."""
    return next((old for old in MOVED if name == old or name.startswith(old + ".")), None)


class MovedFinder(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Finds an old name and hands back the module under its new one (whose own
    ``__spec__`` is put back once the import system has set the old name's)."""

    def __init__(self) -> None:
        self.specs: dict[str, importlib.machinery.ModuleSpec | None] = {}

    def find_spec(self, fullname: str, path: object = None, target: object = None):
        new = new_name(fullname)
        if new is None or importlib.util.find_spec(new) is None:
            return None  # not moved, or nothing there under the new name either
        package = importlib.util.find_spec(new).submodule_search_locations is not None
        return importlib.machinery.ModuleSpec(fullname, self, is_package=package)

    def create_module(self, spec: importlib.machinery.ModuleSpec) -> ModuleType:
        new = new_name(spec.name)
        since = moved_in(_old_key(spec.name) or spec.name)
        warnings.warn(
            f"{spec.name} moved to {new} in cmarl-cd {since}; the old name goes in "
            f"{goes_in(since)}",
            DeprecationWarning,
            stacklevel=2,
        )
        module = importlib.import_module(new)  # type: ignore[arg-type]
        self.specs[spec.name] = module.__spec__
        return module

    def exec_module(self, module: ModuleType) -> None:
        """Nothing to run (the module is loaded under its new name); its own spec back."""
        module.__spec__ = self.specs.pop(module.__spec__.name, module.__spec__)


def install() -> None:
    """Put the finder first on the import path (once)."""
    if not any(isinstance(finder, MovedFinder) for finder in sys.meta_path):
        sys.meta_path.insert(0, MovedFinder())
