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
  degrees, on what the critic learned centrally; or (``critic_form="degrees"``) the
  critic is the sum of the agents' degrees at the joint action, nothing distilled.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from cmarlcd.errors import require
from cmarlcd.learners.deep.config import DEFAULT_STEP, STEP_BEFORE, DeepLearnerConfig
from cmarlcd.learners.deep.coordination_checks import check_coordination_settings
from cmarlcd.learners.deep.coordination_choices import (  # noqa: F401  (re-exported)
    ACT_FROM,
    AUTO_FUSED_UPDATES,
    BEHAVIOURS,
    CHOICES,
    COMPILED_ONLY,
    CRITIC_BOOTSTRAPS,
    CRITIC_FITS,
    CRITIC_FORMS,
    MAX_JOINT_ACTIONS,
    RANGE_WEIGHT,
    RECORDS,
    TEMPERATURE_UNITS,
    TRUNCATIONS,
    UNSEEN_RECORDS,
    UNSEEN_SPREADS,
    UPDATES,
)
from cmarlcd.learners.policy import annealed
from cmarlcd.runs import added_setting


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
    refresh_returns: bool = added_setting(False, "0.7.0")
    """[choice] (``return_lambda`` below 1) Recompute every λ-return the ring holds at each
    target copy, from the estimates of that moment (:meth:`~cmarlcd.learners.deep.
    degree_model.DegreeModel.estimate`), so that a return bootstraps from estimates at
    most ``target_every`` steps old, not from those of its episode's end, kept for as
    long as the ring keeps the visit (measured: the deep CMARL-CD page)."""
    standardise_rewards: bool = added_setting(False, "0.7.0")
    """[choice] (one-step returns: ``return_lambda`` 0, an update other than ``keyed``;
    compiled loop) Each replay batch's rewards standardised as EPyMARL's VDN standardises
    them (``RewardStatistics``: running mean and variance of every batch's rewards so far,
    per seed), and each visit's target ``r + γ V'(s')`` taken with the standardised
    reward in place of ``r``. On LBF most steps pay nothing, so a standardised step costs
    about ``-mean / std`` until the food is collected, and the targets sit at a scale
    where Adam's steps are small against them; the shares learn from the rewards as paid
    otherwise. With λ above 0 a return sums rewards the batch does not standardise,
    so it needs λ 0."""
    truncation: str = added_setting("terminal", "0.7.0")
    """[choice] (``return_lambda`` below 1) What an episode cut at the game's
    ``max_steps`` ends in: ``"terminal"``, nothing (its last visit's return is its reward,
    as a terminated episode's, as first measured); ``"bootstrap"``, the estimate at the
    state it was cut in (``G_T = r_T + γ R(s_T)``; Pardo et al., 2018, "Time Limits in
    Reinforcement Learning"), as VDN's and QMIX's TD targets do. Where every episode is
    cut (simple_spread's 25 steps) ``"terminal"`` makes a state's return depend on the
    steps left, which its observation does not show. Not with ``refresh_returns``, whose
    recomputation does not keep the state an episode was cut in."""
    record_step: float = added_setting(0.02, "0.6.0")
    """(``record="expectile"``) How far a visit moves its state's record towards its
    return, in (0, 1]."""
    hidden: int = 49
    """Hidden units of each degree network (VDN's agent networks: 49)."""
    hidden_layers: int = added_setting(1, "0.7.0")
    """[choice] Hidden layers of each degree network, each of ``hidden`` units (2: the
    model class of EPyMARL's agents, what VDN needed on LBF's cooperative tasks: the
    field page); with more than one the keyed update takes autograd's step (the shares'
    fused step takes any)."""
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
    per agent, and for the shares, ``critic_form="degrees"``, in any model class) or
    ``autograd`` (the step of the runs stored before 0.6.0). ``auto`` takes the fused step
    for the keyed update only (:data:`AUTO_FUSED_UPDATES`). The two steps round floats
    differently, so runs follow other trajectories."""
    batch_size: int = 400
    """States (``keyed``, drawn from the memory) or visits (``replayed``) per gradient
    step; learning starts once a state is kept (``keyed``) or this many visits are
    stored (``replayed``)."""
    train_every: int = 200
    """[choice] One gradient step every this many environment steps (VDN's). The keyed
    update folds every episode into the memory whatever the schedule, so the network
    only has to keep up with the memory: on the DSN at L = 100k, 50 runs, a step per 200
    gave 91.4 % success against 91.2 % at a step per 50, in 38 % of the time. The first
    design needed more (:data:`~cmarlcd.learners.deep.designs.REPLAYED_DEEP_CMARLCD`:
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
    temperature_unit: str = added_setting("fixed", "0.7.0")
    """[choice] What T of eq. (17) is measured in when the behaviour acts: ``"fixed"``,
    the degrees' own units (the paper's); ``"range"``, the range of the acting agent's
    degrees over its legal actions at the state (largest minus smallest), so that the
    behaviour is ``softmax((c - max c) / (T (max c - min c)))``: as greedy wherever the
    degrees differ, whatever their scale. The shares of a record
    (``critic_form="degrees"``) are in the returns' units, which differ by a factor of
    about 40 between LBF and the DSN, so no fixed T suits both (the deep CMARL-CD page of
    the documentation measures it). Where an agent's legal degrees are all equal it
    acts uniformly, as at any T. Greedy execution and the self-imitation loss do not
    read it."""
    behaviour: str = added_setting("softmax", "0.7.0")
    """[choice] How the behaviour draws each agent's action from its clipped degrees:
    ``"softmax"``, eq. (17)'s ``softmax(c / T)`` (the paper's, with the T settings above);
    ``"epsilon-greedy"`` (beyond the paper, a diagnostic), the baselines' rule: with
    probability ε a uniform legal action, else the legal action of largest degree (lowest
    index on ties), ε annealed linearly from ``epsilon_start`` to ``epsilon_end`` over
    ``epsilon_steps`` environment steps. It puts VDN's behaviour on the shares, so that a
    gap left between them and VDN is measured without eq. (17); the T settings then shape
    only the self-imitation loss. Greedy execution does not read it."""
    epsilon_start: float = added_setting(1.0, "0.7.0")
    """[choice] (``behaviour="epsilon-greedy"``) ε at the first step, in [0, 1] (VDN's)."""
    epsilon_end: float = added_setting(0.05, "0.7.0")
    """[choice] (``behaviour="epsilon-greedy"``) ε after its anneal, in [0, 1] (VDN's)."""
    epsilon_steps: int = added_setting(50_000, "0.7.0")
    """[choice] (``behaviour="epsilon-greedy"``) Over how many environment steps ε anneals
    (a seed's own steps, counted over its whole learning; VDN's 50,000 at the field's
    protocol); 0 keeps ``epsilon_start``."""
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
    (:data:`~cmarlcd.learners.deep.designs.IMITATION_DEEP_CMARLCD`: 0.1). The keyed
    memory's maximum is the table's record, so the table's 1e-9;
    the ``replayed`` update's record and the keyed ``expectile`` are estimates that
    waver, and were measured at 1.0
    (:data:`~cmarlcd.learners.deep.designs.REPLAYED_DEEP_CMARLCD`,
    :data:`~cmarlcd.learners.deep.designs.REPEATED_DEEP_CMARLCD`)."""
    critic_fit: str = added_setting("tie", "0.7.0")
    """[choice] (``critic``) How the degrees learn the critic's best joint action ``a*``
    at a replayed visit's state: ``"tie"`` (the design as first run), eqs. (14)-(15) at a
    tie, ``a*_i`` raised by ``delta`` and every other action lowered by it;
    ``"imitation"`` (:data:`~cmarlcd.learners.deep.designs.CRITIC_DEEP_CMARLCD`), a
    cross-entropy of each agent's strategy ``softmax(clip(c_i)/T)`` towards ``a*_i``
    (with ``RANGE_WEIGHT``'s penalty, as ``imitation``). While the critic's outputs are
    near-equal its ``a*`` changes from one step to the next; under ``"tie"`` every action
    is then lowered more often than raised and all degrees sink to ``c_min`` (measured:
    the largest degree 0.57-0.71 on average on 2s-8x8-2p-2f-coop after 100k steps),
    where the cross-entropy keeps the most frequent ``a*`` the greedy one. The critic's
    settings default to the first run's, so that they stay out of every other run's
    identity."""
    critic_form: str = added_setting("joint", "0.7.0")
    """[choice] (``critic``) The critic's form: ``"joint"``, an output per joint action,
    ``R(s, a)``; ``"sum"``, VDN's decomposition, an output per agent and action, ``R(s,
    a) = Σ_i R_i(s, a_i)`` (``Σ_i |A_i|`` outputs), whose best joint action is each
    agent's best and whose outputs each learn from every visit where the agent took that
    action, where a joint output learns only from visits of its joint action;
    ``"degrees"`` (``SHARES_DEEP_CMARLCD``), the agents' degrees as the terms, ``R(s, a)
    = Σ_i c_i(o_i, a_i)``: each its agent's share of the record, acted on directly by
    eq. (17), unclipped (in the returns' units; the softmax reads only differences).
    Both take ``critic_bootstrap="greedy"``."""
    critic_bootstrap: str = added_setting("best", "0.7.0")
    """[choice] (``critic`` with ``return_lambda`` below 1) The critic's estimate that
    λ-returns bootstrap from: ``"best"`` (as first run), its best value, ``max_a R(s,
    a)``; ``"greedy"`` (:data:`~cmarlcd.learners.deep.designs.CRITIC_DEEP_CMARLCD`), its
    value of the joint action the agents' degrees take greedily there (the policy they
    execute). The maximum over many near-equal noisy outputs bootstraps an
    overestimate that compounds through the returns (measured: stored returns of 1.3 on
    average on 2s-8x8-2p-2f-coop, where a greedy episode earns 0.2 at most; the deep
    CMARL-CD page of the documentation)."""

    def __post_init__(self) -> None:
        check_coordination_settings(self)

    @property
    def keyed(self) -> bool:
        """Whether the updates go through the keyed memory."""
        return self.update == "keyed"

    def record_outputs(self, action_counts) -> int:
        """The record network's outputs: one per joint action of agents with
        ``action_counts`` (``critic``; one per agent and action with ``critic_form="sum"``),
        else 1 (the state's record)."""
        if self.update != "critic" or self.critic_form == "degrees":
            return 1
        if self.critic_form == "sum":
            return int(np.sum(np.asarray(action_counts, np.int64)))
        joint = int(np.prod(np.asarray(action_counts, np.int64)))
        require(
            joint <= MAX_JOINT_ACTIONS,
            "update",
            f"'critic' has an output per joint action: {joint} here, more than "
            f"{MAX_JOINT_ACTIONS}; take another update for this game",
        )
        return joint

    @property
    def shares(self) -> bool:
        """Whether the degrees are the agents' shares of the record
        (``critic_form="degrees"``), unclipped."""
        return self.update == "critic" and self.critic_form == "degrees"

    @property
    def degree_bounds(self) -> tuple[float, float]:
        """What the degrees are clipped to as it acts: ``[c_min, c_max]``, or no bound
        where they are the record's shares (:attr:`shares`)."""
        return (-np.inf, np.inf) if self.shares else (self.c_min, self.c_max)

    @property
    def greedy_bootstrap(self) -> bool:
        """Whether λ-returns bootstrap from the critic's value of the degrees' greedy
        joint action."""
        return self.update == "critic" and self.critic_bootstrap == "greedy"

    @property
    def bootstraps(self) -> bool:
        """Whether the ring stores λ-returns bootstrapped from the record network."""
        return not self.keyed and self.return_lambda < 1

    @property
    def fused_covered(self) -> bool:
        """Whether the fused step covers these settings (``step="fused"``): the keyed
        update with one network per agent of one hidden layer, or the shares
        (``update="critic"``, ``critic_form="degrees"``) in any model class."""
        return self.shares or (self.keyed and not self.share and self.hidden_layers == 1)

    @property
    def auto_fuses(self) -> bool:
        """Whether ``step="auto"`` takes the fused step on the CPU: where the study of
        the fused step showed its runs equivalent to autograd's (the keyed update,
        :data:`AUTO_FUSED_UPDATES`)."""
        return self.fused_covered and self.update in AUTO_FUSED_UPDATES

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
        """T, the clip (:attr:`degree_bounds`), γ, L, ``train_every``, the end of T's
        anneal, its steps and its unit (the index in :data:`TEMPERATURE_UNITS`), whether
        a cut episode's λ-returns bootstrap (``truncation``), the behaviour (the index in
        :data:`BEHAVIOURS`) and ε's start, end and steps."""
        lo, hi = self.degree_bounds
        return [
            self.temperature,
            lo,
            hi,
            self.gamma,
            learn_episodes,
            self.train_every,
            self.temperature_end,
            self.temperature_steps,
            float(TEMPERATURE_UNITS.index(self.temperature_unit)),
            float(self.truncation == "bootstrap"),
            float(BEHAVIOURS.index(self.behaviour)),
            self.epsilon_start,
            self.epsilon_end,
            self.epsilon_steps,
        ]

    def compiled_only(self) -> tuple[str, ...]:
        """The settings switched on that only the compiled loop runs (:data:`COMPILED_ONLY`)."""
        return tuple(name for name in COMPILED_ONLY if getattr(self, name))

    def behaviour_temperature(self, steps: int) -> float:
        """The behaviour's T of eq. (17) after ``steps`` environment steps."""
        return annealed(self.temperature, self.temperature_end, self.temperature_steps, steps)

    def behaviour_epsilon(self, steps: int) -> float:
        """ε of the ε-greedy behaviour after ``steps`` environment steps."""
        return annealed(self.epsilon_start, self.epsilon_end, self.epsilon_steps, steps)
