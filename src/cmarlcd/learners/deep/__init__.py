"""The deep learners (``[deep]`` extra for the networks; the settings need no PyTorch).

* :mod:`~.config` -- the VDN and QMIX settings, the ε schedule of eq. (18), and what
  every deep learner's config provides;
* :mod:`~.value_decomposition` -- VDN and QMIX (Section V-A/B), B seeds in one model;
* :mod:`~.coordination`, :mod:`~.degree_memory`, :mod:`~.degree_model` -- deep CMARL-CD,
  Algorithm 2 with networks (beyond the paper): its settings, its keyed memory, its model;
* :mod:`~.agent`, :mod:`~.degree_agent` -- one seed, step by step, for any PettingZoo
  ``ParallelEnv``;
* :mod:`~.replay` -- the replay ring of B seeds;
* :mod:`~.fused` -- the fused CPU step: forward, hand-derived backward and Adam compiled
  in one pass per seed.
"""
