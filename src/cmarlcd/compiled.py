"""How the package's compiled code is compiled: kernels, and loops specialised per pair.

**Kernels** (:func:`kernel`) are the compiled functions games and learners hand to the
loops: ``@njit``, cached on disk, allocation-free and compiled without numba's reference
counting (``_nrt=False``). Kernels take tuples of arrays (a game's state arrays, a
learner's tables), and numba counts a reference each time a function takes an array out
of a tuple: atomic operations that cost about a tenth of a DSN step and a fifth of a
repeated game when every kernel call pays them. A function that needs no memory of its
own needs no reference counting; one that allocates (``np.zeros`` and the like) fails to
compile as a kernel and must use plain ``@njit``.

**Loops** are written once, as plain Python functions (*templates*) that call the game's
kernels through a module-level name ``game`` and the learner's through ``learner`` (both
NamedTuples of compiled functions, :class:`Unbound` until then). :func:`specialise`
compiles a copy of a template with those names bound to one game's and one learner's
functions: numba then compiles one specialisation per pair, calling the kernels directly.

Why not pass the functions as arguments? Numba accepts that, but a function compiled for
function-typed arguments is never found in its on-disk cache by a new process (the
argument types name the functions by per-process identity; numba issues #2956 and
#6264), so every command would spend about 2 s recompiling each loop. A template copy
bound by name has ordinary argument types, and is cached under a name built from the
bound functions and a stamp of their source files, so editing a game or learner
recompiles its loops rather than reusing stale ones.
"""

from __future__ import annotations

import functools
import hashlib
import inspect
import sys
import types
from collections.abc import Callable
from pathlib import Path
from typing import Any

from numba import njit


def kernel(function: Callable) -> Any:
    """Compile ``function`` as a kernel (see the module docstring)."""
    return njit(cache=True, _nrt=False)(function)


def shared_kernel(function: Callable) -> Any:
    """Compile ``function`` as a kernel that plug-ins share (the no-op hooks, and the
    match loop's helpers that take a side's tables), *not* cached on disk.

    Numba keeps every compiled signature of a function in one on-disk index. A kernel
    that a plug-in calls with its own types (its tables, a NamedTuple of its own module)
    would record those types there, and a later process that cannot import that module
    (a script's ``__main__``, a test file) would fail to read the index: every caller of
    the kernel would then fail to compile. These kernels are trivial, so compiling them
    in each process costs nothing; the loops that call them are still cached.
    """
    return njit(cache=False, _nrt=False)(function)


class Unbound:
    """The value of a template's ``game`` / ``learner`` name before specialisation."""

    def __init__(self, name: str) -> None:
        self.name = name

    def __getattr__(self, attribute: str) -> Any:
        raise RuntimeError(
            f"{self.name}.{attribute}: this loop is a template; compile it for a game and a "
            "learner with cmarlcd.compiled.specialise"
        )


def specialise(template: Callable, **bound: tuple) -> Any:
    """``template`` compiled with each module-level name in ``bound`` bound to the given
    NamedTuple of compiled functions (e.g. ``game=spec.kernels, learner=config.kernels``).

    The result is a numba dispatcher, cached on disk and memoised in this process.
    """
    return _specialise(template, tuple(sorted(bound.items())))


def specialise_kernel(template: Callable, **bound: tuple) -> Any:
    """:func:`specialise` for a template that is itself a kernel (it allocates nothing:
    a side's ``enter`` or ``act``, which a loop calls at every step).

    When every bound function is a kernel (compiled without reference counting, as the
    package's games and learners are), the template is compiled like one: taking arrays
    out of a side's tuple then costs no atomic operations (a quarter of a DSN step). A
    plug-in function compiled with plain ``@njit`` may allocate, so a template that calls
    one keeps reference counting: numba would otherwise compile the plug-in's function
    under the template's flags, where an allocation does not compile.
    """
    functions = [f for _, group in bound.items() for f in group]
    nrt = not all(is_kernel(f) for f in functions)
    return _specialise(template, tuple(sorted(bound.items())), nrt=nrt)


def is_kernel(function: Any) -> bool:
    """Whether ``function`` is compiled without reference counting (:func:`kernel`,
    :func:`shared_kernel`)."""
    options = getattr(function, "targetoptions", None)
    return options is not None and options.get("_nrt") is False


@functools.cache
def _specialise(template: Callable, key: tuple, nrt: bool = True) -> Any:
    scope = dict(template.__globals__, **dict(key))
    function = types.FunctionType(
        template.__code__, scope, template.__name__, template.__defaults__, template.__closure__
    )
    function.__qualname__ = f"{template.__qualname__}[{_tag(key)}]"
    function.__module__ = template.__module__
    function.__doc__ = template.__doc__
    return njit(cache=True, _nrt=nrt)(function)


def _tag(key: tuple) -> str:
    """A stable, file-name-safe name for one binding: the functions' names and a digest of
    their qualified names and source files' stamps (size and modification time)."""
    names, stamps = [], []
    for _, functions in key:
        for function in functions:
            py_func = getattr(function, "py_func", function)
            names.append(py_func.__name__)
            stamps.append(f"{py_func.__module__}.{py_func.__qualname__}")
            stamps.append(_source_stamp(py_func.__module__))
    digest = hashlib.sha256("\n".join(stamps).encode()).hexdigest()[:12]
    return f"{'-'.join(dict.fromkeys(names))[:60]}-{digest}"


@functools.cache
def _source_stamp(module_name: str) -> str:
    """Size and mtime of a module's source file and of every file of its top-level
    package (compiled callees may live in sibling modules)."""
    module = sys.modules.get(module_name)
    source = inspect.getsourcefile(module) if module is not None else None
    if source is None:
        return module_name
    top = sys.modules.get(module_name.split(".")[0])
    files = {Path(source)}
    package_file = getattr(top, "__file__", None)
    if package_file and Path(package_file).name == "__init__.py":
        files |= set(Path(package_file).parent.rglob("*.py"))
    stats = ((str(f), f.stat()) for f in sorted(files) if f.exists())
    return ";".join(f"{name}:{st.st_size}:{st.st_mtime_ns}" for name, st in stats)
