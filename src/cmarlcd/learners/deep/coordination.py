"""Deep CMARL-CD: Algorithm 2 with function approximation (beyond the paper, whose
conclusion proposes it), the settings; free of PyTorch so that they validate without the
``[deep]`` extra.

Each agent's **coordination degrees** ``c_i(s, ·)`` come from an MLP (state -> ``hidden``
ReLU units -> one output per action; one network per agent, or one shared by every agent
with the agent's one-hot index as extra input, ``share``), clipped to ``[c_min, c_max]``;
the strategy is ``softmax(c / T)`` over the legal actions (eq. 17) and greedy execution
takes the argmax, as in the tabular learner. How Algorithm 2's updates reach the network
is the ``update`` [choice]:

* ``keyed`` (the default): after each episode its visits are folded, backwards and once
  each, into a **keyed memory** that holds, per state met, the record ``R_max(s)`` (a
  maximum) and the degrees the table would hold (:mod:`cmarlcd.learners.deep.degree_memory`:
  a new record resets them to ``c_init`` and moves the taken action by ``+delta_reset``,
  every other by ``-delta_reset``; a return within ``tolerance`` of the record moves them
  by ``±delta``; a lower return changes nothing). Every ``train_every`` steps the degree
  network is fitted to a batch of kept states drawn uniformly (squared error over each
  agent's real actions). A state not kept starts from the network's degrees and is
  compared with a **record network**'s estimate (``unseen_record="estimate"``; state ->
  ``record_hidden`` ReLU units -> 1, fitted to the memory's records) or with ``-inf``
  (``"first-visit"``, the table's rule).
* ``replayed`` (the first design, kept to compare with): every visit is stored with its
  return ``G_t`` (eq. 1) in a ring; each replayed visit becomes a regression target from
  the network's present degrees, against the record network's target copy ``R(s)``
  fitted by an expectile regression at ``expectile`` τ: a new record when ``G > R(s) +
  margin``, a tie when ``|G - R(s)| <= tolerance``. A tie then moves its state once per
  replay, by Adam's step size rather than ``delta``.
* ``imitation`` (beyond the table's rule, for states that do not recur): the same ring of
  visits and expectile record network, and the degrees learn by *self-imitation gated by
  the record* (after Oh et al., 2018, "Self-Imitation Learning", ICML): each replayed
  visit whose return reaches its state's estimated record (within ``tolerance`` spreads
  of the batch's returns) pulls the strategy ``softmax(c/T)`` of every agent towards its
  action, weighted by how far it passes the record; a lower return moves no degree.
  What the network learns in one state carries to its neighbours through the network,
  where a tie and a record of the table need the same state twice.
* ``critic`` (beyond the table's rule): the record network becomes a *centralised
  critic of joint actions*, ``R(s, a)`` for every joint action ``a`` (trained centrally
  on the ring's returns by the expectile loss at the taken joint action), and the
  state's record is its best, ``R(s) = max_a R(s, a)``, which λ-returns bootstrap from.
  The joint action that reaches the record ties it: each replayed visit moves every
  agent's degrees by ``±delta`` towards the critic's best joint action at the visit's
  state (eqs. 14-15 at a tie), so the agents act decentralised, each from its own
  degrees, on what the critic learned centrally.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import ClassVar

import numpy as np

from cmarlcd.errors import check_discount, require
from cmarlcd.learners.deep.config import DEFAULT_STEP, STEP_BEFORE, STEPS, DeepLearnerConfig
from cmarlcd.learners.degree_rules import check_degree_settings
from cmarlcd.learners.policy import annealed
from cmarlcd.runs import added_setting

#: The ways Algorithm 2's updates reach the degree network (``DeepCMARLCDConfig.update``).
UPDATES = ("keyed", "replayed", "imitation", "critic")
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
#: The spread of the returns that scales ``unseen_tolerance`` (``unseen_spread``).
UNSEEN_SPREADS = ("std", "range")
#: What the keyed memory's per-state record is (``record``).
RECORDS = ("maximum", "expectile")


@dataclass(frozen=True)
class DeepCMARLCDConfig(DeepLearnerConfig):
    """Deep CMARL-CD's settings; the degree steps, temperature, bounds and discount are
    the tabular learner's DSN settings, the network and schedule VDN's (Section V-A)."""

    name: ClassVar[str] = "deep-cmarl-cd"  # type: ignore[misc]
    display_name: ClassVar[str] = "Deep CMARL-CD"  # type: ignore[misc]

    update: str = "keyed"
    """[choice] How Algorithm 2's updates reach the degree network: ``"keyed"`` folds each
    episode once into a keyed memory of the table's records and degrees and fits the
    network to it (:mod:`cmarlcd.learners.deep.degree_memory`); ``"replayed"`` turns every
    replayed visit into a regression target from the network's present degrees and an
    expectile record (the first design; a tie then moves its state once per replay);
    ``"imitation"``, the same ring and record network, the degrees fitted by
    self-imitation of the visits whose return reaches the record (for states that do not
    recur; :meth:`~cmarlcd.learners.deep.degree_model.DegreeModel.imitation_loss`);
    ``"critic"``, the same ring with a record network of every joint action, the degrees
    moved towards its best (:meth:`~cmarlcd.learners.deep.degree_model.DegreeModel.critic_loss`)."""
    unseen_record: str = "estimate"
    """[choice] (``keyed``) What a state not in the memory is compared with:
    ``"estimate"``, the record network's estimate (fitted to the memory's records): a
    visit is kept only when its return reaches what the network expects there, and a tie
    starts from the network's degrees, so what it generalises carries over;
    ``"first-visit"``, the table's ``R_max = -inf`` (every first visit is a new record
    and resets the state's degrees, whatever its return); ``"estimate-kept"``, compared
    with the estimate, and a return below it still enters the memory, with that return as
    its record and the network's degrees unmoved, so that the table's rule goes on from
    there (its next visits tie or beat that record); ``"estimate-once-kept"``, the
    estimate once the memory keeps any state, and ``-inf`` for every state of an episode
    folded into an empty memory. Under ``"estimate"`` the record network, fitted only to
    what the memory keeps, starts near 0: where every return is negative (simple_spread)
    no visit beats it, nothing is ever kept, and the networks never learn; the first
    episode, taken whole by the table's rule, gives ``"estimate-once-kept"`` records to
    fit (measured: level or better on the DSN's one-hot states, but a return per target
    of -62.5 against -31.8 at 146,001 states, so not the default). ``first-visit`` and
    ``estimate`` are level on the DSN's one-hot states; where states rarely recur (the
    DSN at scale) ``first-visit`` fits the network to its own exploration (the deep
    CMARL-CD page of the documentation)."""
    unseen_tolerance: float = added_setting(0.0, "0.7.0")
    """[choice] (``keyed`` with an estimate) Within how many spreads of the returns folded
    so far (``unseen_spread``, per seed) a state not kept ties the record
    network's estimate, and beyond how many above it is a new record: the record network
    with a tolerance, so that the common return of states that do not recur (0 on sparse
    rewards) ties the estimate and moves the network's degrees there by ``delta``, as the
    table's ties would, rather than matching it only by accident. 0: ``tolerance``, as
    kept states (whose record is exact) always are."""
    unseen_spread: str = added_setting("std", "0.7.0")
    """[choice] (with ``unseen_tolerance``) The spread of the returns folded so far that
    scales it: ``"std"``, their standard deviation; ``"range"``, the largest minus the
    smallest. Where rewards are sparse (LBF: most returns 0) the standard deviation is a
    small fraction of a reward (0.02 against rewards of about 0.5 after 100k steps on
    8x8-2p-2f-coop), so a return of 0 still beats an estimate a little below 0 and resets
    the state towards whatever action exploration took; the range is the size of a
    reward."""
    act_from: str = added_setting("network", "0.6.0")
    """[choice] (``keyed``) Where the degrees it acts with (eq. 17) and executes greedily
    come from: ``"network"``, the degree network everywhere; ``"memory"``, the keyed
    memory's degrees where it keeps the state (the table's own, folded in by the table's
    rule) and the network's where it does not (a state never met, or one whose slot
    another took), as episodic-control agents act from their memory where it holds the
    state. With ``"memory"`` and a memory of a slot per state it is the tabular learner,
    and the network only generalises."""
    record: str = added_setting("maximum", "0.6.0")
    """[choice] (``keyed``) What the memory keeps as a state's record ``R(s)``:
    ``"maximum"``, the table's ``R_max(s)``, the largest return met there (eq. 16: a
    return above it by more than ``tolerance`` is a new record and becomes it); or
    ``"expectile"``, a record below the maximum that one lucky draw does not set: every
    visit moves it towards its return ``G`` by ``record_step * w * (G - R)``, with ``w =
    expectile`` when ``G > R`` and ``1 - expectile`` otherwise (a running ``expectile``
    of the state's returns); a return above it by more than ``margin`` is a new record
    (a reset), one within ``tolerance`` of it a tie. On the stochastic climbing games
    the maximum is set by a lucky draw and never falls (the deep CMARL-CD page of the
    documentation measures both)."""
    return_lambda: float = added_setting(1.0, "0.7.0")
    """[choice] (``replayed``, ``imitation``, ``critic``) λ of the returns the ring stores: 1, each
    visit's discounted return (eq. 1, Monte Carlo, as the table); below 1, the λ-return
    bootstrapped from the record network, ``G_t = r_{t+1} + γ ((1 - λ) R(s_{t+1}) + λ
    G_{t+1})`` (0 after an episode's last visit), computed when the episode ends with
    the record network of that moment. A reward then reaches the visits before it
    through the record of the states between, not only within its own episode: for
    sparse rewards, where few episodes earn one. (The keyed memory folds the table's
    Monte-Carlo returns: 1 there.)"""
    record_step: float = added_setting(0.02, "0.6.0")
    """(``record="expectile"``) How far a visit moves its state's record towards its
    return, in (0, 1]."""
    hidden: int = 49
    """Hidden units of each degree network (VDN's agent networks: 49)."""
    share: bool = False
    """[choice] One degree network for every agent (the agent's one-hot index appended to
    its input) rather than one per agent (VDN's and QMIX's: none shared)."""
    record_hidden: int = 49
    """Hidden units of the record network (read by ``replayed``, and by ``keyed`` with
    ``unseen_record="estimate"``, where it is fitted to the memory's records)."""
    buffer_size: int = 40_000
    """Capacity of the keyed memory, in states (``keyed``; with integer states it holds
    at most one slot per state), or of the replay ring, in visits (``replayed``)."""
    ways: int = added_setting(1, "0.6.0")
    """[choice] (``keyed``) Slots per set of the keyed memory: 1, direct-mapped (a state
    whose slot holds another replaces it); more, set-associative (a state takes an empty
    slot of its set, or the one visited least recently), so that fewer states are lost
    to collisions while the memory has room: ``n`` states in ``m`` direct-mapped slots
    keep about ``m (1 - exp(-n/m))`` of them."""
    step: str = added_setting(DEFAULT_STEP, "0.6.0", before=STEP_BEFORE)
    """[choice] How the gradient step is computed (``deep_config.STEPS``): ``auto`` (the
    default, ``deep_config.DEFAULT_STEP``: the fused step on the CPU where it covers the
    settings, else autograd's), ``fused`` (compiled CPU kernels,
    :mod:`cmarlcd.learners.deep.fused.degree_kernels`; for ``update="keyed"`` with one network
    per agent) or ``autograd`` (the step of the runs stored before 0.6.0). The two steps
    round floats differently, so runs follow other trajectories."""
    batch_size: int = 400
    """States (``keyed``, drawn from the memory) or visits (``replayed``) per gradient
    step; learning starts once a state is kept (``keyed``) or this many visits are
    stored (``replayed``)."""
    train_every: int = 200
    """[choice] One gradient step every this many environment steps (VDN's). The keyed
    update folds every episode into the memory whatever the schedule, so the network
    only has to keep up with the memory: on the DSN at L = 100k, 50 runs, a step per 200
    gave 91.4 % success against 91.2 % at a step per 50, in 38 % of the time. The first
    design needed more (:data:`REPLAYED_DEEP_CMARLCD`:
    at 200, 6.7 % success against 21.8 % at 50; the deep CMARL-CD page of the
    documentation)."""
    target_every: int = 2_000
    """[choice] (``replayed``) Copy the record network to its target copy every this many
    environment steps (every 10 gradient steps, VDN's ratio); the keyed update reads the
    record network itself."""
    lr: float = 1e-3
    """Adam learning rate of the degree networks (VDN's)."""
    record_lr: float = 1e-2
    """[choice] Adam learning rate of the record network. Adam moves each weight by about
    the learning rate per step whatever the size of the returns, so at 1e-3 a record of
    the DSN's returns (up to about 32) would take tens of thousands of steps to climb to
    them, and every return above the lagging record would count as a new one."""
    delta: float = 0.05
    """Step of eqs. (14)-(15) when a return ties the record, > 0."""
    delta_reset: float = 0.5
    """Step used after a new record resets the degrees to ``c_init``."""
    temperature: float = 1.0
    """T of eq. (17), > 0 (the behaviour's at the start where it anneals)."""
    temperature_end: float = added_setting(0.1, "0.7.0")
    """[choice] (with ``temperature_steps`` > 0) The behaviour's T of eq. (17) after its
    anneal, > 0."""
    temperature_steps: int = added_setting(0, "0.7.0")
    """[choice] Over how many environment steps the behaviour's T anneals linearly from
    ``temperature`` to ``temperature_end`` (a seed's own steps, counted over its whole
    learning); 0, the paper's fixed T. With degrees in ``[c_min, c_max]`` a fixed T = 1
    keeps the behaviour near uniform (the largest probability ratio ``e^(c_max - c_min)``),
    so where few episodes are rewarded it explores near the greedy policy only once T has
    fallen, as VDN's ε-greedy does once its ε has (the deep CMARL-CD page of the
    documentation measures it). Only acting anneals: the self-imitation loss's
    ``softmax(c / T)`` keeps ``temperature``."""
    c_min: float = 0.5
    """Lower clip of the degrees (positive, Section IV-D)."""
    c_max: float = 3.0
    """Upper clip of the degrees."""
    c_init: float = 1.5
    """The degree a new record resets a state's degrees to."""
    gamma: float = 0.9
    """Discount of eq. (1), in [0, 1]."""
    expectile: float = 0.9999
    """[choice] (``replayed``, and ``keyed`` with ``record="expectile"``) τ of the
    record's expectile, in (0, 1): how close to the upper envelope of the returns the
    record sits (-> 1: the paper's max). The DSN's
    returns from a state are skewed (most far below the best, which needs the targets
    nearly captured): at τ = 0.99 the record sits at about a third of the best return,
    and 5-7 % of the visits count as new records, each resetting its state's degrees."""
    margin: float = 2.0
    """[choice] (``replayed``, and ``keyed`` with ``record="expectile"``) By how much a
    return must pass the record to count as a new one: the record is an estimate that
    wavers, and a record within that of it would reset a state's degrees over and over.
    (The keyed memory's maximum counts any return above it by more than ``tolerance``.)"""
    tolerance: float = 1e-9
    """[choice] Within how much of the record a return counts as reaching it (eq. 16's
    equality). With ``update="imitation"`` it is in units of the spread (standard
    deviation) of the batch's returns, so that one setting serves returns of any scale
    (:data:`IMITATION_DEEP_CMARLCD`: 0.1). The keyed memory's maximum is the table's
    record, so the table's 1e-9;
    the ``replayed`` update's record and the keyed ``expectile`` are estimates that
    waver, and were measured at 1.0 (:data:`REPLAYED_DEEP_CMARLCD`,
    :data:`REPEATED_DEEP_CMARLCD`)."""

    def __post_init__(self) -> None:
        require(
            self.update in UPDATES,
            "update",
            f"must be one of {', '.join(UPDATES)} (got {self.update!r})",
        )
        unseen = self.unseen_record
        require(
            unseen in UNSEEN_RECORDS,
            "unseen_record",
            f"must be one of {', '.join(UNSEEN_RECORDS)} (got {unseen!r})",
        )
        require(
            self.act_from in ACT_FROM,
            "act_from",
            f"must be one of {', '.join(ACT_FROM)} (got {self.act_from!r})",
        )
        require(
            self.record in RECORDS,
            "record",
            f"must be one of {', '.join(RECORDS)} (got {self.record!r})",
        )
        require(
            self.keyed or self.record == "maximum",
            "record",
            "'expectile' is a record kept in the keyed memory (update='keyed'); "
            "with a ring of visits the record network's expectile is the setting",
        )
        steps = ", ".join(STEPS)
        require(self.step in STEPS, "step", f"must be one of {steps} (got {self.step!r})")
        require(
            self.step != "fused" or self.fused_covered,
            "step",
            "'fused' is the keyed update with one network per agent (update='keyed', "
            "share=false); the others take step=autograd (or auto, which falls back to it)",
        )
        lam = self.return_lambda
        require(0 <= lam <= 1, "return_lambda", f"must be in [0, 1] (got {lam})")
        require(
            lam == 1 or not self.keyed,
            "return_lambda",
            "the keyed memory folds the table's Monte-Carlo returns (1); λ-returns are for "
            "a ring of visits (update='replayed', 'imitation' or 'critic')",
        )
        spread = self.unseen_tolerance
        require(
            bool(np.isfinite(spread)) and spread >= 0,
            "unseen_tolerance",
            f"must be >= 0 (got {spread})",
        )
        require(
            spread == 0 or (self.keyed and self.estimates_unseen),
            "unseen_tolerance",
            "is the keyed memory's tolerance for a state not kept against the record "
            "network's estimate (update='keyed', unseen_record other than 'first-visit')",
        )
        require(
            self.unseen_spread in UNSEEN_SPREADS,
            "unseen_spread",
            f"must be one of {', '.join(UNSEEN_SPREADS)} (got {self.unseen_spread!r})",
        )
        step = self.record_step
        in_range = bool(np.isfinite(step)) and 0 < step <= 1
        require(in_range, "record_step", f"must be in (0, 1] (got {step})")
        require(
            self.keyed or self.act_from == "network",
            "act_from",
            "'memory' needs the keyed memory (update='keyed'); "
            f"with update='{self.update}' set act_from=network",
        )
        for name in ("hidden", "record_hidden", "buffer_size", "batch_size", "train_every", "ways"):
            value = getattr(self, name)
            require(value >= 1, name, f"must be >= 1 (got {value})")
        require(self.target_every >= 1, "target_every", f"must be >= 1 (got {self.target_every})")
        require(self.batch_size <= self.buffer_size, "batch_size", "must be <= buffer_size")
        require(self.ways <= self.buffer_size, "ways", "must be <= buffer_size")
        for name in ("lr", "record_lr"):
            value = getattr(self, name)
            require(bool(np.isfinite(value)) and value > 0, name, f"must be > 0 (got {value})")
        check_degree_settings(self)
        check_discount(self.gamma)
        tau = self.expectile
        require(0 < tau < 1, "expectile", f"must be in (0, 1) (got {tau})")
        end = self.temperature_end
        require(bool(np.isfinite(end)) and end > 0, "temperature_end", f"must be > 0 (got {end})")
        steps = self.temperature_steps
        require(steps >= 0, "temperature_steps", f"must be >= 0 (got {steps})")
        for name in ("margin", "tolerance"):
            value = getattr(self, name)
            require(bool(np.isfinite(value)) and value >= 0, name, f"must be >= 0 (got {value})")

    @property
    def keyed(self) -> bool:
        """Whether the updates go through the keyed memory."""
        return self.update == "keyed"

    def record_outputs(self, action_counts) -> int:
        """The record network's outputs: one per joint action of agents with
        ``action_counts`` (``critic``), else 1 (the state's record)."""
        if self.update != "critic":
            return 1
        joint = int(np.prod(np.asarray(action_counts, np.int64)))
        require(
            joint <= MAX_JOINT_ACTIONS,
            "update",
            f"'critic' has an output per joint action: {joint} here, more than "
            f"{MAX_JOINT_ACTIONS}; take another update for this game",
        )
        return joint

    @property
    def bootstraps(self) -> bool:
        """Whether the ring stores λ-returns bootstrapped from the record network."""
        return not self.keyed and self.return_lambda < 1

    @property
    def fused_covered(self) -> bool:
        """Whether the fused step covers these settings: the keyed update with one
        network per agent."""
        return self.keyed and not self.share

    def ready(self, stored: int) -> bool:
        """Keyed: learning starts once a state is kept (a batch draws states with
        replacement); replayed: once a batch's worth of visits is stored."""
        return stored >= (1 if self.keyed else self.batch_size)

    @property
    def estimates_unseen(self) -> bool:
        """Whether a state not kept is compared with the record network's estimate."""
        return self.unseen_record != "first-visit"

    @property
    def acts_from_memory(self) -> bool:
        """Whether it acts with the memory's degrees where the memory keeps the state."""
        return self.act_from == "memory"

    @property
    def anneals(self) -> bool:
        """Its exploration is its strategy: nothing depends on L."""
        return False

    def schedule(self, learn_episodes: int) -> list[float]:
        """T, c_min, c_max, γ, L, ``train_every``, the end of T's anneal and its steps."""
        return [
            self.temperature,
            self.c_min,
            self.c_max,
            self.gamma,
            learn_episodes,
            self.train_every,
            self.temperature_end,
            self.temperature_steps,
        ]

    def behaviour_temperature(self, steps: int) -> float:
        """The behaviour's T of eq. (17) after ``steps`` environment steps."""
        return annealed(self.temperature, self.temperature_end, self.temperature_steps, steps)


#: The first design, kept to compare with: targets recomputed at every replay against
#: an expectile record, with the tolerance and the schedule (a gradient step per 50
#: environment steps) it was measured at (the deep CMARL-CD page of the documentation).
REPLAYED_DEEP_CMARLCD = DeepCMARLCDConfig(
    update="replayed", tolerance=1.0, train_every=50, target_every=500
)
#: Self-imitation gated by the record (``update="imitation"``), a design for states that
#: do not recur: the record a high expectile (τ 0.9) of a state's returns rather than the
#: DSN's near-maximum, a visit imitated from 0.1 spreads below it, the first design's
#: schedule (a gradient step per 50 environment steps, the record's target copied every
#: 500). Declared before its selection run (the deep CMARL-CD page of the documentation).
IMITATION_DEEP_CMARLCD = DeepCMARLCDConfig(
    update="imitation", expectile=0.9, tolerance=0.1, train_every=50, target_every=500
)
#: Self-imitation on λ-returns bootstrapped from the record network (λ 0.9, declared
#: before its selection run): a reward reaches the visits before it through the record
#: of the states between, where on sparse tasks few episodes earn one.
IMITATION_LAMBDA_DEEP_CMARLCD = replace(IMITATION_DEEP_CMARLCD, return_lambda=0.9)

#: A centralised critic of joint actions as the record (``update="critic"``; declared
#: before its selection run): the ring on λ-returns (λ 0.9) bootstrapped from the critic's
#: best joint action, a 0.9-expectile critic (optimistic, as the record is), the
#: self-imitation designs' schedule.
CRITIC_DEEP_CMARLCD = replace(IMITATION_LAMBDA_DEEP_CMARLCD, update="critic")

#: [choice] Its settings on one-step (repeated) games (``cmarl-cd compare``): a game is one
#: transition, so the DSN's schedule (a step per 200 transitions, batches of 400) would
#: take 25 gradient steps in compare's 5,000 games, while Algorithm 1 moves a degree by δ
#: in every game. A batch of 50 (and, for the first design, a ring of 500), a step per 10
#: games and a degree learning rate of 1e-2. Measured first on 10-20 seeds (docs: deep
#: CMARL-CD): with lr 1e-3 the degrees are still near c_init after 500 steps (penalty
#: k = 0: 7-10 of 20); lr 1e-2, or a step every 2 games at 1e-3 (5x the time), 9-10 of 10
#: (those with the first design). The record is the memory's running 0.9-expectile of the
#: returns, ties within 1 (``record="expectile"``): on the stochastic climbing games the
#: maximum is set by one lucky draw, the expectile is not. Over compare's 50 runs, % optimal
#: on the climbing game, k = 0, -10, -50, -100, the partially and the fully stochastic
#: climbing game: 100, 100, 96, 98, 86, 94, 46 (with the maximum: 100 on the five
#: deterministic games, 0 and 0 on the stochastic ones), but the greedy joint action
#: keeps changing (median last change after 410-5,000 games; the maximum's 70-90).
REPEATED_DEEP_CMARLCD = DeepCMARLCDConfig(
    record="expectile",
    expectile=0.9,
    tolerance=1.0,
    buffer_size=500,
    batch_size=50,
    train_every=10,
    target_every=50,
    lr=1e-2,
)

#: [choice] Its battlefield settings: the tabular learner's there (c_max = 2.5, T = 0.8),
#: VDN's and QMIX's batch and schedule there (Section V-B), a memory of 200,000 slots in
#: sets of 4 (a side of the table meets 110,000 states in a match against VDN: 100,000
#: direct-mapped slots keep about 60 % of them), and the table's rule on
#: every state it keeps: it acts from the memory where the memory holds the state, and
#: a state's first visit is a record (``act_from="memory"``,
#: ``unseen_record="first-visit"``). A side meets some 75,000 states there, again and
#: again: on the deterministic battlefield (every hit lands), 10 rounds of 100k + 100k
#: against the table, acting from the network lost every round (with 10x the memory,
#: 5x the width or 4x the gradient steps too), acting from the memory but comparing
#: first visits with the record network's estimate lost 8 of 10, and these settings
#: with 100,000 direct-mapped slots won 3, tied 3 and lost 4, with these 6, 0 and 4
#: (the deep CMARL-CD page of the documentation). In the
#: 5-algorithm tournament (10 x 100k + 100k) a memory of 100,000 direct-mapped slots won
#: 36.5 and 36.8 % against VDN and QMIX, 100,000 in sets of 4 38.5 and 39.5 %, in sets
#: of 8 41.2 and 40.3 %, these 40.4 and 42.1 % (the table: 38.9 and 41.8 %).
BATTLEFIELD_DEEP_CMARLCD = DeepCMARLCDConfig(
    act_from="memory",
    unseen_record="first-visit",
    c_max=2.5,
    temperature=0.8,
    buffer_size=200_000,
    ways=4,
    batch_size=720,
    train_every=240,
    target_every=2_400,
)
