"""Where each plug-in came from: the module that registered an experiment, a learner, a
game or a deep learner, so that worker processes can register it too.

A sweep's worker processes are started fresh (``forkserver`` or ``spawn``, never forked
from the sweep's threads: :mod:`cmarlcd.sweeps.backends.local`), so they know what the
package registers and what their start-up imports: the script that started the sweep
(imported again, under the name ``__mp_main__``, as :mod:`multiprocessing` does) and
every module that registered a plug-in here, which a worker imports before its first
run. A plug-in registered at import time of a module (its top level) therefore reaches
the workers; one registered under ``if __name__ == "__main__":`` or inside a function
does not, and the sweep says so in one line before it computes anything.

The registering functions (:func:`cmarlcd.experiments.register`,
:func:`cmarlcd.registry.register_learner`, :func:`cmarlcd.registry.register_game`,
:func:`cmarlcd.training.deep_side.register_deep_learner`) call :func:`note`; this module
imports nothing of the package.
"""

from __future__ import annotations

import importlib
import importlib.util
import sys
from dataclasses import dataclass

#: The module that registered each plug-in, by (registry, name).
_ORIGINS: dict[tuple[str, str], str] = {}

#: The modules a worker already has as its start-up's main script.
MAIN_MODULES = ("__main__", "__mp_main__")


def note(registry: str, name: str, depth: int = 2) -> None:
    """Record that the caller's caller (``depth`` frames up) registered ``name`` in
    ``registry`` (``experiment``, ``learner``, ``game``, ``deep learner``)."""
    module = sys._getframe(depth).f_globals.get("__name__", "__main__")
    _ORIGINS[(registry, name)] = module


@dataclass(frozen=True)
class Registrations:
    """The plug-ins registered outside the package in a sweep's process: the modules that
    registered them (name and file, in order) and the entries a worker must know after
    importing those modules."""

    modules: tuple[tuple[str, str | None], ...] = ()
    entries: tuple[tuple[str, str], ...] = ()

    @classmethod
    def current(cls) -> Registrations:
        """This process's plug-ins (those the package registers are left out: a worker
        imports the package anyway)."""
        outside = {key: module for key, module in _ORIGINS.items() if not _ours(module)}
        modules: dict[str, str | None] = {}
        for module in outside.values():
            if module not in MAIN_MODULES and module not in modules:
                modules[module] = getattr(sys.modules.get(module), "__file__", None)
        return cls(tuple(modules.items()), tuple(outside))


def _ours(module: str) -> bool:
    return module == "cmarlcd" or module.startswith("cmarlcd.")


def import_modules(registrations: Registrations) -> list[str]:
    """Import every module that registered a plug-in (by name, or from its file where the
    name is not importable here, as for a test module); the errors, one line each."""
    errors = []
    for name, path in registrations.modules:
        if name in sys.modules:
            continue
        try:
            try:
                importlib.import_module(name)
            except ModuleNotFoundError as exc:
                if path is None or not name.startswith(str(exc.name)):
                    raise
                _import_file(name, path)
        except Exception as exc:  # reported as one line
            errors.append(f"importing {name} failed ({type(exc).__name__}: {exc})")
    return errors


def _import_file(name: str, path: str) -> None:
    spec = importlib.util.spec_from_file_location(name, path)
    if spec is None or spec.loader is None:
        raise ModuleNotFoundError(f"no module {name} at {path}", name=name)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    try:
        spec.loader.exec_module(module)
    except BaseException:
        del sys.modules[name]
        raise


def unknown(registrations: Registrations) -> list[tuple[str, str]]:
    """The entries of ``registrations`` this process has not registered (after
    :func:`import_modules`)."""
    known = {key for key in _ORIGINS}
    return [entry for entry in registrations.entries if entry not in known]


def missing_message(registrations: Registrations) -> str | None:
    """Import the plug-ins' modules, then one line saying which plug-ins a worker still
    lacks and how to reach it, or None when it has them all."""
    errors = import_modules(registrations)
    lost = unknown(registrations)
    if not errors and not lost:
        return None
    named = ", ".join(f"{registry} {name!r}" for registry, name in lost)
    text = f"a worker process does not know the {named} registered in this process" if lost else ""
    text = "; ".join([*errors, text] if text else errors)
    return (
        f"{text}: register plug-ins at the top level of a module (the workers import it, "
        "and the script that started the sweep, again), not under "
        "`if __name__ == '__main__':` or in a function, or run with one worker"
    )
