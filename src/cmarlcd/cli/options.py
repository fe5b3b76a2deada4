"""Parsing and checking what the user typed: option types, value parsers, clean failures.

Every failure a user can cause ends in one line, ``error: --option: what is wrong``, and
exit status 2, before anything is computed or written; a disk that fills up or turns
read-only while results are written ends the same way, keeping what was stored before.
"""

from __future__ import annotations

import dataclasses
import errno
import functools
import os
import sys
import tempfile
from collections.abc import Callable
from decimal import Decimal, InvalidOperation
from pathlib import Path
from typing import Annotated, Any, TypeVar

import typer

from cmarlcd.errors import BackendLost, ConfigError, require
from cmarlcd.games.battlefield import Unit
from cmarlcd.learners.deep.designs import DESIGNS_BY_LEARNER
from cmarlcd.sweeps.runner import RunFailed, SweepInterrupted
from cmarlcd.sweeps.store import check_output_directory, check_store

F = TypeVar("F", bound=Callable[..., Any])

DEFAULT_FIGURES = Path("results") / "figures"
#: The write failures a user's disk can cause, reported in one line.
WRITE_ERRORS = {errno.ENOSPC, errno.EDQUOT, errno.EACCES, errno.EPERM, errno.EROFS}

StoreOption = Annotated[Path, typer.Option("--store", help="SQLite results store.")]
FiguresOption = Annotated[Path, typer.Option("--figures", help="Folder for PNG figures.")]
WorkersOption = Annotated[
    int | None,
    typer.Option("--workers", help="Worker processes [default: all cores].", show_default=False),
]
JsonOption = Annotated[
    bool, typer.Option("--json", help="Print one JSON document to stdout.", show_default=False)
]
ProgressOption = Annotated[
    bool, typer.Option("--progress/--no-progress", help="Progress bar (on stderr).")
]
SeedOption = Annotated[int, typer.Option(help="Root seed.")]
BackendOption = Annotated[
    str,
    typer.Option(
        "--backend",
        help="Where runs are computed: process (local worker processes) or ray (a Ray "
        "cluster; pip install 'cmarl-cd[ray]').",
    ),
]
AddressOption = Annotated[
    str | None,
    typer.Option(
        "--address",
        help="Address of a running Ray cluster, e.g. ray://head:10001 [default: start a "
        "local Ray on this machine].",
        show_default=False,
    ),
]


GpuTasksOption = Annotated[
    int,
    typer.Option(
        "--gpu-tasks",
        help="With a GPU: deep tasks that share it at a time (local worker processes on "
        "the card, at most all workers but one; on Ray each one's share of a GPU).",
    ),
]
SavePoliciesOption = Annotated[
    Path | None,
    typer.Option(
        "--save-policies",
        help="Keep each run's final greedy policy in this folder (.npz tables, .safetensors "
        "networks; runs found in the store keep none); cmarl-cd evaluate --policy plays one.",
        show_default=False,
    ),
]
LogDirOption = Annotated[
    Path | None,
    typer.Option(
        "--log-dir",
        help="Write each run's live curves as it computes (TensorBoard event files and a "
        "CSV, a folder a run; pip install 'cmarl-cd[logs]'): tensorboard --logdir DIR.",
        show_default=False,
    ),
]
DeviceOption = Annotated[
    str,
    typer.Option(
        "--device",
        help="Where the deep learners compute: cpu, cuda, cuda:N or auto (a GPU where torch "
        "sees one); not part of a run's identity or seeds.",
    ),
]


def leave_now(message: str) -> None:
    """Print ``error: message`` and end the process at once, exit status 2 (a backend
    that is gone may hold threads that never end; the store's committed runs are safe)."""
    print(f"error: {message}", file=sys.stderr)
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(2)


def traceback_note(details: str) -> str:
    """Where a failed run's traceback was written (a new file in the temporary folder),
    as the end of its one line."""
    if not details:
        return ""
    try:
        with tempfile.NamedTemporaryFile(
            "w", prefix="cmarl-cd-failure-", suffix=".txt", delete=False
        ) as file:
            file.write(details)
    except OSError:
        return ""
    return f" (traceback: {file.name})"


def fails_cleanly(command: F) -> F:
    """Turn bad input, Ctrl-C and a run that fails into one line on stderr and exit
    status 2 (a failed run's traceback goes to a file the line names)."""

    @functools.wraps(command)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            return command(*args, **kwargs)
        except ConfigError as err:
            option = "--" + err.parameter.replace("_", "-")
            print(f"error: {option}: {err.message}", file=sys.stderr)
            raise typer.Exit(2) from None
        except SweepInterrupted as err:
            print(str(err), file=sys.stderr)
            raise typer.Exit(2) from None
        except RunFailed as err:
            print(f"error: {err}{traceback_note(err.failure.details)}", file=sys.stderr)
            raise typer.Exit(2) from None
        except BackendLost as err:  # Ray's threads may wait on it forever: leave at once
            leave_now(str(err))
        except OSError as err:  # a figure, a report or a store on a path that refuses it
            if err.errno not in WRITE_ERRORS and err.filename is None:
                raise
            action = "cannot write " if err.errno in WRITE_ERRORS else ""
            print(f"error: {action}{err.filename or 'the output'}: {err.strerror}", file=sys.stderr)
            raise typer.Exit(2) from None

    return wrapper  # type: ignore[return-value]


def check_outputs(store: Path | None = None, figures: Path | None = None) -> None:
    """Every output path is usable, checked before anything is computed (nothing is
    created here)."""
    if store is not None:
        check_store(store)
    if figures is not None:
        check_output_directory(figures, "figures")


def parse_range(text: str, parameter: str, low: int, high: int) -> tuple[int, ...]:
    """``"2-7"`` -> (2, ..., 7); ``"3"`` -> (3,); ``"2,4,6"`` -> (2, 4, 6); every value in
    ``[low, high]``, checked before any range is expanded."""
    values: list[int] = []
    parts = text.replace(" ", "").split(",")
    require(all(parts), parameter, f"expected N, LOW-HIGH or a comma list (got {text!r})")
    for part in parts:
        first, sep, last = part.partition("-")
        try:
            lo = int(first)
            hi = int(last) if sep else lo
        except ValueError:
            message = f"expected N, LOW-HIGH or a comma list (got {text!r})"
            raise ConfigError(parameter, message) from None
        require(lo <= hi, parameter, f"range {part} is reversed; write LOW-HIGH, e.g. {hi}-{lo}")
        require(lo >= low, parameter, f"must be >= {low} (got {lo})")
        require(hi <= high, parameter, f"must be <= {high} (got {hi})")
        values.extend(range(lo, hi + 1))
    return tuple(sorted(set(values)))


def parse_names(text: str, parameter: str) -> tuple[str, ...]:
    """``"cmarl-cd, la-oca"`` -> ("cmarl-cd", "la-oca")."""
    names = tuple(dict.fromkeys(p.strip().lower() for p in text.split(",") if p.strip()))
    require(len(names) > 0, parameter, f"needs at least one name (got {text!r})")
    return names


#: The ``--set`` option of the commands that train learners.
SetOption = Annotated[
    str,
    typer.Option(
        "--set",
        help="Learner settings, LEARNER.SETTING=VALUE as a comma list, e.g. "
        "deep-cmarl-cd.expectile=0.99,vdn.lr=0.0005 (any field of the learner's config; "
        "see the docs' interpretation choices); deep-cmarl-cd.design=NAME takes a named "
        "design's settings (shares-cold, critic, ...), which the others then change.",
    ),
]


def apply_settings(text: str, configs: tuple[Any, ...], parameter: str = "set") -> tuple:
    """``configs`` with the settings of ``text`` (``LEARNER.SETTING=VALUE, ...``), each
    value read as its field's type; a learner not among ``configs``, an unknown setting
    or a value the learner refuses is one clear error."""
    by_name = {config.name: config for config in configs}
    changes: dict[str, dict[str, Any]] = {}
    designs: dict[str, dict[str, Any]] = {}
    for item in (part.strip() for part in text.split(",") if part.strip()):
        target, _, value = item.partition("=")
        name, _, field = target.strip().lower().rpartition(".")
        if field == "design" and name in DESIGNS_BY_LEARNER and name in by_name:
            designs[name] = _design_settings(by_name[name], value, parameter)
        else:
            changes.setdefault(name, {})[field] = _setting_value(
                item, name, field, value, by_name, parameter
            )
    out = []
    for config in configs:
        try:
            settings = {**designs.get(config.name, {}), **changes.get(config.name, {})}
            changed = dataclasses.replace(config, **settings)
        except ConfigError as err:
            raise ConfigError(parameter, f"{config.name}.{err.parameter} {err.message}") from None
        renamed = f"would make {config.name} another learner; choose it with --algorithms"
        require(changed.name == config.name, parameter, renamed)
        out.append(changed)
    return tuple(out)


def _design_settings(config: Any, text: str, parameter: str) -> dict[str, Any]:
    """``LEARNER.design=NAME``: the settings in which the named design differs from the
    learner's defaults, applied before the learner's other settings (which win) and after
    the command's own options and the game's settings (which it changes only where the
    design does)."""
    designs = DESIGNS_BY_LEARNER[config.name]
    chosen = text.strip().lower()
    known = f"{config.name} has no design {chosen!r}; its designs: {', '.join(designs)}"
    require(chosen in designs, parameter, known)
    design, default = designs[chosen], type(config)()
    fields = (f.name for f in dataclasses.fields(design))
    return {f: getattr(design, f) for f in fields if getattr(design, f) != getattr(default, f)}


def _setting_value(
    item: str, name: str, field: str, text: str, by_name: dict[str, Any], parameter: str
) -> Any:
    """``item``, ``"learner.setting=value"`` split into ``name``, ``field`` and ``text``:
    the value as the setting's type."""
    usage = f"expected LEARNER.SETTING=VALUE (got {item!r})"
    require(bool(name and field and text.strip()), parameter, usage)
    playing = ", ".join(by_name)
    require(name in by_name, parameter, f"{name!r} does not play here (playing: {playing})")
    fields = sorted(f.name for f in dataclasses.fields(by_name[name]))
    known = f"{name} has no setting {field!r}; its settings: {', '.join(fields)}"
    require(field in fields, parameter, known)
    config = by_name[name]
    default = getattr(config, field)
    if default is None:  # an optional setting: its declared type says what it holds
        declared = next(f.type for f in dataclasses.fields(config) if f.name == field)
        if text.strip().lower() == "none":
            return None
        default = 0.0 if "float" in str(declared) else 0 if "int" in str(declared) else None
    return _typed(default, text.strip(), parameter, f"{name}.{field}")


#: How a setting's type is named where a value does not parse as one.
KIND_NAMES = {"int": "an integer", "float": "a number"}


def _typed(default: Any, text: str, parameter: str, label: str = "the value") -> Any:
    """``text`` as a value of ``default``'s type (bool: true/false/1/0); ``label`` names
    the setting where it does not parse."""
    kind = KIND_NAMES.get(type(default).__name__, type(default).__name__)
    if isinstance(default, bool):
        require(
            text.lower() in ("true", "false", "1", "0"),
            parameter,
            f"{label}: expected true or false (got {text!r})",
        )
        return text.lower() in ("true", "1")
    try:
        if isinstance(default, int):
            return parse_count(text, parameter) if text.lower().endswith("k") else int(text)
        if isinstance(default, float):
            return float(text)
    except ValueError:
        raise ConfigError(parameter, f"{label}: expected {kind} (got {text!r})") from None
    return text


def parse_grid(text: str, parameter: str = "grid") -> tuple[int, int]:
    """``"3x4"`` -> (3, 4): rows and columns of cells, each >= 1."""
    rows, sep, cols = text.strip().lower().partition("x")
    usage = f"expected ROWSxCOLS such as 3x4 (got {text!r})"
    require(bool(sep) and rows.strip().isdecimal() and cols.strip().isdecimal(), parameter, usage)
    shape = int(rows), int(cols)
    require(min(shape) >= 1, parameter, f"needs at least 1x1 cells (got {text!r})")
    return shape


#: The suffixes a count may end with, and what they multiply.
COUNT_SUFFIXES = {"k": 1000, "m": 1_000_000}


def parse_count(text: str, parameter: str) -> int:
    """``"100000"``, ``"100_000"`` or ``"100k"`` -> 100000, ``"2.05M"`` -> 2050000 (a
    whole number once scaled; must be >= 1)."""
    part = text.replace("_", "").strip().lower()
    scale = COUNT_SUFFIXES.get(part[-1:], 1)
    digits = part[:-1] if scale > 1 else part
    form = f"expected an integer such as 50000, 50k or 2.05M (got {text!r})"
    try:
        value = int(digits) * scale
    except ValueError:
        try:  # a decimal before a suffix: exact in decimal, whole once scaled
            scaled = Decimal(digits) * scale
        except InvalidOperation:
            raise ConfigError(parameter, form) from None
        if scale == 1 or not scaled.is_finite() or scaled != scaled.to_integral_value():
            raise ConfigError(parameter, form) from None
        value = int(scaled)
    require(value >= 1, parameter, f"must be >= 1 (got {value})")
    return value


def parse_counts(text: str, parameter: str) -> tuple[int, ...]:
    """``"100000,300000"`` or ``"100k,300k"`` -> (100000, 300000)."""
    parts = text.split(",")
    require(
        all(p.strip() for p in parts),
        parameter,
        f"expected comma-separated integers (got {text!r})",
    )
    return tuple(sorted({parse_count(part, parameter) for part in parts}))


def parse_unit(text: str, parameter: str) -> Unit:
    """``"3,1,0.8"`` -> a unit of 3 HP, 1 damage per hit and hit rate 0.8 (Fig. 5's
    stats: whole HP and damage in 1..99, a hit rate in (0, 1])."""
    form = f"expected HP,DAMAGE,HIT_RATE such as 3,1,0.8 (got {text!r})"
    parts = [part.strip() for part in text.split(",")]
    require(len(parts) == 3, parameter, form)
    try:
        hp, damage, hit_rate = int(parts[0]), int(parts[1]), float(parts[2])
    except ValueError:
        raise ConfigError(parameter, form) from None
    try:
        return Unit(hp, damage, hit_rate)
    except ConfigError as err:  # the unit's own check, under the option's name
        what = {"hp": "HP", "damage": "damage", "hit_rate": "the hit rate"}[err.parameter]
        raise ConfigError(parameter, f"{what} {err.message}") from None
