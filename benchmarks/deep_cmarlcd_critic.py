"""Diagnostic: what deep CMARL-CD's critic of joint actions (``update="critic"``) and its
degrees hold after one seed has learned a field task.

Where the selection run finds the critic design learning nothing, this locates the loss.
After ``--steps`` of learning it reads up to 4,000 visits of the seed's ring and prints:
the mean and largest return stored there (λ-returns: an overestimate that compounds shows
here first, against what a greedy episode earns), the critic's best value and its value
at the taken joint actions, the spread of its outputs (their standard deviation at a
visit, over the joint actions or, for ``critic_form="sum"`` and ``"degrees"``, the
agents' actions, averaged over the visits), the share of visits whose taken joint
action is the critic's best ``a*``, how many distinct ``a*`` there are, the share of
visits where the degrees' greedy joint action is ``a*`` (the agents following the
critic; with ``critic_form="degrees"`` the degrees are the critic, so always), and the
degrees' largest and smallest value (clipped; ``c_min`` 0.5 when they have sunk; the
shares of ``"degrees"`` unclipped).

    python benchmarks/deep_cmarlcd_critic.py foraging:2s-8x8-2p-2f-coop --steps 100k
    python benchmarks/deep_cmarlcd_critic.py foraging:2s-8x8-2p-2f-coop --steps 100k \\
        --set expectile=0.9,critic_bootstrap=best,critic_fit=tie

It starts from ``CRITIC_DEEP_CMARLCD`` at the field's discount (0.99); ``--set`` changes
any deep CMARL-CD setting. Needs the ``[deep]`` extra.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence

import numpy as np
from deep_cmarlcd_memory import arguments, task_and_settings  # the diagnostics' arguments

#: The most ring visits read.
VISITS = 4_000


def main(argv: Sequence[str] | None = None) -> int:
    args = arguments(__doc__, "foraging:2s-8x8-2p-2f-coop").parse_args(argv)
    from cmarlcd.errors import ConfigError, require
    from cmarlcd.learners.deep.designs import CRITIC_DEEP_CMARLCD

    try:
        spec, config, steps = task_and_settings(args, CRITIC_DEEP_CMARLCD)
        require(config.update == "critic", "update", "this diagnostic reads the critic (critic)")
        config.record_outputs(spec.action_counts)
    except ConfigError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    for name, value in report(spec, config, steps, args.seed).items():
        print(f"{name}: {value}")
    return 0


def report(spec, config, steps: int, seed: int) -> dict[str, str]:
    """Learn ``steps`` with one seed, then read the ring, the critic and the degrees."""
    import torch

    from cmarlcd.training.deep import DeepBatch

    run = DeepBatch(spec, config, [np.random.SeedSequence(seed)], steps, unit="steps")
    run.train([], lambda *args: None)
    model, replay = run.group.model, run.group.ring
    ring = getattr(replay, "ring", replay)
    stored = int(ring.size[0])
    if stored == 0:
        return {"visits stored": "0 (nothing to read: learn longer)"}
    rows = np.random.default_rng(seed).choice(stored, min(stored, VISITS), replace=False)
    state = torch.as_tensor(ring.state[0, rows])[None]
    actions = torch.as_tensor(ring.actions[0, rows].astype(np.int64))[None]
    returns = torch.as_tensor(ring.reward[0, rows])
    with torch.no_grad():
        degrees = model.agents(state)[0].clamp(*config.degree_bounds)
        greedy = model._masked(degrees[None], None)[0].argmax(dim=-1)
        if config.shares:  # the degrees are the critic: their sum at a joint action
            values = model._masked(degrees, None).flatten(1)[None]  # (1, N, n * A)
            best = greedy
            best_value = model.shares_at(degrees[None], best[None])[0]
            taken_value = model.shares_at(degrees[None], actions)[0]
        else:
            values = model.record.values(state)  # (1, N, K)
            best = model.critic_best(values)[0]  # (N, n)
            best_value = model.critic_at(values, best[None])[0]
            taken_value = model.critic_at(values, actions)[0]
        follows = (greedy == best).all(dim=-1)
        lowest = degrees.masked_fill(~model.valid[0], np.inf).amin(dim=-1)
        highest = degrees.masked_fill(~model.valid[0], -np.inf).amax(dim=-1)
    joint = int(np.prod(spec.action_counts))
    return {
        "visits read": f"{len(rows):,} of {stored:,}",
        "stored returns": f"mean {returns.mean():.4f}, largest {returns.max():.4f}, "
        f"above 0 {(returns > 0).float().mean():.1%}",
        "critic": f"best {best_value.mean():.4f}, at the taken joint action "
        f"{taken_value.mean():.4f}, spread over its outputs {spread(values[0]):.4f}",
        "a*": f"the taken joint action {(best == actions[0]).all(dim=-1).float().mean():.1%}, "
        f"{len({tuple(row) for row in best.tolist()})} distinct of {joint}",
        "degrees' greedy joint action = a*": f"{follows.float().mean():.1%}",
        "degrees": f"largest {highest.mean():.3f}, smallest {lowest.mean():.3f}",
    }


def spread(values) -> float:
    """The outputs' standard deviation at each visit (over its finite ones: an agent's
    real actions where the degrees are the critic), averaged over the visits."""
    finite = values.isfinite()
    count = finite.sum(dim=-1)
    mean = values.where(finite, 0).sum(dim=-1) / count
    square = ((values - mean[:, None]) ** 2).where(finite, 0).sum(dim=-1) / count
    return float(square.sqrt().mean())


if __name__ == "__main__":
    raise SystemExit(main())
