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
#: Largest action count of a sensor (idle + four cells, the interior sensors).
MAX_ACTIONS = 5
#: The idle action of every sensor.
IDLE = 0
#: "No cell": a captured target in ``targets``, an idle sensor's focus, table padding.
NO_CELL = -1
CAPTURED = NO_CELL

# -------------------------------------------------------------------------- states

#: Non-terminal states: 6 * 5 (both alive) + 6 (target 0 captured) + 6 (target 1 captured).
N_STATES = N_CELLS * (N_CELLS - 1) + 2 * N_CELLS
#: Both targets captured (absorbing).
TERMINAL_STATE = N_STATES
#: State indices including the terminal one (the observation space size).
N_STATE_INDICES = N_STATES + 1
_ONLY_T1_OFFSET = N_CELLS * (N_CELLS - 1)  # 30: target 0 captured, 30 + t1
_ONLY_T0_OFFSET = _ONLY_T1_OFFSET + N_CELLS  # 36: target 1 captured, 36 + t0

# ------------------------------------------------------------------------- dynamics

#: Episode cap: an episode is truncated after this many steps.
MAX_STEPS = 40
#: Initial energy of each target.
TARGET_ENERGY = 3
#: Focusing sensors needed on a target's cell to hit it.
HIT_THRESHOLD = 3
#: Sensors rewarded for a capture (the highest-indexed focusing ones).
CAPTURE_CREDITED = 3
#: Reward of each of the sensors making a capture.
CAPTURE_REWARD = 10.0
#: Reward of a focusing sensor (on a target or not); idle earns 0.
FOCUS_REWARD = -1.0
#: [choice] Target moves, drawn uniformly: 0 stay, 1 up, 2 down, 3 left, 4 right.
N_MOVES = 5
MOVE_ROW = np.array([0, -1, 1, 0, 0], dtype=np.int64)
MOVE_COL = np.array([0, 0, 0, -1, 1], dtype=np.int64)
#: The best episode: 3 sensors on each target for 3 steps, 2 * 3 * 10 - 6 * 3 = 42.
OPTIMAL_RETURN = 42.0
OPTIMAL_STEPS = 3


def _sensor_cells() -> np.ndarray:
    """Row ``s``: the cells sensor ``s`` touches, increasing, padded with ``-1``."""
    table = np.full((N_SENSORS, MAX_ACTIONS - 1), NO_CELL, dtype=np.int64)
    for sensor in range(N_SENSORS):
        row, col = divmod(sensor, N_COLS + 1)
        cells = [
            r * N_COLS + c
            for r, c in ((row - 1, col - 1), (row - 1, col), (row, col - 1), (row, col))
            if 0 <= r < N_ROWS and 0 <= c < N_COLS
        ]
        table[sensor, : len(cells)] = sorted(cells)
    return table


#: ``SENSOR_CELLS[s, k]``: the cell that action ``k + 1`` of sensor ``s`` focuses (-1: none).
SENSOR_CELLS = _sensor_cells()
#: Actions per sensor: idle + one per touched cell (corners 2, edges 3, interior 5).
ACTION_COUNTS = 1 + (SENSOR_CELLS >= 0).sum(axis=1).astype(np.int64)
#: ``CELL_SENSORS[c]``: the four sensors touching cell ``c``, increasing.
CELL_SENSORS = np.array(
    [np.flatnonzero(np.isin(SENSOR_CELLS, cell).any(axis=1)) for cell in range(N_CELLS)],
    dtype=np.int64,
)
#: ``CELL_ACTIONS[c, j]``: the action with which sensor ``CELL_SENSORS[c, j]`` focuses ``c``.
CELL_ACTIONS = np.array(
    [
        [1 + int(np.flatnonzero(SENSOR_CELLS[s] == cell)[0]) for s in CELL_SENSORS[cell]]
        for cell in range(N_CELLS)
    ],
    dtype=np.int64,
)
for _table in (SENSOR_CELLS, ACTION_COUNTS, CELL_SENSORS, CELL_ACTIONS, MOVE_ROW, MOVE_COL):
    _table.setflags(write=False)

# -------------------------------------------------------------------------- kernels


@njit(cache=True)
def dsn_reset(targets: np.ndarray, energy: np.ndarray, rng) -> None:
    """Start an episode: full energy, two distinct uniform cells (two draws, in order)."""
    energy[0] = TARGET_ENERGY
    energy[1] = TARGET_ENERGY
    first = int(N_CELLS * rng.random())
    second = int((N_CELLS - 1) * rng.random())
    if second >= first:
        second += 1
    targets[0] = first
    targets[1] = second


@njit(cache=True)
def dsn_state(targets: np.ndarray) -> int:
    """The global state index: 0..29 both alive, 30..35 / 36..41 one alive, 42 none."""
    t0 = targets[0]
    t1 = targets[1]
    if t0 >= 0 and t1 >= 0:
        return t0 * (N_CELLS - 1) + (t1 if t1 < t0 else t1 - 1)
    if t1 >= 0:
        return _ONLY_T1_OFFSET + t1
    if t0 >= 0:
        return _ONLY_T0_OFFSET + t0
    return TERMINAL_STATE


@njit(cache=True)
def done(targets: np.ndarray) -> bool:
    """True when both targets are captured (the episode terminates)."""
    return targets[0] < 0 and targets[1] < 0


@njit(cache=True)
def focused_cell(sensor: int, action: int) -> int:
    """The cell ``sensor`` focuses with ``action``, or ``-1`` when idle."""
    if action == IDLE:
        return NO_CELL
    return SENSOR_CELLS[sensor, action - 1]


@njit(cache=True)
def dsn_sensor_phase(
    targets: np.ndarray, energy: np.ndarray, joint: np.ndarray, individual: np.ndarray
) -> float:
    """The sensors act: fill ``individual`` with each sensor's reward, apply hits and
    captures (a captured target becomes ``-1``), and return the global reward."""
    total = 0.0
    for s in range(N_SENSORS):
        individual[s] = FOCUS_REWARD if joint[s] != IDLE else 0.0
    for k in range(N_TARGETS):
        cell = targets[k]
        if cell < 0:
            continue
        focusing = 0
        for s in range(N_SENSORS):
            if focused_cell(s, joint[s]) == cell:
                focusing += 1
        if focusing < HIT_THRESHOLD:
            continue
        energy[k] -= 1
        if energy[k] > 0:
            continue
        targets[k] = CAPTURED
        credited = 0
        for s in range(N_SENSORS - 1, -1, -1):  # the highest-indexed focusing sensors
            if credited < CAPTURE_CREDITED and focused_cell(s, joint[s]) == cell:
                individual[s] += CAPTURE_REWARD
                credited += 1
    for s in range(N_SENSORS):
        total += individual[s]
    return total


@njit(cache=True)
def move_cell(cell: int, move: int) -> int:
    """The cell reached from ``cell`` by ``move``, or ``cell`` itself when it leaves the grid."""
    row = cell // N_COLS + MOVE_ROW[move]
    col = cell % N_COLS + MOVE_COL[move]
    if row < 0 or row >= N_ROWS or col < 0 or col >= N_COLS:
        return cell
    return row * N_COLS + col


@njit(cache=True)
def move_target(targets: np.ndarray, k: int, move: int) -> None:
    """Move live target ``k``; a move into the other live target's cell is not executed
    (a captured target, ``-1``, blocks nothing)."""
    destination = move_cell(targets[k], move)
    if destination != targets[1 - k]:
        targets[k] = destination


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
    reward = dsn_sensor_phase(targets, energy, joint, individual)
    for k in range(N_TARGETS):
        if targets[k] >= 0:
            move_target(targets, k, int(N_MOVES * rng.random()))
    return reward


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
