"""Estimated costs of the runs of the episodic protocol (:mod:`cmarlcd.experiments.episodic`),
for progress and for ordering the work: seconds per learning and evaluation episode,
scaled to a game's size."""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from cmarlcd.experiments.episodic import EpisodicGame, EpisodicRun
    from cmarlcd.registry import LearnerConfig

#: Estimated seconds of a greedy evaluation episode on the DSN, and of a learning episode
#: by learner (a deep learner's with its share of gradient steps): fitted to measured
#: runs on the project's 2-core machine (the paper protocol's for VDN and QMIX, the quick
#: preset's for the others, benchmarks/fit_costs.py). A learner not listed is taken at
#: the slowest tabular learner's cost.
SECONDS_PER_EPISODE = 1e-6
LEARN_SECONDS_PER_EPISODE = {
    "cmarl-cd": 3e-6,
    "la-oca": 1.2e-6,
    "iql": 7.3e-6,
    "hysteretic": 5.9e-6,
    "lenient": 7.1e-6,
    "distributed-q": 4.7e-6,
    "vdn": 36e-6,
    "qmix": 106e-6,
    "deep-cmarl-cd": 2.5e-4,  # its 10-run row at --seed-batch 1 (docs: deep CMARL-CD)
}


def learn_seconds(learner: LearnerConfig) -> float:
    """Estimated seconds of one learning episode of ``learner``."""
    return LEARN_SECONDS_PER_EPISODE.get(learner.name, 7.3e-6)


def episode_scale(game: EpisodicGame, settings: EpisodicRun) -> float:
    """How much longer an episode of the game with the run's options is estimated to take
    than one of the game itself (whose costs are measured): agents x step cap."""
    if not settings.options:
        return 1.0
    base, sized = game.spec, game.with_options(settings.options).spec
    return (sized.n_agents * sized.max_steps) / (base.n_agents * base.max_steps)


def run_cost(game: EpisodicGame, settings: EpisodicRun) -> float:
    """Estimated seconds of one run: its learning episodes and its evaluation episodes
    (what the run reports as it goes, :func:`cmarlcd.progress.unit_cost`)."""
    max_steps = game.with_options(settings.options).spec.max_steps
    learned = settings.learned(max_steps)
    evaluated = settings.work(max_steps) - learned
    per_episode = learn_seconds(settings.learner) * learned + SECONDS_PER_EPISODE * evaluated
    return per_episode * episode_scale(game, settings)
