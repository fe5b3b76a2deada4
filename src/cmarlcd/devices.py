"""Where the deep learners compute: ``cpu``, ``cuda``, ``cuda:N`` or ``auto``.

The device is an *execution* setting, like the number of workers: it is not part of a
run's identity or seeds, so a run keeps its key and its random streams on any device
(its numbers agree up to float rounding, which over a long run lets trajectories part),
and a store computed on a GPU resumes on a CPU. Each deep run records the device that
computed it in its metrics (``"device"``).

Inside a process the device in use is a setting of the process, :func:`current` (``cpu``
unless :func:`using` or :func:`set_current` says otherwise): the runner sets it in every
worker, and the deep learners read it when they are built, unless they are given one.

Only :func:`resolve` and :func:`describe` import torch; checking the spelling does not.
Whether a GPU is present is asked through NVML (``PYTORCH_NVML_BASED_CUDA_CHECK``, unless
the environment sets it otherwise), which does not start CUDA in this process, so worker
processes forked afterwards can (a worker pool for the GPU is spawned instead where this
process has started CUDA, :class:`cmarlcd.sweeps.backends.local.ProcessBackend`).
"""

from __future__ import annotations

import contextlib
import functools
import importlib.util
import os
import re
from collections.abc import Iterator

from cmarlcd.errors import ConfigError, require

#: What ``--device`` accepts.
DEVICES = ("cpu", "cuda", "cuda:N", "auto")

#: The default: stored results and every fixed-seed number were computed there.
DEFAULT_DEVICE = "cpu"

#: [choice] Deep tasks that share one GPU at a time (``--gpu-tasks``): local worker
#: processes that take the deep learners' tasks, or on Ray each such task's share of a
#: GPU (``1 / GPU_TASKS``). Several, not one, because a deep task holds a core with its
#: acting and evaluation (compiled loops on the CPU, over a copy of the weights) however
#: fast the card: measured on the CPU, a task of 10 stacked battlefield rounds at the
#: paper's budget holds its core for at least 5 minutes, so the paper's tournament (21
#: such tasks) takes at least 105 minutes with one at a time, 15 with 8 (docs: GPU). Each
#: such process holds a CUDA context (a few hundred MB of the card).
GPU_TASKS = 8

_SPELLING = re.compile(r"cpu|auto|cuda(:\d+)?")
_current = DEFAULT_DEVICE


def check_device(device: str) -> None:
    """``device`` is spelt as one of :data:`DEVICES` (nothing imported, nothing asked)."""
    require(
        isinstance(device, str) and _SPELLING.fullmatch(device) is not None,
        "device",
        f"must be one of {', '.join(DEVICES)} (got {device!r})",
    )


def gpu_count() -> int:
    """The GPUs torch sees, asked without starting CUDA here (0 without torch, or with a
    torch built without CUDA)."""
    if importlib.util.find_spec("torch") is None:
        return 0
    os.environ.setdefault("PYTORCH_NVML_BASED_CUDA_CHECK", "1")
    import torch

    if not torch.cuda.is_available():
        return 0
    return int(torch.cuda.device_count())


def resolve(device: str) -> str:
    """The device ``device`` names, as torch spells it: ``cpu`` or ``cuda:N``.

    ``auto`` takes the first GPU where torch sees one, else the CPU. A GPU asked for where
    torch sees none, or one it does not have, is refused (:class:`ConfigError`).
    """
    check_device(device)
    if device == DEFAULT_DEVICE:
        return device
    count = gpu_count()
    if device == "auto":
        return "cuda:0" if count else DEFAULT_DEVICE
    index = int(device.partition(":")[2] or 0)
    if count == 0:
        raise ConfigError(
            "device", f"{device}: torch sees no GPU here (torch.cuda.is_available() is False)"
        )
    require(
        index < count, "device", f"{device}: torch sees {count} GPU(s), cuda:0 to cuda:{count - 1}"
    )
    return f"cuda:{index}"


@functools.lru_cache(maxsize=16)
def describe(device: str) -> str:
    """The device as a run records it: ``cpu``, or ``cuda:N`` with the card's name."""
    if not device.startswith("cuda"):
        return device
    import torch

    return f"{device} ({torch.cuda.get_device_name(torch.device(device))})"


def current() -> str:
    """The device this process's deep learners are built on (a resolved name)."""
    return _current


def set_current(device: str) -> None:
    """Build this process's deep learners on ``device`` from now on (a resolved name:
    :func:`resolve`)."""
    global _current
    require(
        device == DEFAULT_DEVICE or re.fullmatch(r"cuda:\d+", device) is not None,
        "device",
        f"must be resolved first, cpu or cuda:N (got {device!r})",
    )
    _current = device


@contextlib.contextmanager
def running_on(device: str) -> Iterator[str]:
    """Within the block, build deep learners on ``device`` (a resolved name)."""
    before = _current
    set_current(device)
    try:
        yield device
    finally:
        set_current(before)


def using(device: str) -> contextlib.AbstractContextManager[str]:
    """Within the block, build deep learners on ``device`` (``auto``, ``cuda``, …):
    ``with devices.using("auto"): ...``."""
    return running_on(resolve(device))
