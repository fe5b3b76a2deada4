"""Level-Based Foraging (LBF): the rules of the ``lbforaging`` package, 2.0.0, compiled.

Agents with levels walk a grid on which foods with levels lie; a food is collected when
the agents next to it that ``LOAD`` at once have levels summing to at least the food's.
Every rule below is the package's (``lbforaging/foraging/environment.py``,
``ForagingEnv``), step for step; ``benchmarks/check_foraging.py`` proves the compiled step
equal to it over hundreds of thousands of steps.

**Actions** (per agent): 0 NONE, 1 NORTH (row - 1), 2 SOUTH, 3 WEST (column - 1), 4 EAST,
5 LOAD. An action is *valid* when it is NONE; a move into the grid and onto a cell
without food (other agents do not block it); LOAD next to a food. An invalid action is
played as NONE.

**A step**: every agent's move aims at a cell (NONE and LOAD aim at its own); agents
whose cell no other agent aims at go there, the others stay (so two agents cannot meet,
and an agent cannot enter the cell of one that stays; two agents may swap). Then each
food with loaders next to it (row or column distance 1): when their levels sum to at
least the food's level, the food is removed and each loader gets ``level * food_level /
(loaders_level * food_spawned)`` (``food_spawned``: the sum of the levels of the foods
of the episode, so a whole episode's team return is at most 1), otherwise each loader
gets ``-penalty``. The episode ends when no food is left (a termination) or after
``max_steps`` steps. [choice] The package calls the second a termination too; here it is
the protocol's cap (:attr:`GameSpec.max_steps`), a truncation: the step count is not in
any observation, so a learner that took the cap for the game's end would learn values of
a state that depend on something it cannot see. The rule is the same: the episode ends
at the same step (``benchmarks/check_foraging.py`` checks the package's ``done`` against
the two together), and an episode that terminated is one that collected every food.

**A reset**: each agent in turn is placed on a uniformly drawn cell, redrawn up to 1,000
times while the cell holds an agent (one already placed, or, as in the package, where an
agent not yet placed stood when the last episode ended), with a uniform level in
``[min_player_level, max_player_level]``. Then foods are placed one by one, up to
``max_foods`` of them in at most 1,000 draws in all, on uniform cells off the border that
hold no agent and have no food within one cell (diagonals included) nor two cells in
line; a food's level is uniform in ``[min_food_level, max_food_level]`` where
``max_food_level`` defaults to the sum of the three lowest agent levels, and equals it
(``force_coop``, the ``-coop`` tasks) where no agent may load a food alone.

**Observations** (per agent, the package's vector layout, ``3 * max_foods + 3 *
players`` floats): the foods the agent sees, ``(row, column, level)`` each in row-major
order, then the agents it sees, itself first and the others in agent order, ``(row,
column, level)``; unused slots are ``(-1, -1, 0)``. Coordinates are relative to the
corner of its window, the rows and columns within ``sight`` of its cell cut at the grid's
edges; an agent is seen when its coordinates in that frame lie in ``[0, 2 * sight]``
(the package's test, which at an edge of the grid sees agents up to ``2 * sight`` cells
away on the inner side). With ``sight`` the grid's size, every agent sees everything
in absolute coordinates.

The package draws its positions and levels with its own generator; the compiled game
draws them from the loop's: the same distribution (``tests/games/test_foraging.py``
tests it by chi-square), not the same episodes.

The state arrays ``env = (players, field, rules, status, rewards, scratch)`` are made by
:func:`new_env` from a :class:`~cmarlcd.games.foraging.rules.Foraging`.
"""

from __future__ import annotations

import numpy as np

from cmarlcd.compiled import kernel
from cmarlcd.games.spec import GameKernels

#: The actions.
NONE, NORTH, SOUTH, WEST, EAST, LOAD = range(6)
N_ACTIONS = 6
#: Row and column steps of each action (NONE and LOAD stay).
ACTION_ROW = np.array([0, -1, 1, 0, 0, 0], dtype=np.int64)
ACTION_COL = np.array([0, 0, 0, -1, 1, 0], dtype=np.int64)
#: Columns of ``players``.
ROW, COL, LEVEL = range(3)
#: A position not yet drawn (before the first reset).
NOWHERE = -1
#: Entries of ``rules``.
(
    ROWS,
    COLS,
    SIGHT,
    MAX_STEPS,
    FORCE_COOP,
    MIN_PLAYER_LEVEL,
    MAX_PLAYER_LEVEL,
    MIN_FOOD_LEVEL,
    MAX_FOOD_LEVEL,
    MAX_FOODS,
    MASK_INVALID,
    FOOD_LEVELS,
) = range(12)
N_RULES = 12
#: ``rules[MAX_FOOD_LEVEL]`` when the sum of the three lowest agent levels sets it.
FROM_PLAYERS = -1
#: Entries of ``status``.
STEP, FOOD_SPAWNED, OVER = range(3)
#: Draws a reset makes at most for each agent, and for all foods together (the package's).
ATTEMPTS = 1000
#: Agents whose levels make the default largest food level.
LOWEST_LEVELS = 3


def new_env(
    players: int, rows: int, cols: int, rules: np.ndarray, penalty: float
) -> tuple[np.ndarray, ...]:
    """The state arrays of one game:

    * ``players`` (P, 3) int64: each agent's ROW, COL (NOWHERE before the first reset) and
      LEVEL;
    * ``field`` (rows, cols) int64: the level of the food on each cell (0: none);
    * ``rules`` (N_RULES,) int64: the rules' numbers (:class:`~.rules.Foraging`);
    * ``status`` (3,) int64: the STEP of the episode, FOOD_SPAWNED, whether it is OVER
      (every food collected);
    * ``rewards`` (P + 1,) float64: each agent's reward of the last step, then the penalty;
    * ``scratch`` (2, P) int64: each agent's target cell and whether it loads.
    """
    people = np.zeros((players, 3), dtype=np.int64)
    people[:, ROW] = NOWHERE
    people[:, COL] = NOWHERE
    rewards = np.zeros(players + 1, dtype=np.float64)
    rewards[players] = penalty
    return (
        people,
        np.zeros((rows, cols), dtype=np.int64),
        rules.astype(np.int64),
        np.zeros(3, dtype=np.int64),
        rewards,
        np.zeros((2, players), dtype=np.int64),
    )


# ------------------------------------------------------------------------- reset


@kernel
def uniform_int(rng, low: int, high: int) -> int:
    """A uniform integer in ``[low, high)`` from one draw of ``rng``."""
    return low + min(int((high - low) * rng.random()), high - low - 1)


@kernel
def agent_at(players, row: int, col: int) -> bool:
    """Whether an agent stands (or stood, for one not yet placed) on ``(row, col)``."""
    for i in range(players.shape[0]):  # noqa: SIM110  (numba: no any() of a generator)
        if players[i, ROW] == row and players[i, COL] == col:
            return True
    return False


@kernel
def food_near(field, row: int, col: int) -> bool:
    """Whether a food lies within one cell of ``(row, col)`` (diagonals included), or
    two cells in line with it: where the package places no new food."""
    rows, cols = field.shape
    for r in range(max(row - 1, 0), min(row + 2, rows)):
        for c in range(max(col - 1, 0), min(col + 2, cols)):
            if field[r, c] > 0:
                return True
    for r in range(max(row - 2, 0), min(row + 3, rows)):
        if field[r, col] > 0:
            return True
    for c in range(max(col - 2, 0), min(col + 3, cols)):  # noqa: SIM110  (as above)
        if field[row, c] > 0:
            return True
    return False


@kernel
def lowest_levels_sum(players, count: int) -> int:
    """The sum of the ``count`` lowest agent levels (all of them, where fewer)."""
    n = players.shape[0]
    total, taken, last, last_index = 0, 0, -1, -1
    while taken < min(count, n):
        best, best_index = -1, -1
        for i in range(n):
            level = players[i, LEVEL]
            later = level > last or (level == last and i > last_index)
            if later and (best_index < 0 or level < best):
                best, best_index = level, i
        total += best
        last, last_index = best, best_index
        taken += 1
    return total


@kernel
def forage_reset(env, rng) -> None:
    """Protocol ``reset``: agents, then foods, placed as the package places them."""
    players, field, rules, status, rewards, _ = env
    rows, cols = field.shape
    for r in range(rows):
        for c in range(cols):
            field[r, c] = 0
    low, high = rules[MIN_PLAYER_LEVEL], rules[MAX_PLAYER_LEVEL]
    for i in range(players.shape[0]):
        rewards[i] = 0.0
        for _ in range(ATTEMPTS):
            row, col = uniform_int(rng, 0, rows), uniform_int(rng, 0, cols)
            if not agent_at(players, row, col):
                players[i, ROW], players[i, COL] = row, col
                players[i, LEVEL] = uniform_int(rng, low, high + 1)
                break
    top = rules[MAX_FOOD_LEVEL]
    if top == FROM_PLAYERS:
        top = lowest_levels_sum(players, LOWEST_LEVELS)
    bottom = top if rules[FORCE_COOP] else rules[MIN_FOOD_LEVEL]
    placed, attempts, spawned = 0, 0, 0
    while placed < rules[MAX_FOODS] and attempts < ATTEMPTS:
        attempts += 1
        row, col = uniform_int(rng, 1, rows - 1), uniform_int(rng, 1, cols - 1)
        if food_near(field, row, col) or agent_at(players, row, col):
            continue
        level = bottom if bottom == top else uniform_int(rng, bottom, top + 1)
        field[row, col] = level
        spawned += level
        placed += 1
    status[STEP], status[FOOD_SPAWNED], status[OVER] = 0, spawned, 0


# ------------------------------------------------------------------------- step


@kernel
def food_next_to(field, row: int, col: int) -> int:
    """The levels of the foods next to ``(row, col)`` summed, as the package sums them
    (its own cell where a neighbour is off the grid): > 0 where LOAD is valid."""
    rows, cols = field.shape
    return (
        field[max(row - 1, 0), col]
        + field[min(row + 1, rows - 1), col]
        + field[row, max(col - 1, 0)]
        + field[row, min(col + 1, cols - 1)]
    )


@kernel
def is_valid(field, players, i: int, action: int) -> bool:
    """Whether agent ``i`` may play ``action`` now."""
    row, col = players[i, ROW], players[i, COL]
    if action == NONE:
        return True
    if action == LOAD:
        return food_next_to(field, row, col) > 0
    r, c = row + ACTION_ROW[action], col + ACTION_COL[action]
    rows, cols = field.shape
    return 0 <= r < rows and 0 <= c < cols and field[r, c] == 0


@kernel
def food_of(field, row: int, col: int) -> int:
    """The cell (``row * cols + col``) of the food an agent at ``(row, col)`` loads, in
    the package's order of looking (above, below, left, right; its tests ``row > 1``
    and ``col > 1`` kept, though no food lies where they differ from ``> 0``); -1: none."""
    rows, cols = field.shape
    if row > 1 and field[row - 1, col] > 0:
        return (row - 1) * cols + col
    if row < rows - 1 and field[row + 1, col] > 0:
        return (row + 1) * cols + col
    if col > 1 and field[row, col - 1] > 0:
        return row * cols + col - 1
    if col < cols - 1 and field[row, col + 1] > 0:
        return row * cols + col + 1
    return -1


@kernel
def forage_step(env, joint, rng, team_rewards) -> None:
    """Protocol ``step``: invalid actions played as NONE, moves without collisions made,
    then every food with loaders next to it loaded or not; ``team_rewards[0]`` := the sum
    of the agents' rewards (in agent order)."""
    players, field, _, status, rewards, scratch = env
    n = players.shape[0]
    rows, cols = field.shape
    penalty = rewards[n]
    status[STEP] += 1
    target, loads = scratch[0], scratch[1]
    for i in range(n):
        rewards[i] = 0.0
        action = joint[i]
        if not is_valid(field, players, i, action):
            action = NONE
        loads[i] = action == LOAD
        row, col = players[i, ROW] + ACTION_ROW[action], players[i, COL] + ACTION_COL[action]
        target[i] = row * cols + col
    for i in range(n):  # agents alone in aiming at their cell go there
        alone = True
        for j in range(n):
            if j != i and target[j] == target[i]:
                alone = False
                break
        if alone:
            players[i, ROW], players[i, COL] = target[i] // cols, target[i] % cols
    for i in range(n):  # loaders, grouped by the food next to them (at most one)
        if not loads[i]:
            continue
        cell = food_of(field, players[i, ROW], players[i, COL])
        if cell < 0:  # (a valid LOAD always has its food)
            loads[i] = 0
            continue
        group_level = 0
        for j in range(i, n):
            if loads[j] and food_of(field, players[j, ROW], players[j, COL]) == cell:
                group_level += players[j, LEVEL]
        frow, fcol = cell // cols, cell % cols
        food = field[frow, fcol]
        for j in range(i, n):
            if loads[j] and food_of(field, players[j, ROW], players[j, COL]) == cell:
                loads[j] = 0
                if group_level < food:
                    rewards[j] -= penalty
                else:
                    rewards[j] = float(players[j, LEVEL] * food) / float(
                        group_level * status[FOOD_SPAWNED]
                    )
        if group_level >= food:
            field[frow, fcol] = 0
    left = 0
    for r in range(rows):
        for c in range(cols):
            left += field[r, c]
    status[OVER] = left == 0
    total = 0.0
    for i in range(n):
        total += rewards[i]
    team_rewards[0] = total


# ------------------------------------------------------------------------- views


@kernel
def forage_done(env) -> bool:
    """Protocol ``done``: no food is left (the step cap is the protocol's, a truncation:
    see the module docstring)."""
    return env[3][OVER] != 0


@kernel
def forage_legal(env, masks) -> None:
    """Protocol ``legal``: every action (``mask_invalid`` off, as the package's own
    spaces and EPyMARL see it: an invalid action is played as NONE), or the valid ones."""
    players, field, rules = env[0], env[1], env[2]
    for i in range(players.shape[0]):
        for a in range(masks.shape[1]):
            masks[i, a] = a < N_ACTIONS and (
                rules[MASK_INVALID] == 0 or is_valid(field, players, i, a)
            )


@kernel
def observe(env, i: int, out, at: int) -> None:
    """Agent ``i``'s observation in the package's vector layout (see the module
    docstring) into ``out[at : at + 3 * max_foods + 3 * players]``."""
    players, field, rules = env[0], env[1], env[2]
    n = players.shape[0]
    rows, cols = field.shape
    sight, foods = rules[SIGHT], rules[MAX_FOODS]
    row, col = players[i, ROW], players[i, COL]
    top, left = max(row - sight, 0), max(col - sight, 0)
    slot = 0
    for r in range(top, min(row + sight + 1, rows)):
        for c in range(left, min(col + sight + 1, cols)):
            if field[r, c] > 0 and slot < foods:
                out[at + 3 * slot] = r - top
                out[at + 3 * slot + 1] = c - left
                out[at + 3 * slot + 2] = field[r, c]
                slot += 1
    for k in range(slot, foods):
        out[at + 3 * k] = -1.0
        out[at + 3 * k + 1] = -1.0
        out[at + 3 * k + 2] = 0.0
    base, slot = 3 * foods, 0
    for k in range(n):
        j = i if k == 0 else (k - 1 if k - 1 < i else k)  # itself first, then in order
        r, c = players[j, ROW] - top, players[j, COL] - left
        if min(r, c) >= 0 and max(r, c) <= 2 * sight:
            out[at + base + 3 * slot] = r
            out[at + base + 3 * slot + 1] = c
            out[at + base + 3 * slot + 2] = players[j, LEVEL]
            slot += 1
    for k in range(slot, n):
        out[at + base + 3 * k] = -1.0
        out[at + base + 3 * k + 1] = -1.0
        out[at + base + 3 * k + 2] = 0.0


@kernel
def forage_features(env, team: int, out) -> None:
    """Protocol ``features``: every agent's observation (:func:`observe`), joined in
    agent order."""
    n = env[0].shape[0]
    width = 3 * env[2][MAX_FOODS] + 3 * n
    for i in range(n):
        observe(env, i, out, i * width)


@kernel
def forage_state(env, team: int) -> int:
    """Protocol ``state``: the state as one index (mixed radix): each agent's cell and
    level, then the foods in row-major order, each ``1 + cell * levels + level - 1``
    (``0`` for a slot without food). Only a game whose count of indices fits 62 bits
    reads it (:attr:`~.rules.Foraging.n_states`); elsewhere it is 0."""
    players, field, rules = env[0], env[1], env[2]
    rows, cols = field.shape
    cells = rows * cols
    levels = rules[MAX_PLAYER_LEVEL] - rules[MIN_PLAYER_LEVEL] + 1
    food_levels = rules[FOOD_LEVELS]
    if food_levels == 0:
        return 0
    index, radix = 0, 1
    for i in range(players.shape[0]):
        index += (players[i, ROW] * cols + players[i, COL]) * radix
        radix *= cells
        index += (players[i, LEVEL] - rules[MIN_PLAYER_LEVEL]) * radix
        radix *= levels
    for r in range(rows):
        for c in range(cols):
            if field[r, c] > 0:
                index += (1 + (r * cols + c) * food_levels + field[r, c] - 1) * radix
                radix *= 1 + cells * food_levels
    return index


KERNELS = GameKernels(
    forage_reset, forage_step, forage_state, forage_done, forage_legal, forage_features
)
