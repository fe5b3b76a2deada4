"""The distributed sensor network (DSN) task (Section V-A, Fig. 3).

Twelve sensors sit on the 3 x 4 intersections of a grid of 2 x 3 cells and try to
capture two moving targets. Cells are numbered row-major ``0..5`` (cell ``(r, c)`` is
``3 r + c``) and sensors row-major ``0..11`` (sensor ``(R, C)`` is ``4 R + C``). A
sensor touches the up to four cells ``(R-1, C-1), (R-1, C), (R, C-1), (R, C)`` that lie
inside the grid; its action ``0`` is idle and action ``k + 1`` focuses the ``k``-th of
its cells in increasing cell number::

    s0 --- s1 --- s2 --- s3
    |  c0  |  c1  |  c2  |
    s4 --- s5 --- s6 --- s7
    |  c3  |  c4  |  c5  |
    s8 --- s9 --- s10 -- s11

Each step: all sensors act at once; a target whose cell has ``>= 3`` focusing sensors
loses one energy (four sensors still make one hit); a target at energy 0 is captured
and removed; then every live target (target 0 first) moves uniformly to one of
{stay, up, down, left, right}, a move off the grid or into the other live target's
cell is not executed. Every focusing sensor gets ``-1``, the three sensors making a
capture ``+10`` each (the three highest-indexed when four focus); the global reward,
which every sensor learns from, is the sum.

The transition is written once, as numba kernels over plain arrays (``targets``: the
cell of each target or ``-1`` when captured; ``energy``; ``joint``: one action per
sensor). The game protocol (:mod:`cmarlcd.games.spec`) wraps them as :data:`SPEC`, over
the state arrays ``env = (targets, energy, individual)``, where ``individual`` holds each
sensor's own reward of the last step; the training loops and
:class:`cmarlcd.games.sensor_network.SensorNetworkEnv` both run :data:`SPEC`.
"""

from __future__ import annotations

import operator

import numpy as np
from numba import njit

from cmarlcd.compiled import kernel
from cmarlcd.errors import ConfigError, require
from cmarlcd.games.sensor_network import layout
from cmarlcd.games.sensor_network.layout import (
    CAPTURE_CREDITED,
    CAPTURE_REWARD,
    FOCUS_REWARD,
    HIT_THRESHOLD,
    MAX_ACTIONS,
    MOVE_COL,
    MOVE_ROW,
    N_MOVES,
    NO_CELL,
    TARGET_ENERGY,
)
from cmarlcd.games.spec import GameKernels, GameSpec

__all__ = [
    "ACTION_COUNTS",
    "AGENTS",
    "CAPTURED",
    "CAPTURE_CREDITED",
    "CAPTURE_REWARD",
    "CELL_ACTIONS",
    "CELL_SENSORS",
    "FOCUS_REWARD",
    "HIT_THRESHOLD",
    "IDLE",
    "MAX_ACTIONS",
    "MAX_STEPS",
    "MOVE_COL",
    "MOVE_ROW",
    "NO_CELL",
    "N_CELLS",
    "N_COLS",
    "N_MOVES",
    "N_ROWS",
    "N_SENSORS",
    "N_STATES",
    "N_STATE_INDICES",
    "N_TARGETS",
    "OPTIMAL_RETURN",
    "OPTIMAL_STEPS",
    "SENSOR_CELLS",
    "SPEC",
    "STATE_OFFSETS",
    "TARGET_ENERGY",
    "TERMINAL_STATE",
    "decode_state",
    "done",
    "dsn_move_targets",
    "dsn_reset",
    "dsn_sensor_phase",
    "dsn_state",
    "dsn_step",
    "encode_state",
    "env_done",
    "env_legal",
    "env_reset",
    "env_state",
    "env_step",
    "focused_cell",
    "move_cell",
    "move_target",
    "new_env",
    "optimal_joint_action",
    "validate_joint",
]

# ------------------------------------------------------------------------ geometry

#: Grid rows and columns of cells (Fig. 3).
N_ROWS = 2
N_COLS = 3
N_CELLS = N_ROWS * N_COLS
#: Sensors on the (N_ROWS + 1) x (N_COLS + 1) grid intersections.
N_SENSORS = (N_ROWS + 1) * (N_COLS + 1)
N_TARGETS = 2
#: The idle action of every sensor.
IDLE = 0
CAPTURED = NO_CELL

# -------------------------------------------------------------------------- states

#: Non-terminal states: 6 * 5 (both alive) + 6 (target 0 captured) + 6 (target 1 captured).
N_STATES = N_CELLS * (N_CELLS - 1) + 2 * N_CELLS
#: Both targets captured (absorbing).
TERMINAL_STATE = N_STATES
#: State indices including the terminal one (the observation space size).
N_STATE_INDICES = N_STATES + 1
#: The first index of each group of states (by captured targets, :mod:`~.layout`).
STATE_OFFSETS = layout.state_offsets(N_CELLS, N_TARGETS)
_ONLY_T1_OFFSET = int(STATE_OFFSETS[1])  # 30: target 0 captured, 30 + t1
_ONLY_T0_OFFSET = int(STATE_OFFSETS[2])  # 36: target 1 captured, 36 + t0

# ------------------------------------------------------------------------- dynamics

#: Episode cap: an episode is truncated after this many steps.
MAX_STEPS = layout.STEPS_PER_TARGET * N_TARGETS
#: The best episode: 3 sensors on each target for 3 steps, 2 * 3 * 10 - 6 * 3 = 42.
OPTIMAL_RETURN = 42.0
OPTIMAL_STEPS = 3

#: ``SENSOR_CELLS[s, k]``: the cell that action ``k + 1`` of sensor ``s`` focuses (-1: none).
SENSOR_CELLS = layout.sensor_cells(N_ROWS, N_COLS)
#: Actions per sensor: idle + one per touched cell (corners 2, edges 3, interior 5).
ACTION_COUNTS = layout.action_counts(SENSOR_CELLS)
#: ``CELL_SENSORS[c]``: the four sensors touching cell ``c``, increasing.
CELL_SENSORS = layout.cell_sensors(SENSOR_CELLS, N_CELLS)
#: ``CELL_ACTIONS[c, j]``: the action with which sensor ``CELL_SENSORS[c, j]`` focuses ``c``.
CELL_ACTIONS = np.array(
    [
        [1 + int(np.flatnonzero(SENSOR_CELLS[s] == cell)[0]) for s in CELL_SENSORS[cell]]
        for cell in range(N_CELLS)
    ],
    dtype=np.int64,
)
for _table in (SENSOR_CELLS, ACTION_COUNTS, CELL_SENSORS, CELL_ACTIONS, STATE_OFFSETS):
    _table.setflags(write=False)

# -------------------------------------------------------------------------- kernels
# The rules of :mod:`~.layout`, bound to the paper's grid (its arrays and sizes are
# module constants, which the compiled loops see as constants).


@njit(cache=True)
def dsn_reset(targets: np.ndarray, energy: np.ndarray, rng) -> None:
    """Start an episode: full energy, two distinct uniform cells (two draws, in order)."""
    layout.reset_targets(targets, energy, N_CELLS, rng)


@njit(cache=True)
def dsn_state(targets: np.ndarray) -> int:
    """The global state index: 0..29 both alive, 30..35 / 36..41 one alive, 42 none."""
    return layout.state_index(targets, N_CELLS, STATE_OFFSETS)


@njit(cache=True)
def done(targets: np.ndarray) -> bool:
    """True when both targets are captured (the episode terminates)."""
    return layout.all_captured(targets)


@njit(cache=True)
def focused_cell(sensor: int, action: int) -> int:
    """The cell ``sensor`` focuses with ``action``, or ``-1`` when idle."""
    return layout.focus_of(SENSOR_CELLS, sensor, action)


@njit(cache=True)
def dsn_sensor_phase(
    targets: np.ndarray, energy: np.ndarray, joint: np.ndarray, individual: np.ndarray
) -> float:
    """The sensors act: fill ``individual`` with each sensor's reward, apply hits and
    captures (a captured target becomes ``-1``), and return the global reward."""
    return layout.sensor_phase(SENSOR_CELLS, targets, energy, joint, individual)


@njit(cache=True)
def move_cell(cell: int, move: int) -> int:
    """The cell reached from ``cell`` by ``move``, or ``cell`` itself when it leaves the grid."""
    return layout.moved_cell(cell, move, N_ROWS, N_COLS)


@njit(cache=True)
def move_target(targets: np.ndarray, k: int, move: int) -> None:
    """Move live target ``k``; a move into the other live target's cell is not executed
    (a captured target, ``-1``, blocks nothing)."""
    layout.move_one(targets, k, move, N_ROWS, N_COLS)


@njit(cache=True)
def dsn_move_targets(targets: np.ndarray, moves: np.ndarray) -> None:
    """Move the live targets by ``moves``, target 0 first."""
    for k in range(N_TARGETS):
        if targets[k] >= 0:
            move_target(targets, k, moves[k])


@njit(cache=True)
def dsn_step(
    targets: np.ndarray, energy: np.ndarray, joint: np.ndarray, rng, individual: np.ndarray
) -> float:
    """One step: the sensor phase, then one uniform move per live target, target 0 first
    (no draw for a captured target). Returns the global reward."""
    return layout.step_layout(SENSOR_CELLS, N_ROWS, N_COLS, targets, energy, joint, rng, individual)


# ------------------------------------------------------------------ Python helpers


def encode_state(t0: int, t1: int) -> int:
    """The state index of target cells ``(t0, t1)``, ``-1`` meaning captured."""
    t0, t1 = operator.index(t0), operator.index(t1)
    for name, cell in (("t0", t0), ("t1", t1)):
        require(
            CAPTURED <= cell < N_CELLS, name, f"must be a cell 0..{N_CELLS - 1} or -1 (got {cell})"
        )
    require(t0 < 0 or t0 != t1, "t1", f"two live targets cannot share cell {t0}")
    return int(dsn_state(np.array([t0, t1], dtype=np.int64)))


def decode_state(index: int) -> tuple[int, int]:
    """The target cells ``(t0, t1)`` of state ``index`` (``-1``: captured)."""
    index = operator.index(index)
    require(
        0 <= index < N_STATE_INDICES,
        "state",
        f"must be in 0..{TERMINAL_STATE} (got {index})",
    )
    if index == TERMINAL_STATE:
        return CAPTURED, CAPTURED
    if index >= _ONLY_T0_OFFSET:
        return index - _ONLY_T0_OFFSET, CAPTURED
    if index >= _ONLY_T1_OFFSET:
        return CAPTURED, index - _ONLY_T1_OFFSET
    t0, rest = divmod(index, N_CELLS - 1)
    return t0, rest if rest < t0 else rest + 1


def optimal_joint_action(state_index: int) -> np.ndarray:
    """A scripted optimal joint action: exactly 3 sensors on each live target, others idle.

    [choice] Rule: the live targets pick in turn, target 0 first; each takes, among the
    four sensors touching its cell and not yet taken, those *not* touching the other
    live target's cell first, then the lowest-indexed. Two adjacent cells share two
    sensors and each target needs only one of them, so the choice never conflicts.
    """
    require(
        0 <= state_index < N_STATES,
        "state",
        f"must be a non-terminal state 0..{N_STATES - 1} (got {state_index})",
    )
    cells = decode_state(state_index)
    joint = np.zeros(N_SENSORS, dtype=np.int64)
    for k, cell in enumerate(cells):
        if cell < 0:
            continue
        other = cells[1 - k]
        shared = set(CELL_SENSORS[other].tolist()) if other >= 0 else set()
        free = [j for j in range(CELL_SENSORS.shape[1]) if joint[CELL_SENSORS[cell, j]] == IDLE]
        free.sort(key=lambda j: (int(CELL_SENSORS[cell, j]) in shared, j))
        for j in free[:HIT_THRESHOLD]:
            joint[CELL_SENSORS[cell, j]] = CELL_ACTIONS[cell, j]
    return joint


def validate_joint(joint: object) -> np.ndarray:
    """Return ``joint`` as an int64 array of 12 legal actions, or raise :class:`ConfigError`."""
    try:
        array = np.asarray(joint)
    except (TypeError, ValueError):
        raise ConfigError("joint", "must be a sequence of 12 integer actions") from None
    require(
        array.shape == (N_SENSORS,) and array.dtype.kind in "iu",
        "joint",
        f"must be {N_SENSORS} integer actions (got shape {array.shape}, dtype {array.dtype})",
    )
    array = array.astype(np.int64)
    bad = np.flatnonzero((array < 0) | (array >= ACTION_COUNTS))
    if bad.size:
        s = int(bad[0])
        raise ConfigError(
            "joint", f"sensor {s} action must be in 0..{ACTION_COUNTS[s] - 1} (got {array[s]})"
        )
    return array


# ------------------------------------------------------------------ game protocol


@kernel
def env_reset(env, rng) -> None:
    """Protocol ``reset``: :func:`dsn_reset` on ``env = (targets, energy, individual)``."""
    dsn_reset(env[0], env[1], rng)


@kernel
def env_step(env, joint: np.ndarray, rng, rewards: np.ndarray) -> None:
    """Protocol ``step``: :func:`dsn_step`; the global reward goes to the one team."""
    rewards[0] = dsn_step(env[0], env[1], joint, rng, env[2])


@kernel
def env_state(env, team: int) -> int:
    """Protocol ``state``: every sensor observes :func:`dsn_state`."""
    return dsn_state(env[0])


@kernel
def env_done(env) -> bool:
    """Protocol ``done``: both targets captured."""
    return done(env[0])


@kernel
def env_legal(env, masks: np.ndarray) -> None:
    """Protocol ``legal``: every action of every sensor is always legal."""
    for s in range(N_SENSORS):
        for a in range(masks.shape[1]):
            masks[s, a] = a < ACTION_COUNTS[s]


def new_env() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Fresh state arrays ``(targets, energy, individual)``: no episode started yet."""
    return (
        np.full(N_TARGETS, CAPTURED, dtype=np.int64),
        np.zeros(N_TARGETS, dtype=np.int64),
        np.zeros(N_SENSORS),
    )


AGENTS = tuple(f"sensor_{s}" for s in range(N_SENSORS))

#: The DSN as the training loops and the ParallelEnv see it: 43 state indices (42 +
#: the absorbing terminal state), one team of twelve sensors, episodes of at most 40 steps.
SPEC = GameSpec(
    name="sensor_network_v0",
    kernels=GameKernels(env_reset, env_step, env_state, env_done, env_legal),
    new_env=new_env,
    agents=AGENTS,
    action_counts=ACTION_COUNTS,
    n_states=N_STATE_INDICES,
    max_steps=MAX_STEPS,
    teams=(tuple(range(N_SENSORS)),),
)
