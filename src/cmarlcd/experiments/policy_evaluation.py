"""A kept policy played greedily again (``cmarl-cd evaluate``): on the environment of the
run that kept it, by default with that run's own last evaluation (the same copies, reset
seeds and episodes, so the same return as the store's last curve point), or for
``episodes`` episodes from ``seed``, or on another environment of the same shapes."""

from __future__ import annotations

from typing import Any

import numpy as np

from cmarlcd.errors import require
from cmarlcd.experiments import environment as envs
from cmarlcd.runs import RunSpec


def run_spec(meta: dict[str, Any]) -> RunSpec:
    """The run a policy file names (its identity and seeds)."""
    return RunSpec(meta["experiment"], meta["algorithm"], meta["config_json"],
                   int(meta["root_seed"]), int(meta["run_index"]), meta["stream_json"])  # fmt: skip


def evaluate_policy(
    policy: Any,
    episodes: int | None = None,
    seed: int | None = None,
    env: str | None = None,
    env_kwargs: envs.EnvKwargs | None = None,
) -> dict[str, Any]:
    """Play ``policy`` greedily; its mean return (the team's, as the run counted it)."""
    meta = policy.metadata
    require(
        meta.get("experiment") == envs.EXPERIMENT,
        "policy",
        f"a policy of {meta.get('experiment')}'s runs: evaluate plays those of train --env",
    )
    spec = run_spec(meta)
    settings = envs.EnvRun.from_config(spec.config)
    where, kwargs = env or settings.env, settings.env_kwargs if env_kwargs is None else env_kwargs
    own = episodes is None and seed is None and env is None and env_kwargs is None
    count = settings.eval_episodes if episodes is None else episodes
    require(count >= 1, "episodes", f"must be >= 1 (got {count})")
    copies = min(settings.envs, count)
    if own:  # the run's last evaluation: its point's seed sequence
        eval_seed = spec.seed_sequence().spawn(3)[2]
        point = np.random.SeedSequence(
            eval_seed.entropy, spawn_key=(*eval_seed.spawn_key, settings.episodes)
        )
    else:
        point = np.random.SeedSequence(0 if seed is None else seed)
    played = envs.make_copies(where, kwargs, settings.inputs, copies)
    _, counts = envs.check_copies(played, settings.inputs, envs.copy_seeds(point, copies))
    require(
        list(counts) == list(policy.counts),
        "env",
        f"{where}: its agents have {list(counts)} actions; the policy's {list(policy.counts)}",
    )
    from cmarlcd.training.episodes import play_copies

    stats = play_copies(
        played, policy, count, learn=False, seeds=envs.copy_seeds(point, copies),
        global_reward=envs.REWARDS[settings.reward],
    )  # fmt: skip
    return {
        "env": where, "env_kwargs": dict(kwargs), "algorithm": meta["algorithm"],
        "episodes": count, "mean_return": float(stats.returns.mean()),
        "std_return": float(stats.returns.std()), "mean_steps": float(stats.lengths.mean()),
        "seeds": "the run's last evaluation" if own else f"seed {0 if seed is None else seed}",
    }  # fmt: skip
