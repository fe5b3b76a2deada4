"""The modules that moved in 0.6 (the ``sweeps`` and ``reports`` packages), still
importable under their 0.5 names for one release: ``import cmarlcd.store`` gives
:mod:`cmarlcd.sweeps.store` itself (the same module object, so its state is shared),
with a :class:`DeprecationWarning` naming the new place. The old names go in 0.7.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import importlib.util
import sys
import warnings
from types import ModuleType

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
    "cmarlcd.training.replay": "cmarlcd.learners.replay",
}


def new_name(name: str) -> str | None:
    """Where module ``name`` lives now, or None if it did not move."""
    for old, new in MOVED.items():
        if name == old or name.startswith(old + "."):
            return new + name[len(old) :]
    return None


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
        warnings.warn(
            f"{spec.name} moved to {new} in cmarl-cd 0.6; the old name goes in 0.7",
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
