"""The fused CPU step of the deep learners (``step="fused"``, the default on a CPU):
:mod:`~.step` is the loss each model calls; :mod:`~.kernels` (VDN, QMIX, deep IQL,
hysteretic DQN) and :mod:`~.degree_kernels` (deep CMARL-CD's keyed update) compile it,
from the layers and Adam of :mod:`~.layers`, the agent networks of any depth of
:mod:`~.networks` and the mixers of :mod:`~.mixers`. The modules are one unit: a change
to any of their sources drops every one's on-disk kernel cache
(:func:`~.layers.drop_stale_caches`).
"""
