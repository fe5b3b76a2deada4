"""The DSN at any size as a game of the compiled protocol: :func:`make_spec`.

The state arrays carry the layout: ``env = (targets, energy, individual, sensor_cells,
action_counts, state_offsets, shape)`` with ``shape = [rows, cols]``, so one compiled
loop plays every size. The rules are :mod:`~.layout`'s, the ones the paper's
:data:`~cmarlcd.games.sensor_network.SPEC` binds to its grid: on 2 x 3 cells with 2
targets both play the same episodes from the same seeds (tested). Unlike the paper's
spec, a sized spec has state features (:func:`~.layout.target_features`): a vector whose
length does not grow with the state count, for learners that read features.
"""

from __future__ import annotations

import numpy as np

from cmarlcd.compiled import kernel
from cmarlcd.errors import require
from cmarlcd.games.sensor_network import layout
from cmarlcd.games.spec import GameKernels, GameSpec

#: The paper's layout, the default of :func:`make_spec`.
PAPER_GRID = (2, 3)
PAPER_TARGETS = 2


@kernel
def sized_reset(env, rng) -> None:
    layout.reset_targets(env[0], env[1], env[6][0] * env[6][1], rng)


@kernel
def sized_step(env, joint: np.ndarray, rng, rewards: np.ndarray) -> None:
    rows, cols = env[6][0], env[6][1]
    rewards[0] = layout.step_layout(env[3], rows, cols, env[0], env[1], joint, rng, env[2])


@kernel
def sized_state(env, team: int) -> int:
    return layout.state_index(env[0], env[6][0] * env[6][1], env[5])


@kernel
def sized_done(env) -> bool:
    return layout.all_captured(env[0])


@kernel
def sized_legal(env, masks: np.ndarray) -> None:
    """Every action of every sensor is always legal."""
    counts = env[4]
    for s in range(counts.shape[0]):
        for a in range(masks.shape[1]):
            masks[s, a] = a < counts[s]


@kernel
def sized_features(env, team: int, out) -> None:
    layout.target_features(env[0], env[6][0] * env[6][1], out)


KERNELS = GameKernels(sized_reset, sized_step, sized_state, sized_done, sized_legal, sized_features)


def check_layout(rows: int, cols: int, targets: int, max_steps: int | None) -> None:
    """A grid of at least one cell, 1..cells targets, a positive step cap, and a state
    count the learners can index; else one clear error."""
    require(rows >= 1 and cols >= 1, "grid", f"needs at least 1 x 1 cells (got {rows} x {cols})")
    cells = rows * cols
    require(targets >= 1, "targets", f"must be >= 1 (got {targets})")
    require(
        targets <= cells,
        "targets",
        f"at most one per cell: {rows} x {cols} cells hold at most {cells} (got {targets})",
    )
    require(max_steps is None or max_steps >= 1, "max_steps", f"must be >= 1 (got {max_steps})")
    states = layout.state_count(cells, targets, cap=layout.MAX_LAYOUT_STATES)
    require(
        states <= layout.MAX_LAYOUT_STATES,
        "targets",
        f"{rows} x {cols} cells with {targets} targets make more than "
        f"{layout.MAX_LAYOUT_STATES:,} states, the most a learner may index",
    )


def make_spec(
    rows: int = PAPER_GRID[0],
    cols: int = PAPER_GRID[1],
    targets: int = PAPER_TARGETS,
    max_steps: int | None = None,
) -> GameSpec:
    """The DSN on ``rows`` x ``cols`` cells with ``targets`` targets; an episode is cut
    after ``max_steps`` steps (default :data:`~.layout.STEPS_PER_TARGET` per target)."""
    check_layout(rows, cols, targets, max_steps)
    cells_of_sensor = layout.sensor_cells(rows, cols)
    counts = layout.action_counts(cells_of_sensor)
    offsets = layout.state_offsets(rows * cols, targets)
    shape = np.array([rows, cols], dtype=np.int64)
    for table in (cells_of_sensor, counts, offsets, shape):
        table.setflags(write=False)
    n_sensors = cells_of_sensor.shape[0]

    def new_env() -> tuple:
        return (
            np.full(targets, layout.NO_CELL, dtype=np.int64),
            np.zeros(targets, dtype=np.int64),
            np.zeros(n_sensors),
            cells_of_sensor,
            counts,
            offsets,
            shape,
        )

    return GameSpec(
        name=f"sensor_network_{rows}x{cols}_{targets}t_v0",
        kernels=KERNELS,
        new_env=new_env,
        agents=tuple(f"sensor_{s}" for s in range(n_sensors)),
        action_counts=counts,
        n_states=layout.state_count(rows * cols, targets),
        max_steps=layout.STEPS_PER_TARGET * targets if max_steps is None else max_steps,
        teams=(tuple(range(n_sensors)),),
        n_features=targets * (rows * cols + 1),
    )
