"""EPyMARL's optional parts of the deep learners' TD step (beyond the paper): rewards
standardised by running statistics (``DeepConfig.standardise_rewards``) and each seed's
gradient norm clipped (``DeepConfig.grad_clip``), per seed of a stacked model."""

from __future__ import annotations

from collections.abc import Sequence

import torch


class RewardStatistics:
    """The running mean and variance of the rewards of every replay batch so far, one
    pair per seed: EPyMARL's ``RunningMeanStd`` (the parallel update of Chan et al.: a
    count that starts at 1e-4, a mean at 0 and a variance at 1; each batch's variance
    unbiased, as ``torch.var`` gives it)."""

    #: The count the statistics start from (EPyMARL's ``epsilon``).
    START_COUNT = 1e-4

    def __init__(self, seeds: int, device: torch.device) -> None:
        self.mean = torch.zeros(seeds, device=device)
        self.var = torch.ones(seeds, device=device)
        self.count = self.START_COUNT

    def standardise(self, reward: torch.Tensor) -> torch.Tensor:
        """Update with a batch's rewards (B, N), then return them standardised per seed:
        ``(r - mean) / sqrt(var)``."""
        n = reward.shape[1]
        batch_mean, batch_var = reward.mean(dim=1), reward.var(dim=1)
        delta, total = batch_mean - self.mean, self.count + n
        spread = self.var * self.count + batch_var * n + delta**2 * self.count * n / total
        self.mean = self.mean + delta * n / total
        self.var, self.count = spread / total, total
        return (reward - self.mean[:, None]) / torch.sqrt(self.var[:, None])


def clip_per_seed(params: Sequence[torch.Tensor], seeds: int, max_norm: float) -> None:
    """Scale each seed's gradients so that their L2 norm over all ``params`` is at most
    ``max_norm``, by ``torch.nn.utils.clip_grad_norm_``'s rule (a factor ``max_norm /
    (norm + 1e-6)`` where that is below 1). Every parameter's leading axis holds the
    seeds, seed-major (per agent within a seed for the agent networks), so a seed's
    gradient is its rows of each."""
    grads = [p.grad.view(seeds, -1) for p in params if p.grad is not None]
    if not grads:
        return
    norm = torch.stack([g.pow(2).sum(dim=1) for g in grads]).sum(dim=0).sqrt()
    scale = (max_norm / (norm + 1e-6)).clamp(max=1.0)
    for grad in grads:
        grad.mul_(scale[:, None])
