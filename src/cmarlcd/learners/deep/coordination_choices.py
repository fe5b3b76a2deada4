"""The names deep CMARL-CD's settings take (:class:`~cmarlcd.learners.deep.coordination.
DeepCMARLCDConfig`), and the constants its updates read: one place for what a setting
may be, so that the settings, their checks and the command line's help agree."""

from __future__ import annotations

#: The ways Algorithm 2's updates reach the degree network (``DeepCMARLCDConfig.update``).
UPDATES = ("keyed", "replayed", "imitation", "critic")
#: [choice] The updates whose fused step ``step="auto"`` takes on the CPU: those whose
#: fused runs were shown equivalent to autograd's (the keyed update, by the study of the
#: fused step's documentation page). The shares' fused step (``critic_form="degrees"``)
#: equals autograd's per step to float32 rounding (the tests), but no study has compared
#: their runs yet, so ``auto`` keeps autograd's for them; ``step=fused`` takes it.
AUTO_FUSED_UPDATES = ("keyed",)
#: (``update="critic"``) The most joint actions the critic may have outputs for.
MAX_JOINT_ACTIONS = 4_096
#: [choice] (``update="imitation"``) Weight of the penalty that keeps each raw degree
#: within ``[c_min, c_max]``: the strategy reads the clipped degrees, whose gradient is
#: zero outside the range, so a degree pushed past a bound would stay there when a better
#: action is found; the squared distance to the range brings it back.
RANGE_WEIGHT = 1.0
#: What a state not in the keyed memory is compared with (``unseen_record``).
UNSEEN_RECORDS = ("first-visit", "estimate", "estimate-kept", "estimate-once-kept")
#: Where the degrees it acts with come from (``act_from``).
ACT_FROM = ("network", "memory")
#: The critic's form (``critic_form``).
CRITIC_FORMS = ("joint", "sum", "degrees")
#: How the degrees learn the critic's best joint action (``critic_fit``).
CRITIC_FITS = ("imitation", "tie")
#: What the critic's λ-returns bootstrap from (``critic_bootstrap``).
CRITIC_BOOTSTRAPS = ("greedy", "best")
#: The spread of the returns that scales ``unseen_tolerance`` (``unseen_spread``).
UNSEEN_SPREADS = ("std", "range")
#: What the keyed memory's per-state record is (``record``).
RECORDS = ("maximum", "expectile")
#: What the behaviour's T is measured in (``temperature_unit``).
TEMPERATURE_UNITS = ("fixed", "range")
#: How the behaviour draws its actions from the degrees (``behaviour``).
BEHAVIOURS = ("softmax", "epsilon-greedy")
#: What an episode cut at ``max_steps`` ends in for λ-returns (``truncation``).
TRUNCATIONS = ("terminal", "bootstrap")
#: Settings only the compiled loop runs (:mod:`cmarlcd.training.deep_replay`), which the
#: object API (``DegreeAgent``, any PettingZoo environment) refuses: the ring's returns
#: recomputed at each target copy, and the batch's rewards standardised.
COMPILED_ONLY = ("refresh_returns", "standardise_rewards")
#: The settings that take one of a few names, and those names.
CHOICES = {
    "update": UPDATES,
    "unseen_record": UNSEEN_RECORDS,
    "act_from": ACT_FROM,
    "record": RECORDS,
    "critic_form": CRITIC_FORMS,
    "critic_fit": CRITIC_FITS,
    "critic_bootstrap": CRITIC_BOOTSTRAPS,
    "unseen_spread": UNSEEN_SPREADS,
    "temperature_unit": TEMPERATURE_UNITS,
    "behaviour": BEHAVIOURS,
    "truncation": TRUNCATIONS,
}
