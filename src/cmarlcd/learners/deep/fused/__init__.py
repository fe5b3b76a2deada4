"""The fused CPU step of the deep learners (``step="fused"``, the default on a CPU):
:mod:`~.step` is the loss each model calls; :mod:`~.kernels` (VDN, QMIX) and
:mod:`~.degree_kernels` (deep CMARL-CD's keyed update) compile it, from the layers and
Adam of :mod:`~.layers` and the mixers of :mod:`~.mixers`. The modules are one unit: a
change to any of their sources drops every one's on-disk kernel cache
(:func:`~.layers.drop_stale_caches`).
"""
