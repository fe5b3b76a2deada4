"""Trained greedy policies kept as files, loaded and played again (beyond the paper).

A run computed with ``--save-policies DIR`` leaves its final greedy policy in ``DIR``: a
table learner's greedy joint action of every state it met as ``.npz``, a deep learner's
agent networks as ``.safetensors`` (readable without PyTorch), each with the learner,
its settings, the run's identity and the package's version in its metadata
(:mod:`cmarlcd.policies.files`). :func:`load_policy` reads one back as an object that
acts greedily in any PettingZoo loop (:mod:`cmarlcd.policies.greedy`)."""

from cmarlcd.policies.files import load_policy, write_policy
from cmarlcd.policies.greedy import NetworkPolicy, TablePolicy

__all__ = ["NetworkPolicy", "TablePolicy", "load_policy", "write_policy"]
