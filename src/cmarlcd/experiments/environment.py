"""Beyond the paper: any learner on any PettingZoo ``ParallelEnv`` with discrete actions.

A run makes the environment from ``MODULE:FACTORY`` (with keyword arguments), learns for
``episodes`` episodes through the generic loop (:func:`cmarlcd.training.episodes.play_copies`,
one Python call per step: an environment of the user's is no compiled kernel) over
``envs`` copies of it played in lockstep (a deep learner acts for all of them with one
forward pass and feeds one replay; each copy's reset seed derived from the run's), and
evaluates the greedy joint policy for ``eval_episodes`` episodes on an environment of its
own at ``curve_points`` evenly spaced budgets: a learning curve. The team's reward is the
agents' rewards summed or averaged (``reward``, a named choice); the learners read the
environment's ``state()``, the agents' observations joined, or, for VDN and QMIX, each
agent its own observation while the mixer reads the state (``inputs``, a named
choice). A uniform random policy is run beside them as the baseline (``"random"``).

The deep learners read a ``Discrete`` state one-hot and anything else as a flat feature
vector; the tabular learners need a discrete state (an integer, or any hashable value:
their tables grow with the states met).
"""

from __future__ import annotations

import importlib
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, Self

import gymnasium
import numpy as np

from cmarlcd import registry
from cmarlcd.errors import ConfigError, require
from cmarlcd.experiments.env_inputs import (
    INPUTS,
    StateShape,
    check_deep_inputs,
    check_reads_own_observations,
    state_shape,
    wrapped,
)
from cmarlcd.experiments.episodic import options_of
from cmarlcd.learners.deep.config import DeepLearnerConfig
from cmarlcd.limits import (
    check_at_most,
    check_episodes,
    check_run_count,
    check_seed,
    check_steps,
)
from cmarlcd.policies.keeping import POLICY, wanted
from cmarlcd.policies.learned import policy_of
from cmarlcd.progress import report_progress
from cmarlcd.registry import LearnerConfig
from cmarlcd.run_logs import log_point
from cmarlcd.runs import Experiment, RunSpec, Settings, added_setting, identity
from cmarlcd.training.episodes import play_copies
from cmarlcd.training.loop import BUDGET_UNITS

EXPERIMENT = "train"
#: The uniform random policy, run beside the learners as the baseline.
RANDOM = "random"
#: [choice] How the agents' rewards make the team's: their sum (default) or mean.
REWARDS: dict[str, Callable[[Mapping[str, float]], float]] = {
    "sum": lambda rewards: float(sum(rewards.values())),
    "mean": lambda rewards: float(np.mean(list(rewards.values()))),
}
#: [choice] Points of the learning curve, each a greedy evaluation of ``eval_episodes``.
CURVE_POINTS = 10
MAX_CURVE_POINTS = 100
#: The most copies of the environment a run plays at once.
MAX_ENVS = 1024
#: [choice] Copies a ``train`` run plays at once unless told: measured on simple_spread
#: (the benchmarks page), VDN learns at 0.36x the bare environment's random-action rate
#: with one copy, 0.69x with 4, 0.78x with 16 and 0.80x with 64, and at equal
#: environment steps 16 copies learn what one does; 16 is where the gain levels off.
#: ``EnvRun.envs`` keeps 1 as its identity's base, so runs stored with one copy resume
#: under ``--envs 1`` (a command without it now makes runs of 16 copies, new ones).
DEFAULT_ENVS = 16
#: [choice] For progress only: a budget of environment steps counts as episodes of this
#: many steps (an environment's episode length is not known before it is played).
PROGRESS_EPISODE_STEPS = 25

EnvKwargs = tuple[tuple[str, Any], ...]


def load_factory(path: str) -> Callable[..., Any]:
    """``"mpe2.simple_spread_v3:parallel_env"`` -> that callable, or one clear error."""
    module_name, colon, attribute = path.partition(":")
    require(
        bool(colon and module_name and attribute), "env", f"expected MODULE:FACTORY (got {path!r})"
    )
    try:
        module = importlib.import_module(module_name)
    except ImportError as error:
        raise ConfigError("env", f"cannot import {module_name!r} ({error})") from None
    factory = getattr(module, attribute, None)
    require(callable(factory), "env", f"{module_name} has no callable {attribute!r}")
    return factory


def make_env(path: str, kwargs: EnvKwargs) -> Any:
    """The environment of ``path`` called with ``kwargs``, checked: a ``ParallelEnv``
    (``reset``, ``step``, ``possible_agents``) whose agents all act from ``Discrete``
    spaces."""
    try:
        env = load_factory(path)(**dict(kwargs))
    except ConfigError:
        raise
    except Exception as error:  # the user's factory: any failure is theirs to read
        raise ConfigError("env", f"{path}({kwargs_text(kwargs)}) failed: {error}") from None
    for method in ("reset", "step", "action_space"):
        require(hasattr(env, method), "env", f"{path} made no PettingZoo ParallelEnv (no {method})")
    agents = list(getattr(env, "possible_agents", []))
    require(len(agents) > 0, "env", f"{path} made an environment without possible_agents")
    for agent in agents:
        space = env.action_space(agent)
        require(
            isinstance(space, gymnasium.spaces.Discrete),
            "env",
            f"{agent} acts from {space}: the learners take discrete actions only",
        )
    return env


def declared_episode_steps(path: str, kwargs: EnvKwargs) -> int | None:
    """The episode length the environment declares: its ``max_cycles`` (PettingZoo's MPE
    and Butterfly environments keep it on the unwrapped environment); None where it
    declares none."""
    env = make_env(path, kwargs)
    for holder in (env, getattr(env, "unwrapped", None)):
        value = getattr(holder, "max_cycles", None)
        if isinstance(value, int) and not isinstance(value, bool) and value >= 1:
            return value
    return None


def kwargs_text(kwargs: EnvKwargs) -> str:
    """``(('N', 3),)`` -> ``"N=3"``."""
    return ", ".join(f"{k}={v!r}" for k, v in kwargs)


class RandomPolicy:
    """The uniform random joint policy over the legal actions (acts the same greedily)."""

    def __init__(self, counts: np.ndarray, seed: np.random.SeedSequence) -> None:
        self.counts, self.rng = counts, np.random.default_rng(seed)

    def act(self, state, masks=None, copy: int = 0) -> tuple[int, ...]:
        joint = []
        for i, count in enumerate(self.counts):
            legal = np.arange(count) if masks is None else np.flatnonzero(masks[i])
            joint.append(int(self.rng.choice(legal)))
        return tuple(joint)

    def greedy(self, state, masks=None) -> tuple[int, ...]:
        return self.act(state, masks)

    def observe(self, state, joint_action, reward: float, copy: int = 0) -> None:
        """Nothing to learn."""

    def end_episode(self, final_state=None, terminated: bool = True, copy: int = 0) -> None:
        """Nothing to learn."""


def new_learner(
    config: LearnerConfig | None,
    counts: np.ndarray,
    shape: StateShape,
    total: int,
    seed,
    unit: str = "episodes",
) -> Any:
    """The object-API learner of ``config`` (None: the random policy); ``total``: the
    learning budget, in ``unit`` (episodes or environment steps)."""
    if config is None:
        return RandomPolicy(counts, seed)
    if isinstance(config, DeepLearnerConfig):
        from cmarlcd.learners.deep.agent import DeepAgent  # needs the [deep] extra
        from cmarlcd.learners.deep.coordination import DeepCMARLCDConfig
        from cmarlcd.learners.deep.degree_agent import DegreeAgent

        kind = DegreeAgent if isinstance(config, DeepCMARLCDConfig) else DeepAgent
        inputs = {"n_states": shape.n_states} if shape.n_states else {"state_dim": shape.dim}
        if shape.own_dim:
            check_reads_own_observations(config, "own-observations")
            inputs["own_dim"] = shape.own_dim
        return kind(counts, config, total, **inputs, seed=seed, unit=unit)
    from cmarlcd.learners.tabular.protocol import TabularLearner

    require(
        shape.dim is None,
        "algorithms",
        f"{config.name} keeps a table per state and needs discrete states; this "
        f"environment's are vectors of {shape.dim} numbers: use a deep learner",
    )
    return TabularLearner(counts, config, n_states=shape.n_states, seed=seed)


@dataclass(frozen=True)
class EnvRun(Settings):
    """One learner's runs on one environment."""

    env: str
    env_kwargs: EnvKwargs
    learner: LearnerConfig | None
    """None: the uniform random policy."""
    episodes: int
    eval_episodes: int
    curve_points: int = CURVE_POINTS
    reward: str = "sum"
    inputs: str = "state"
    envs: int = added_setting(1, "0.6.0")
    """Copies of the environment played at once (1: one at a time, as before)."""
    unit: str = added_setting("episodes", "0.7.0")
    """What ``episodes`` counts: learning episodes, or environment ``"steps"`` (a budget
    of steps ends at the end of the episodes in play when it is reached; the curve's
    points and a deep learner's ε count steps too)."""
    eval_at_start: bool = added_setting(False, "0.7.0")
    """Whether the curve starts with a greedy evaluation before any learning (a point at
    0, as the field's protocol has; the learner's own random draws at that evaluation,
    the random policy's among them, shift its later draws)."""

    @property
    def algorithm(self) -> str:
        return RANDOM if self.learner is None else self.learner.name

    def to_config(self) -> dict[str, Any]:
        config = {k: v for k, v in identity(self).items() if k not in ("learner", "env_kwargs")}
        config["env_kwargs"] = dict(self.env_kwargs)
        config["algorithm"] = self.algorithm
        if self.learner is not None:
            config["learner"] = identity(self.learner)
        return config

    @classmethod
    def from_config(cls, config: Mapping[str, Any]) -> Self:
        name = config["algorithm"]
        learner = None if name == RANDOM else registry.learner_config(name, config["learner"])
        kwargs = options_of(config["env_kwargs"])
        rest = {k: v for k, v in config.items() if k not in ("algorithm", "learner", "env_kwargs")}
        return cls(**{**rest, "env_kwargs": kwargs, "learner": learner})

    def stream(self) -> dict[str, Any]:
        """Everything but the evaluation's episodes (a stricter stream than needed:
        ``curve_points`` and, for a learner that does not anneal over it, ``episodes``
        change no draw either; kept, so that stored runs keep their seeds)."""
        return {k: v for k, v in self.to_config().items() if k not in ("eval_episodes",)}

    def budgets(self) -> list[int]:
        """The budgets the curve evaluates at (the last is ``episodes``; never 0)."""
        points = max(1, self.curve_points)
        return sorted({round(self.episodes * k / points) for k in range(1, points + 1)} - {0})

    def points(self) -> list[int]:
        """Every point of the curve: 0 first where it evaluates before learning, then the
        budgets."""
        return [0, *self.budgets()] if self.eval_at_start else self.budgets()


def run(settings: EnvRun, seed: np.random.SeedSequence) -> dict[str, Any]:
    """One run: learn, and evaluate greedily at every budget of the curve."""
    start = time.perf_counter()
    env_seed, learner_seed, eval_seed = seed.spawn(3)
    envs = make_copies(settings.env, settings.env_kwargs, settings.inputs, settings.envs)
    evaluating = min(settings.envs, settings.eval_episodes)  # copies an evaluation can use
    evaluations = make_copies(settings.env, settings.env_kwargs, settings.inputs, evaluating)
    shape, counts = check_copies(envs, settings.inputs, copy_seeds(env_seed, settings.envs))
    steps = settings.unit == "steps"
    learner = new_learner(
        settings.learner, counts, shape, settings.episodes, learner_seed, settings.unit
    )
    reward = REWARDS[settings.reward]
    curve, trained, started = [], 0, False
    for budget in settings.points():
        if budget > 0:  # 0: the evaluation before any learning
            first = None if started else copy_seeds(env_seed, settings.envs)
            started = True
            if steps:  # to the end of the episodes in play when the budget is reached
                learned = play_copies(
                    envs, learner, 0, global_reward=reward, seeds=first, steps=budget - trained
                )
                trained += int(learned.lengths.sum())
                report_progress(int(learned.lengths.sum()) / PROGRESS_EPISODE_STEPS)
            else:
                play_copies(envs, learner, budget - trained, global_reward=reward, seeds=first)
                report_progress(budget - trained)
                trained = budget
        point = point_seed(eval_seed, budget)
        stats = play_copies(
            evaluations, learner, settings.eval_episodes, learn=False,
            seeds=copy_seeds(point, evaluating), global_reward=reward,
        )  # fmt: skip
        report_progress(settings.eval_episodes)
        curve.append([budget, float(stats.returns.mean()), float(stats.lengths.mean())])
        log_point(0, budget, {"eval/return": curve[-1][1], "eval/episode_steps": curve[-1][2]},
                  settings.unit)  # the live curves (--log-dir)  # fmt: skip
    result = {"curve": curve, "seconds": time.perf_counter() - start}
    if hasattr(learner, "stored"):  # what a deep learner learned from: replay or memory
        result["stored"] = int(learner.stored)
    if wanted():  # --save-policies: the greedy policy it ended with (not stored)
        meta = {"inputs": settings.inputs, "agents": list(envs[0].possible_agents)}
        policy = policy_of(learner, meta)
        if policy is not None:
            result[POLICY] = policy
    return result


def point_seed(eval_seed: np.random.SeedSequence, budget: int) -> np.random.SeedSequence:
    """The seeds of the greedy evaluation at ``budget``: a stream of its own, which no
    draw of the learning changes."""
    return np.random.SeedSequence(eval_seed.entropy, spawn_key=(*eval_seed.spawn_key, budget))


def make_copies(path: str, kwargs: EnvKwargs, inputs: str, count: int) -> list[Any]:
    """``count`` copies of the environment, each made by its factory."""
    return [wrapped(make_env(path, kwargs), inputs) for _ in range(count)]


def copy_seeds(seed: np.random.SeedSequence, count: int) -> list[int]:
    """The first reset seeds of ``count`` copies: ``seed``'s own for copy 0 (so that one
    copy plays as a run always has), and for copy ``k`` its ``k``-th child key."""
    key, entropy = seed.spawn_key, seed.entropy
    children = (np.random.SeedSequence(entropy, spawn_key=(*key, k)) for k in range(1, count))
    return [_int_seed(seed), *(_int_seed(child) for child in children)]


def check_copies(envs: list[Any], inputs: str, seeds: list[int]) -> tuple[StateShape, np.ndarray]:
    """Reset each copy with its seed; the learners' input shape and action counts, the
    same in every copy (one clear error where two copies disagree)."""
    shapes, counts = [], []
    for env, seed in zip(envs, seeds, strict=True):
        env.reset(seed=seed)
        shapes.append(state_shape(env, inputs))
        counts.append([env.action_space(a).n for a in env.possible_agents])
    for k in range(1, len(envs)):
        require(
            shapes[k] == shapes[0] and counts[k] == counts[0],
            "envs",
            f"copies of the environment disagree: copy 0 has {_describe(shapes[0], counts[0])}, "
            f"copy {k} has {_describe(shapes[k], counts[k])}",
        )
    return shapes[0], np.array(counts[0], np.int64)


def _describe(shape: StateShape, counts: list[int]) -> str:
    inputs = f"{shape.n_states} states" if shape.n_states else f"{shape.dim} input features"
    return f"{inputs} and action counts {counts}"


def _int_seed(seed: np.random.SeedSequence) -> int:
    """An environment's ``reset(seed=…)`` takes an integer."""
    return int(seed.generate_state(1)[0])


@dataclass(frozen=True)
class EnvSweep:
    """Learners (and the random baseline) x runs on one environment."""

    env: str
    learners: tuple[LearnerConfig, ...]
    episodes: int
    runs: int
    eval_episodes: int
    env_kwargs: EnvKwargs = ()
    curve_points: int = CURVE_POINTS
    reward: str = "sum"
    inputs: str = "state"
    seed: int = 0
    envs: int = DEFAULT_ENVS
    unit: str = "episodes"
    """What ``episodes`` counts: learning episodes, or environment ``"steps"``."""
    eval_at_start: bool = False
    """Whether each curve starts with a greedy evaluation before learning."""

    def __post_init__(self) -> None:
        require(self.unit in BUDGET_UNITS, "unit", f"must be one of {BUDGET_UNITS}")
        require(
            self.reward in REWARDS,
            "reward",
            f"must be one of {', '.join(REWARDS)} (got {self.reward!r})",
        )
        require(
            self.inputs in INPUTS,
            "inputs",
            f"must be one of {', '.join(INPUTS)} (got {self.inputs!r})",
        )
        require(self.runs >= 1, "runs", f"must be >= 1 (got {self.runs})")
        budget = "steps" if self.unit == "steps" else "episodes"
        require(self.episodes >= 1, budget, f"must be >= 1 (got {self.episodes})")
        if self.unit == "steps":
            check_steps(self.episodes, "steps")
        else:
            check_episodes(self.episodes, "episodes")
        require(
            self.eval_episodes >= 1, "eval_episodes", f"must be >= 1 (got {self.eval_episodes})"
        )
        check_episodes(self.eval_episodes, "eval_episodes")
        require(self.curve_points >= 1, "curve_points", f"must be >= 1 (got {self.curve_points})")
        check_at_most(self.curve_points, MAX_CURVE_POINTS, "curve_points")
        check_seed(self.seed)
        names = [c.name for c in self.learners]
        require(len(set(names)) == len(names), "algorithms", f"each at most once (got {names})")
        check_run_count((len(self.learners) + 1) * self.runs)
        require(self.envs >= 1, "envs", f"must be >= 1 (got {self.envs})")
        check_at_most(self.envs, MAX_ENVS, "envs")
        # checked before anything runs, and every learner told whether it can read it
        copies = make_copies(self.env, self.env_kwargs, self.inputs, min(self.envs, 2))
        try:
            shape, _ = check_copies(copies, self.inputs, list(range(len(copies))))
        except ConfigError:
            raise
        except Exception as error:  # the user's environment: its failure is theirs to read
            raise ConfigError("env", f"{self.env}: reset failed: {error}") from None
        for config in self.learners:
            check_reads_own_observations(config, self.inputs)
            if isinstance(config, DeepLearnerConfig):
                check_deep_inputs(shape)
            else:
                new_learner(config, np.ones(1, np.int64), shape, 1, np.random.SeedSequence(0))

    def settings(self, learner: LearnerConfig | None) -> EnvRun:
        return EnvRun(
            self.env, self.env_kwargs, learner, self.episodes, self.eval_episodes,
            self.curve_points, self.reward, self.inputs, self.envs, self.unit,
            self.eval_at_start,
        )  # fmt: skip

    def specs(self) -> list[RunSpec]:
        """The random baseline's runs, then each learner's."""
        return [
            RunSpec.make(EXPERIMENT, s.algorithm, s, self.seed, r)
            for s in (self.settings(None), *(self.settings(c) for c in self.learners))
            for r in range(self.runs)
        ]


def _cost(settings: EnvRun) -> float:
    """[choice] A rough estimate, for progress only: 5 ms per learning episode of a deep
    learner, 1 ms otherwise, and 1 ms per evaluation episode."""
    deep = isinstance(settings.learner, DeepLearnerConfig)
    evaluated = settings.eval_episodes * len(settings.points())
    return _learned(settings) * (5e-3 if deep else 1e-3) + 1e-3 * evaluated


def _learned(settings: EnvRun) -> float:
    """The learning budget in episodes (a budget of steps in episodes of
    :data:`PROGRESS_EPISODE_STEPS` steps)."""
    if settings.unit == "steps":
        return settings.episodes / PROGRESS_EPISODE_STEPS
    return settings.episodes


def _work(settings: EnvRun) -> float:
    """Episodes one run plays: learning and evaluation."""
    return _learned(settings) + settings.eval_episodes * len(settings.points())


TRAIN = Experiment(
    EXPERIMENT,
    EnvRun,
    run,
    cost=_cost,
    work=_work,
    work_unit="episodes",
    uses_device=lambda settings: isinstance(settings.learner, DeepLearnerConfig),
    keeps_policies=lambda settings: True,
)
