"""MPE's simple_spread (``mpe2`` 1.1.1, ``simple_spread_v3``, discrete actions), compiled.

N agents and N landmarks on the plane; the agents must cover the landmarks without
colliding. Every rule below is the package's (``mpe2/_mpe_utils/core.py``, ``simple_env.py``
and ``simple_spread/simple_spread.py``); ``benchmarks/check_spread.py`` holds the compiled
step against it.

**Actions** (per agent): 0 none, 1 left (x - 1), 2 right, 3 down (y - 1), 4 up: a push
``u`` of 5 (the package's sensitivity) along that axis.

**A step** (the package's world step): each agent's force is its push, plus, for every
pair of agents (landmarks do not collide), a contact force ``F = c · Δ / d · k ·
log(1 + exp(-(d - d_min) / k))`` on the first (``Δ`` = its position less the other's,
``d`` their distance, ``d_min`` = 0.3, the two radii, ``c`` = 100, ``k`` = 0.001) and its
opposite on the second. Then every agent moves: position += velocity · dt, velocity ×= 1 -
damping, velocity += force / mass · dt (dt 0.1, damping 0.25, mass 1).

**Rewards**: the global reward ``-Σ_landmarks min_agents distance`` and each agent's own,
``-1`` for every other agent closer than 0.3; agent ``i`` gets ``global · (1 - local_ratio)
+ own_i · local_ratio``, and the team reward is the sum of the agents' (in agent order).
The episode never terminates; the protocol's cap (``max_cycles``, 25) truncates it.

**Observations** (per agent, float32): its velocity, its position, each landmark's
position relative to it, each other agent's relative position (in agent order), and two
zeros per other agent (the silent agents' communication): ``4 + 2N + 4(N - 1)`` numbers.

**A reset** draws every agent's position, then every landmark's, uniform in
``[-1, 1]²`` (x then y), velocities zero; from the loop's generator, so the same
distribution as the package's, not the same episodes.

The state arrays ``env = (agents, landmarks, params, force, rewards)`` are made by
:func:`new_env`.
"""

from __future__ import annotations

import numpy as np

from cmarlcd.compiled import kernel
from cmarlcd.games.spec import GameKernels

#: The actions: none, then a push along -x, +x, -y, +y.
N_ACTIONS = 5
PUSH_AXIS = np.array([0, 0, 0, 1, 1], dtype=np.int64)
PUSH_SIGN = np.array([0.0, -1.0, 1.0, -1.0, 1.0])
#: Columns of ``agents``: position x, y and velocity x, y.
X, Y, VX, VY = range(4)
#: Entries of ``params`` (the package's constants, then the task's).
(
    LOCAL_RATIO,
    DT,
    DAMPING,
    CONTACT_FORCE,
    CONTACT_MARGIN,
    RADIUS,
    SENSITIVITY,
    MASS,
    TEAM_MEAN,
) = range(9)
N_PARAMS = 9
#: The package's world and agents.
PACKAGE_PARAMS = {
    DT: 0.1,
    DAMPING: 0.25,
    CONTACT_FORCE: 1e2,
    CONTACT_MARGIN: 1e-3,
    RADIUS: 0.15,
    SENSITIVITY: 5.0,
    MASS: 1.0,
}
#: The positions' range at a reset.
SPAWN = 1.0


def new_env(agents: int, local_ratio: float, team_mean: bool = False) -> tuple[np.ndarray, ...]:
    """The state arrays of one game:

    * ``agents`` (N, 4) float64: each agent's position and velocity (X, Y, VX, VY);
    * ``landmarks`` (N, 2) float64: each landmark's position;
    * ``params`` (N_PARAMS,) float64: the physics and ``local_ratio``;
    * ``force`` (N, 2) float64: scratch, each agent's force this step;
    * ``rewards`` (N,) float64: each agent's reward of the last step.
    """
    params = np.zeros(N_PARAMS, dtype=np.float64)
    for entry, value in PACKAGE_PARAMS.items():
        params[entry] = value
    params[LOCAL_RATIO] = local_ratio
    params[TEAM_MEAN] = float(team_mean)
    return (
        np.zeros((agents, 4), dtype=np.float64),
        np.zeros((agents, 2), dtype=np.float64),
        params,
        np.zeros((agents, 2), dtype=np.float64),
        np.zeros(agents, dtype=np.float64),
    )


@kernel
def spread_reset(env, rng) -> None:
    """Protocol ``reset``: agents then landmarks at uniform positions, at rest."""
    agents, landmarks, _, _, rewards = env
    for i in range(agents.shape[0]):
        agents[i, X] = -SPAWN + 2 * SPAWN * rng.random()
        agents[i, Y] = -SPAWN + 2 * SPAWN * rng.random()
        agents[i, VX] = 0.0
        agents[i, VY] = 0.0
        rewards[i] = 0.0
    for k in range(landmarks.shape[0]):
        landmarks[k, 0] = -SPAWN + 2 * SPAWN * rng.random()
        landmarks[k, 1] = -SPAWN + 2 * SPAWN * rng.random()


@kernel
def distance(ax: float, ay: float, bx: float, by: float) -> float:
    dx, dy = ax - bx, ay - by
    return np.sqrt(dx * dx + dy * dy)


@kernel
def contact(env, a: int, b: int) -> None:
    """Add the contact force between agents ``a`` and ``b`` to both (the package's
    ``get_collision_force``, its order of operations kept)."""
    agents, _, params, force, _ = env
    dx, dy = agents[a, X] - agents[b, X], agents[a, Y] - agents[b, Y]
    dist = np.sqrt(dx * dx + dy * dy)
    margin = params[CONTACT_MARGIN]
    penetration = np.logaddexp(0.0, -(dist - 2 * params[RADIUS]) / margin) * margin
    fx = params[CONTACT_FORCE] * dx / dist * penetration
    fy = params[CONTACT_FORCE] * dy / dist * penetration
    force[a, 0], force[a, 1] = fx + force[a, 0], fy + force[a, 1]
    force[b, 0], force[b, 1] = -fx + force[b, 0], -fy + force[b, 1]


@kernel
def spread_step(env, joint, rng, team_rewards) -> None:
    """Protocol ``step``: the pushes and contacts, the agents moved, the rewards;
    ``team_rewards[0]`` := the sum of the agents' rewards."""
    agents, landmarks, params, force, rewards = env
    n = agents.shape[0]
    for i in range(n):
        force[i, 0], force[i, 1] = 0.0, 0.0
        action = joint[i]
        if action > 0:
            force[i, PUSH_AXIS[action]] = PUSH_SIGN[action] * params[SENSITIVITY]
    for a in range(n):
        for b in range(a + 1, n):
            contact(env, a, b)
    dt, keep, mass = params[DT], 1.0 - params[DAMPING], params[MASS]
    for i in range(n):
        agents[i, X] += agents[i, VX] * dt
        agents[i, Y] += agents[i, VY] * dt
        agents[i, VX] = agents[i, VX] * keep + force[i, 0] / mass * dt
        agents[i, VY] = agents[i, VY] * keep + force[i, 1] / mass * dt
    covered = 0.0
    for k in range(landmarks.shape[0]):
        nearest = np.inf
        for i in range(n):
            nearest = min(
                nearest, distance(agents[i, X], agents[i, Y], landmarks[k, 0], landmarks[k, 1])
            )
        covered -= nearest
    ratio, limit = params[LOCAL_RATIO], 2 * params[RADIUS]
    total = 0.0
    for i in range(n):
        own = 0.0
        for j in range(n):
            if j != i and distance(agents[i, X], agents[i, Y], agents[j, X], agents[j, Y]) < limit:
                own -= 1.0
        rewards[i] = covered * (1 - ratio) + own * ratio
        total += rewards[i]
    team_rewards[0] = total / n if params[TEAM_MEAN] else total


@kernel
def spread_done(env) -> bool:
    """Protocol ``done``: never (the protocol's cap, ``max_cycles``, truncates)."""
    return False


@kernel
def spread_legal(env, masks) -> None:
    """Protocol ``legal``: every action, always."""
    for i in range(masks.shape[0]):
        for a in range(masks.shape[1]):
            masks[i, a] = a < N_ACTIONS


@kernel
def spread_state(env, team: int) -> int:
    """Protocol ``state``: 0 (a continuous state has no index; only learners that read
    features play it)."""
    return 0


@kernel
def observe(env, i: int, out, at: int) -> None:
    """Agent ``i``'s observation (see the module docstring) into ``out[at:]``."""
    agents, landmarks = env[0], env[1]
    n = agents.shape[0]
    x, y = agents[i, X], agents[i, Y]
    out[at], out[at + 1], out[at + 2], out[at + 3] = agents[i, VX], agents[i, VY], x, y
    k = at + 4
    for m in range(landmarks.shape[0]):
        out[k], out[k + 1] = landmarks[m, 0] - x, landmarks[m, 1] - y
        k += 2
    for j in range(n):
        if j != i:
            out[k], out[k + 1] = agents[j, X] - x, agents[j, Y] - y
            k += 2
    for j in range(2 * (n - 1)):
        out[k + j] = 0.0


@kernel
def spread_features(env, team: int, out) -> None:
    """Protocol ``features``: every agent's observation, joined in agent order (mpe2's
    ``state()``)."""
    n = env[0].shape[0]
    width = 4 + 2 * n + 4 * (n - 1)
    for i in range(n):
        observe(env, i, out, i * width)


KERNELS = GameKernels(
    spread_reset, spread_step, spread_state, spread_done, spread_legal, spread_features
)
