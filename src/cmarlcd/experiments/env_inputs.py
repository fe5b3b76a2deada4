"""What the learners of ``cmarl-cd train`` read of an environment (``inputs``, a named
choice): its ``state()``, every agent's observation joined, or each agent its own
observation beside the state; the wrappers that make the last two a ``state()``, and the
shape a learner is built for."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import gymnasium
import numpy as np

from cmarlcd.errors import ConfigError, require
from cmarlcd.learners.deep.config import OWN_OBSERVATION_LEARNERS
from cmarlcd.training.deep_kernels import MAX_INDEX_STATES

#: [choice] What the learners read: the environment's ``state()`` (default); every
#: agent's observation joined in agent order (for environments without a state); or
#: ``own-observations``: each agent's network its own observation and QMIX's mixer the
#: state (decentralised execution, as VDN and QMIX were published; VDN and QMIX only).
INPUTS = ("state", "observations", "own-observations")


class JoinedObservations:
    """An environment whose ``state()`` is every agent's last observation, flattened and
    joined in agent order (``inputs="observations"``)."""

    def __init__(self, env: Any) -> None:
        self.env, self.possible_agents = env, list(env.possible_agents)
        self._last: dict[str, Any] = {}

    @property
    def agents(self) -> list[str]:
        return self.env.agents

    def action_space(self, agent: str) -> Any:
        return self.env.action_space(agent)

    def reset(self, seed: int | None = None, options: dict | None = None):
        self._last, infos = self.env.reset(seed=seed, options=options)
        return self._last, infos

    def step(self, actions):
        observations, *rest = self.env.step(actions)
        self._last = {**self._last, **observations}
        return (observations, *rest)

    def state(self) -> np.ndarray:
        return np.concatenate(self._observations())

    def _observations(self) -> list[np.ndarray]:
        return [np.asarray(self._last[a], dtype=np.float32).ravel() for a in self.possible_agents]


class OwnObservations(JoinedObservations):
    """An environment whose ``state()`` is ``[s, o_1, ..., o_n]``: the environment's own
    ``state()`` (or, without one, the observations joined), then each agent's last
    observation, flattened and zero-padded to ``own_dim`` features
    (``inputs="own-observations"``)."""

    def __init__(self, env: Any) -> None:
        super().__init__(env)
        self.own_dim = 0

    def reset(self, seed: int | None = None, options: dict | None = None):
        result = super().reset(seed=seed, options=options)
        self.own_dim = max(o.size for o in self._observations())
        return result

    def state(self) -> np.ndarray:
        observations = self._observations()
        try:
            shared = np.asarray(self.env.state(), dtype=np.float32).ravel()
        except (NotImplementedError, AttributeError):
            shared = np.concatenate(observations)
        own = np.zeros((len(observations), self.own_dim), np.float32)
        for i, observation in enumerate(observations):
            own[i, : observation.size] = observation
        return np.concatenate([shared, own.ravel()])


@dataclass(frozen=True)
class StateShape:
    """What a learner reads: ``n_states`` discrete states, or ``dim`` features (of which
    the last ``n_agents * own_dim`` are the agents' own observations, where they read
    them)."""

    n_states: int | None
    dim: int | None
    own_dim: int | None = None


def state_shape(env: Any, inputs: str) -> StateShape:
    """How the learners read the environment's states (after a reset); one clear error
    where they cannot (no ``state()``, observations that are not arrays of numbers)."""
    try:
        if inputs == "state":
            space = getattr(env, "state_space", None)
            if isinstance(space, gymnasium.spaces.Discrete):
                return StateShape(int(space.n), None)
            state = env.state()
            if isinstance(state, int | np.integer):
                return StateShape(None, None)  # discrete, count unknown: tables grow
            return StateShape(None, int(np.asarray(state, dtype=np.float32).size))
        return StateShape(None, int(env.state().size), getattr(env, "own_dim", None))
    except (NotImplementedError, AttributeError):
        raise ConfigError(
            "inputs", "the environment has no state(): use --inputs observations"
        ) from None
    except (TypeError, ValueError) as error:
        raise ConfigError("inputs", f"its {inputs} is not an array of numbers ({error})") from None


def check_deep_inputs(shape: StateShape) -> None:
    """A deep learner reads a discrete state one-hot (at most :data:`MAX_INDEX_STATES` of
    them, counted by a ``Discrete`` state space) or a vector of features."""
    require(
        shape.dim is not None or shape.n_states is not None,
        "algorithms",
        "a deep learner reads a discrete state one-hot and needs its count: give the "
        "environment a Discrete state_space, or use --inputs observations",
    )
    count = shape.n_states or 0
    require(
        count <= MAX_INDEX_STATES,
        "algorithms",
        f"a deep learner reads discrete states one-hot, at most {MAX_INDEX_STATES:,} "
        f"(this environment has {count:,})",
    )


def check_reads_own_observations(config: Any, inputs: str) -> None:
    """One clear error where ``inputs`` is ``own-observations`` and the learner of
    ``config`` cannot read them."""
    if inputs != "own-observations":
        return
    learner = config.name
    require(
        learner in OWN_OBSERVATION_LEARNERS,
        "inputs",
        f"own-observations is for {', '.join(OWN_OBSERVATION_LEARNERS)}; "
        f"{learner} reads the state or the observations joined",
    )


def wrapped(env: Any, inputs: str) -> Any:
    wrappers = {"observations": JoinedObservations, "own-observations": OwnObservations}
    return wrappers[inputs](env) if inputs in wrappers else env
