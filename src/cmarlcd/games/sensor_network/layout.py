"""The DSN's rules at any size: R x C cells, K targets (beyond the paper, whose grid is
2 x 3 with 2 targets).

Sensors sit on the (R + 1) x (C + 1) intersections, numbered row-major; a sensor touches
the up to four cells around it, and its action ``k + 1`` focuses the ``k``-th of them in
increasing cell number (0 is idle), so a corner sensor has 2 actions, an edge one 3, an
interior one 5. The rules generalise as the paper writes them: the targets start in
distinct uniformly random cells (drawn in index order, each among the cells still free);
each step, a target whose cell has at least three focusing sensors loses one energy and
is captured at zero (its three highest-indexed focusing sensors share the capture); then
every live target, in index order, moves uniformly to stay/up/down/left/right, a move off
the grid or into another live target's cell not executed.

**State index.** The live targets' cells, grouped by which targets are captured (the
groups ordered by the bitmask of captured targets, target k being bit k), and within a
group by the live cells in index order as a falling-factorial number (the first live
target's cell, then the second's among the cells the first leaves, …). On the paper's
grid this is its numbering: 30 states with both targets live, then 6 with target 0
captured, 6 with target 1 captured, and the terminal state 42.

The functions here take the layout as arrays and numbers; :mod:`~.kernels` binds the
paper's (its module constants, so its compiled loops see constants) and :func:`make_spec`
any other.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

#: "No cell": a captured target, an idle sensor's focus, table padding.
NO_CELL = -1
#: Largest action count of a sensor (idle + four cells).
MAX_ACTIONS = 5
#: Target moves, drawn uniformly: 0 stay, 1 up, 2 down, 3 left, 4 right.
N_MOVES = 5
MOVE_ROW = np.array([0, -1, 1, 0, 0], dtype=np.int64)
MOVE_COL = np.array([0, 0, 0, -1, 1], dtype=np.int64)
MOVE_ROW.setflags(write=False)
MOVE_COL.setflags(write=False)
#: Focusing sensors needed on a target's cell to hit it.
HIT_THRESHOLD = 3
#: Sensors rewarded for a capture (the highest-indexed focusing ones).
CAPTURE_CREDITED = 3
#: Reward of each of the sensors making a capture.
CAPTURE_REWARD = 10.0
#: Reward of a focusing sensor (on a target or not); idle earns 0.
FOCUS_REWARD = -1.0
#: Initial energy of each target.
TARGET_ENERGY = 3
#: [choice] Episode cap per target: an episode of K targets is cut after
#: ``STEPS_PER_TARGET * K`` steps (the paper's 40 for its 2 targets; its text gives no
#: rule for other sizes).
STEPS_PER_TARGET = 20
#: The most state indices a layout may have (every learner indexes them).
MAX_LAYOUT_STATES = 50_000_000


# ------------------------------------------------------------------------ geometry


def sensor_cells(rows: int, cols: int) -> np.ndarray:
    """Row ``s``: the cells sensor ``s`` touches, increasing, padded with ``-1``."""
    table = np.full(((rows + 1) * (cols + 1), MAX_ACTIONS - 1), NO_CELL, dtype=np.int64)
    for sensor in range(table.shape[0]):
        row, col = divmod(sensor, cols + 1)
        cells = [
            r * cols + c
            for r, c in ((row - 1, col - 1), (row - 1, col), (row, col - 1), (row, col))
            if 0 <= r < rows and 0 <= c < cols
        ]
        table[sensor, : len(cells)] = sorted(cells)
    return table


def action_counts(cells_of_sensor: np.ndarray) -> np.ndarray:
    """Actions per sensor: idle + one per touched cell."""
    return 1 + (cells_of_sensor >= 0).sum(axis=1).astype(np.int64)


def cell_sensors(cells_of_sensor: np.ndarray, n_cells: int) -> np.ndarray:
    """``[c]``: the four sensors touching cell ``c``, increasing."""
    return np.array(
        [np.flatnonzero((cells_of_sensor == cell).any(axis=1)) for cell in range(n_cells)],
        dtype=np.int64,
    )


def state_offsets(n_cells: int, n_targets: int) -> np.ndarray:
    """``[mask]``: the first state index of the states whose captured targets are the
    bits of ``mask``; the last entry (every target captured) is the terminal state."""
    sizes = [math.perm(n_cells, n_targets - bin(mask).count("1")) for mask in range(2**n_targets)]
    return np.cumsum([0, *sizes[:-1]]).astype(np.int64)


def state_count(n_cells: int, n_targets: int, cap: int | None = None) -> int:
    """State indices of a layout, the terminal one included; once past ``cap`` the sum
    stops (any count above ``cap`` is returned), so a huge layout is refused at once."""
    total = 0
    for live in range(n_targets + 1):
        total += math.comb(n_targets, live) * math.perm(n_cells, live)
        if cap is not None and total > cap:
            return total
    return total


# -------------------------------------------------------------------------- kernels


@njit(cache=True)
def reset_targets(targets: np.ndarray, energy: np.ndarray, n_cells: int, rng) -> None:
    """Full energy; the targets in distinct uniform cells, target k drawn (one uniform)
    among the cells the earlier ones left, in increasing order."""
    for k in range(targets.shape[0]):
        energy[k] = TARGET_ENERGY
    for k in range(targets.shape[0]):
        rank = int((n_cells - k) * rng.random())
        cell = 0
        while True:
            free = True
            for j in range(k):
                if targets[j] == cell:
                    free = False
            if free:
                if rank == 0:
                    break
                rank -= 1
            cell += 1
        targets[k] = cell


@njit(cache=True)
def state_index(targets: np.ndarray, n_cells: int, offsets: np.ndarray) -> int:
    """The state index of the targets' cells (see the module docstring)."""
    mask = 0
    for k in range(targets.shape[0]):
        if targets[k] < 0:
            mask |= 1 << k
    index, live = 0, 0
    for k in range(targets.shape[0]):
        cell = targets[k]
        if cell < 0:
            continue
        rank = cell
        for j in range(k):
            if 0 <= targets[j] < cell:
                rank -= 1
        index = index * (n_cells - live) + rank
        live += 1
    return offsets[mask] + index


@njit(cache=True)
def all_captured(targets: np.ndarray) -> bool:
    for k in range(targets.shape[0]):  # noqa: SIM110 (compiled: a plain loop)
        if targets[k] >= 0:
            return False
    return True


@njit(cache=True)
def focus_of(cells_of_sensor: np.ndarray, sensor: int, action: int) -> int:
    """The cell ``sensor`` focuses with ``action``, or ``-1`` when idle."""
    if action == 0:
        return NO_CELL
    return cells_of_sensor[sensor, action - 1]


@njit(cache=True)
def sensor_phase(
    cells_of_sensor: np.ndarray,
    targets: np.ndarray,
    energy: np.ndarray,
    joint: np.ndarray,
    individual: np.ndarray,
) -> float:
    """The sensors act: each sensor's reward into ``individual``, hits and captures (a
    captured target becomes ``-1``); returns the global reward."""
    n_sensors = cells_of_sensor.shape[0]
    total = 0.0
    for s in range(n_sensors):
        individual[s] = FOCUS_REWARD if joint[s] != 0 else 0.0
    for k in range(targets.shape[0]):
        cell = targets[k]
        if cell < 0:
            continue
        focusing = 0
        for s in range(n_sensors):
            if focus_of(cells_of_sensor, s, joint[s]) == cell:
                focusing += 1
        if focusing < HIT_THRESHOLD:
            continue
        energy[k] -= 1
        if energy[k] > 0:
            continue
        targets[k] = NO_CELL
        credited = 0
        for s in range(n_sensors - 1, -1, -1):  # the highest-indexed focusing sensors
            if credited < CAPTURE_CREDITED and focus_of(cells_of_sensor, s, joint[s]) == cell:
                individual[s] += CAPTURE_REWARD
                credited += 1
    for s in range(n_sensors):
        total += individual[s]
    return total


@njit(cache=True)
def moved_cell(cell: int, move: int, rows: int, cols: int) -> int:
    """The cell reached from ``cell`` by ``move``, or ``cell`` when it leaves the grid."""
    row = cell // cols + MOVE_ROW[move]
    col = cell % cols + MOVE_COL[move]
    if row < 0 or row >= rows or col < 0 or col >= cols:
        return cell
    return row * cols + col


@njit(cache=True)
def move_one(targets: np.ndarray, k: int, move: int, rows: int, cols: int) -> None:
    """Move live target ``k``; a move into another live target's cell is not executed."""
    destination = moved_cell(targets[k], move, rows, cols)
    for j in range(targets.shape[0]):
        if j != k and targets[j] == destination:
            return
    targets[k] = destination


@njit(cache=True)
def step_layout(
    cells_of_sensor: np.ndarray,
    rows: int,
    cols: int,
    targets: np.ndarray,
    energy: np.ndarray,
    joint: np.ndarray,
    rng,
    individual: np.ndarray,
) -> float:
    """One step: the sensor phase, then one uniform move per live target in index order
    (no draw for a captured one). Returns the global reward."""
    reward = sensor_phase(cells_of_sensor, targets, energy, joint, individual)
    for k in range(targets.shape[0]):
        if targets[k] >= 0:
            move_one(targets, k, int(N_MOVES * rng.random()), rows, cols)
    return reward


@njit(cache=True)
def target_features(targets: np.ndarray, n_cells: int, out: np.ndarray) -> None:
    """Per target: its cell one-hot (n_cells entries, all 0 once captured), then 1 if it
    is captured; ``K * (n_cells + 1)`` entries, whatever the number of states."""
    for f in range(out.shape[0]):
        out[f] = 0.0
    for k in range(targets.shape[0]):
        base = k * (n_cells + 1)
        if targets[k] >= 0:
            out[base + targets[k]] = 1.0
        else:
            out[base + n_cells] = 1.0
