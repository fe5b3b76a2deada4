"""EPyMARL's settings of the deep learners as a named preset (beyond the paper).

EPyMARL (Papoudakis et al., "Benchmarking multi-agent deep reinforcement learning
algorithms in cooperative tasks", NeurIPS 2021 Datasets and Benchmarks; repository
uoe-agents/epymarl at commit cbc38c0) fixes the settings the field reports its learners
with: ``src/config/default.yaml`` and ``src/config/algs/{iql,vdn,qmix}.yaml``. This module
sets a :class:`~cmarlcd.learners.deep.config.DeepConfig` to them for a task whose
episodes last at most ``episode_steps`` environment steps.

EPyMARL counts its replay, its batches, its training rhythm and its target copies in
episodes; the compiled loop counts them in environment steps, because the seeds of one
stacked model pause together at the same step counts while their episodes end at
different ones. So an episode is taken as ``episode_steps`` steps: a batch of 32 episodes
is ``32 · episode_steps`` transitions, a buffer of 5,000 episodes ``5,000 ·
episode_steps``, one gradient step per ``episode_steps`` steps and a target copy every 200
of them. That is exact while episodes run to the step cap (LBF's do until food is
collected, simple_spread's always) and gives fewer gradient steps than EPyMARL's once
episodes end early. Every other difference is listed in :data:`DIFFERENCES`.
"""

from __future__ import annotations

from dataclasses import replace

from cmarlcd.errors import require
from cmarlcd.learners.deep.config import DeepConfig

#: The EPyMARL commit the settings are read from.
EPYMARL_COMMIT = "cbc38c0"
#: EPyMARL's algorithm config each mixer takes its settings from (hysteretic DQN is not
#: in EPyMARL: it is deep IQL with a smaller rate for negative errors, so IQL's).
ALGORITHM_OF = {"vdn": "vdn", "qmix": "qmix", "independent": "iql", "hysteretic": "iql"}
#: Per EPyMARL algorithm: the learning rate, the agents' hidden units and the steps over
#: which ε anneals (``lr``, ``hidden_dim``, ``epsilon_anneal_time``; the default.yaml's
#: 5e-4 and 64 where the algorithm's file sets none).
BY_ALGORITHM = {
    "iql": (3e-4, 128, 200_000),
    "vdn": (5e-4, 64, 50_000),
    "qmix": (5e-4, 64, 50_000),
}
#: The settings every algorithm shares: γ, ε's ends, the gradient norm clip, double Q,
#: standardised rewards, QMIX's mixing width (``mixing_embed_dim``), and the batch,
#: buffer and target-copy interval in episodes.
GAMMA, EPS_START, EPS_END, GRAD_CLIP, MIXING_EMBED = 0.99, 1.0, 0.05, 10.0, 32
BATCH_EPISODES, BUFFER_EPISODES, TARGET_EPISODES = 32, 5_000, 200

#: What the preset does not reproduce, and why (the docs list them: docs/anchors.md).
DIFFERENCES = (
    (
        "replay, batches, training and target copies",
        "in episodes (32-episode batches, a 5,000-episode buffer, a step per episode, "
        "a copy every 200)",
        "in environment steps, an episode taken as the task's step cap: the seeds of a "
        "stacked model pause at the same step counts; equal while episodes reach the cap",
    ),
    (
        "parameter sharing",
        "one agent network shared by the agents, the agent's one-hot id in its input",
        "a network per agent (EPyMARL's non-shared variant, which its paper also reports), "
        "so no id: an id is a constant input of an agent's own network; ``share=true`` "
        "(``--set LEARNER.share=true``) shares one with the id, as EPyMARL's configs",
    ),
    (
        "agent network",
        "two hidden layers of hidden_dim (IQL: a GRU for the second)",
        "one hidden layer of hidden_dim, the paper's; ``hidden_layers=2`` gives EPyMARL's "
        "feed-forward agent (``use_rnn=False``), stepped by autograd under ``step=auto`` "
        "(``step=fused`` takes it); no recurrent layer",
    ),
    (
        "QMIX's hypernetworks",
        "two layers (hypernet_embed 64) for the mixing weights",
        "one layer, the mixer of the paper's QMIX; ``hypernet_layers=2`` gives EPyMARL's "
        "(``hypernet_hidden`` 64), stepped by autograd under ``step=auto`` (``step=fused`` "
        "takes them)",
    ),
    (
        "batches",
        "32 whole episodes, every transition of each",
        "32 · cap transitions drawn one by one from the buffer: as many transitions, from "
        "more episodes, each drawn on its own (the buffer keeps transitions)",
    ),
    (
        "the step cap",
        "a termination on LBF: lbforaging 2.0.0 reports its 50th step as done and EPyMARL's "
        "gym wrapper passes no time-limit flag, so the runner stores it as terminated and "
        "the TD target does not bootstrap there",
        "a truncation (the games' [choice]): the target bootstraps at the cap, since the "
        "step count is in no observation",
    ),
    (
        "ε within an episode",
        "fixed at the steps done when the episode began",
        "the steps done before each step",
    ),
)


def epymarl_config(config: DeepConfig, episode_steps: int) -> DeepConfig:
    """``config`` (VDN, QMIX, deep IQL or hysteretic DQN; its mixer and its hysteretic
    rate kept) with EPyMARL's settings for a task of ``episode_steps``-step episodes."""
    require(episode_steps >= 1, "episode_steps", f"must be >= 1 (got {episode_steps})")
    lr, hidden, anneal = BY_ALGORITHM[ALGORITHM_OF[config.mixer]]
    return replace(
        config,
        hidden=hidden,
        mixer_hidden=MIXING_EMBED,
        buffer_size=BUFFER_EPISODES * episode_steps,
        batch_size=BATCH_EPISODES * episode_steps,
        train_every=episode_steps,
        target_every=TARGET_EPISODES * episode_steps,
        lr=lr,
        gamma=GAMMA,
        eps_start=EPS_START,
        eps_end=EPS_END,
        anneal_steps=anneal,
        double_q=True,
        grad_clip=GRAD_CLIP,
        standardise_rewards=True,
    )
