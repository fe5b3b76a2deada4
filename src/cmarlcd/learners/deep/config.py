"""Hyper-parameters of the VDN and QMIX baselines and the ε schedule of eq. (18), and
what every deep learner's config provides (:class:`DeepLearnerConfig`).

Kept free of PyTorch so that configs validate, and the command line reports bad input,
without the ``[deep]`` extra installed.
"""

from __future__ import annotations

from dataclasses import dataclass

from cmarlcd.errors import check_discount, require
from cmarlcd.learners.policy import annealed_epsilon
from cmarlcd.runs import added_setting

#: How the agents' values make the TD target: VDN's sum and QMIX's monotonic network (one
#: target for the team), or none (each agent its own target on the team reward: deep
#: independent Q-learning, and its hysteretic form).
MIXERS = ("vdn", "qmix", "independent", "hysteretic")
#: The mixers whose agents learn each from its own TD error.
INDEPENDENT_MIXERS = ("independent", "hysteretic")
#: [choice] The fused CPU step covers every mixer with every setting of theirs (double Q
#: and the gradient clip are in its kernels; rewards are standardised before either
#: step). The mixers that take the fused step under ``step=auto``: those whose fused
#: runs were shown equivalent to autograd's by the study of docs/fused-step.md. Deep
#: IQL's and hysteretic DQN's fused step equals autograd's per step to float32 rounding
#: (the tests), but no study has compared their runs yet, so ``auto`` keeps autograd's
#: for them; ``step=fused`` takes it.
AUTO_FUSED_MIXERS = ("vdn", "qmix")
#: [choice] Hysteretic DQN's ratio of the learning rate for negative TD errors to the
#: rate for positive ones (Omidshafiei et al., 2017, "Deep decentralized multi-task
#: multi-agent reinforcement learning under partial observability", ICML: a smaller rate
#: for negative errors, ``β < α``). The project's value, 0.2, is its own choice; the
#: setting is ``negative_rate``.
HYSTERETIC_NEGATIVE_RATE = 0.2
#: How a deep learner takes its gradient step ([choice]): ``autograd``, PyTorch's autograd
#: and Adam (any device); ``fused``, hand-derived gradients and Adam in compiled CPU
#: kernels (:mod:`cmarlcd.learners.deep.fused.step`), equal to autograd's to float32 rounding
#: (CPU only); ``auto``, the fused step where it runs (on the CPU, for a learner it
#: covers), else autograd's.
STEPS = ("auto", "autograd", "fused")
#: The step of the runs stored before ``step`` existed (0.5.x): their identity leaves it
#: out, and reads back as this one.
STEP_BEFORE = "autograd"
#: The deep learners' default step ([choice]): ``auto``, the fused step on the CPU, since
#: the equivalence study (benchmarks/fused_equivalence.py, docs: The fused gradient step)
#: showed its runs equivalent to autograd's within the declared margins (0.6.0; autograd's
#: before, and still on a GPU).
DEFAULT_STEP = "auto"


def takes_fused_step(step: str, device, covered: bool = True) -> bool:
    """Whether a model with the ``step`` setting computing on ``device`` (a
    :class:`torch.device`) takes the fused step: ``fused`` always (the step refuses a
    device that is not the CPU), ``auto`` on the CPU where the fused kernels cover the
    learner's settings (``covered``)."""
    return step == "fused" or (step == "auto" and covered and device.type == "cpu")


#: How the mixers are named in tables and figures.
DISPLAY_NAMES = {
    "vdn": "VDN",
    "qmix": "QMIX",
    "independent": "Deep IQL",
    "hysteretic": "Hysteretic DQN",
}
#: The registry name of the learner of each mixer.
LEARNER_NAMES = {
    "vdn": "vdn",
    "qmix": "qmix",
    "independent": "deep-iql",
    "hysteretic": "hysteretic-dqn",
}
#: The learners that can read each agent its own observation (``own-observations``):
#: every learner of :class:`DeepConfig`, and deep CMARL-CD (its degree networks; its
#: record network and keyed memory read the whole input), whose agent networks take
#: ``own_dim``.
OWN_OBSERVATION_LEARNERS = (*LEARNER_NAMES.values(), "deep-cmarl-cd")


class DeepLearnerConfig:
    """Base of the configs of the deep learners (VDN and QMIX, deep CMARL-CD): the fields
    every deep config has (``hidden``, ``buffer_size``, ``batch_size``, ``train_every``,
    ``target_every``, ``lr``, ``gamma``; :func:`scheduled_work` reads them and
    :meth:`ready`) and the
    constants its compiled kernels read. Its kernels and its stacked model are found by
    the config's type (:func:`cmarlcd.training.deep_side.register_deep_learner`)."""

    name: str
    display_name: str
    hidden: int
    buffer_size: int
    batch_size: int
    train_every: int
    target_every: int

    @property
    def anneals(self) -> bool:
        """Whether its exploration depends on the learning budget L (eq. 18), so that a run
        is made per L rather than evaluated at every L on the way."""
        raise NotImplementedError

    @property
    def explores_by_steps(self) -> bool:
        """Whether its exploration schedule counts environment steps whatever its budget
        counts (default: it counts what the budget counts)."""
        return False

    def ready(self, stored: int) -> bool:
        """Whether ``stored`` entries of its replay are enough to learn from (default: a
        batch's worth)."""
        return stored >= self.batch_size

    def schedule(self, learn_episodes: int) -> list[float]:
        """The constants its compiled kernels read (``schedule``): entry
        :data:`TRAIN_EVERY_ENTRY` is ``train_every`` for every deep learner."""
        raise NotImplementedError


#: Where every deep learner's schedule holds ``train_every`` (read by the pause kernel).
TRAIN_EVERY_ENTRY = 5
#: Where a deep side's schedule ends with what its exploration counts (appended by the
#: side after the learner's own entries): :data:`EPISODES_UNIT` or :data:`STEPS_UNIT`
#: (steps where its learning stage counts them, or its ε anneals over a number of them:
#: ``DeepLearnerConfig.explores_by_steps``).
BUDGET_UNIT_ENTRY = -1
EPISODES_UNIT, STEPS_UNIT = 0.0, 1.0


@dataclass(frozen=True)
class DeepConfig(DeepLearnerConfig):
    """Hyper-parameters of VDN / QMIX (and of deep IQL and hysteretic DQN, the same
    networks without a mixer); defaults are the paper's DSN settings."""

    mixer: str = "vdn"
    """``"vdn"`` (sum), ``"qmix"`` (monotonic mixing network), ``"independent"`` (deep
    IQL: no mixer, each agent's own TD target on the team reward) or ``"hysteretic"``
    (hysteretic DQN: deep IQL whose negative TD errors move the values at
    ``negative_rate`` times the rate)."""
    hidden: int = 49
    """Hidden units of each agent's MLP."""
    mixer_hidden: int = 70
    """Hidden units of the QMIX mixing network (70 DSN, 64 battlefield)."""
    buffer_size: int = 40_000
    """Replay buffer capacity, in transitions."""
    batch_size: int = 400
    """Transitions per gradient step; learning starts once this many are stored."""
    train_every: int = 200
    """One gradient step every this many environment steps."""
    target_every: int = 2_000
    """Copy the online networks to the target networks every this many environment steps."""
    lr: float = 1e-3
    """Adam learning rate."""
    gamma: float = 0.9
    """[choice] Discount of the TD target, in [0, 1] (0: each step's own reward)."""
    eps_start: float = 1.0
    """ε_ini of eq. (18)."""
    eps_end: float = 0.0
    """ε_fin of eq. (18), reached after ``anneal_fraction`` of the episodes."""
    anneal_fraction: float = 0.8
    """Fraction of the L learning episodes over which ε is annealed (eq. 18: 0.8)."""
    eps_after: float = 0.01
    """ε for the remaining episodes (eq. 18: 0.01)."""
    step: str = added_setting(DEFAULT_STEP, "0.6.0", before=STEP_BEFORE)
    """[choice] How the gradient step is computed (:data:`STEPS`): ``auto`` (the default,
    :data:`DEFAULT_STEP`: the fused step on the CPU, autograd's on a GPU), ``fused`` (CPU
    only) or ``autograd`` (the step of the runs stored before 0.6.0). The two steps round
    floats differently, so runs follow other trajectories."""

    double_q: bool = added_setting(False, "0.7.0")
    """[choice] Double Q-learning (van Hasselt et al., 2016; EPyMARL's ``double_q``): the
    TD target values each agent's next action chosen greedily (over its legal actions) by
    the online networks with the target networks; False: the target networks' own
    greedy value."""
    grad_clip: float | None = added_setting(None, "0.7.0")
    """[choice] Each seed's gradient, over all its parameters, rescaled to at most this L2
    norm before the optimiser's step (``torch.nn.utils.clip_grad_norm_``'s rule, per
    seed; EPyMARL's ``grad_norm_clip``: 10); None: not clipped."""
    standardise_rewards: bool = added_setting(False, "0.7.0")
    """[choice] Each replay batch's rewards standardised by a running mean and variance
    of every batch's rewards so far, the batch's own included (EPyMARL's
    ``standardise_rewards``: the parallel update of its ``RunningMeanStd`` from a count
    of 1e-4, mean 0 and variance 1, the batch's variance unbiased); per seed."""
    anneal_steps: int | None = added_setting(None, "0.7.0")
    """[choice] ε linear from ``eps_start`` to ``eps_end`` over this many environment
    steps, then ``eps_end``, whatever the budget (EPyMARL's ``epsilon_anneal_time``);
    None: eq. (18) over the budget (``anneal_fraction``, ``eps_after``)."""
    share: bool = added_setting(False, "0.7.0")
    """[choice] One agent network per seed for every agent, the agent's one-hot index
    appended to its input (parameter sharing: EPyMARL's default, ``obs_agent_id``), rather
    than one network per agent (the paper's VDN and QMIX). ``step=auto`` takes autograd's
    step with it (the fused step covers it, ``step=fused``, equal per step to float32
    rounding, but no study has compared their runs yet)."""
    hidden_layers: int = added_setting(1, "0.7.0")
    """[choice] Hidden layers of each agent network, ``hidden`` units each (ReLU): 1, the
    paper's; 2 is EPyMARL's feed-forward agent (``use_rnn=False``: ``fc1``, a ReLU
    ``Linear`` of ``hidden_dim``, ``fc2``). ``step=fused`` takes any depth on feature
    states (equal per step to autograd's to float32 rounding) and one hidden layer on
    integer states; ``step=auto`` takes autograd's with more than one, as no study has
    compared their runs yet."""
    hypernet_layers: int = added_setting(1, "0.7.0")
    """[choice] QMIX's hypernetworks of the mixing weights: 1, a linear layer of the state
    each (the paper's QMIX), or 2, ``Linear -> ReLU -> Linear`` with ``hypernet_hidden``
    units (EPyMARL's ``hypernet_layers: 2``). ``step=fused`` takes 2 on feature states
    (equal per step to autograd's to float32 rounding); ``step=auto`` takes autograd's with
    2, as no study has compared their runs yet."""
    hypernet_hidden: int = added_setting(64, "0.7.0")
    """Hidden units of QMIX's two-layer hypernetworks (EPyMARL's ``hypernet_embed``: 64);
    read only with ``hypernet_layers=2``."""
    negative_rate: float | None = added_setting(None, "0.7.0")
    """Hysteretic DQN's β/α ([choice]): each squared TD error whose TD error
    ``r + γ max Q' − Q`` is negative is weighed by it, so with plain gradient descent
    those errors move the values at this fraction of the rate (with Adam, which scales
    the summed gradient, approximately so). None: :data:`HYSTERETIC_NEGATIVE_RATE` for
    ``mixer="hysteretic"``, 1 (no hysteresis) for every other mixer."""

    @property
    def name(self) -> str:  # type: ignore[override]
        """The learner's registry name (:data:`LEARNER_NAMES`): ``"vdn"``, ``"qmix"``,
        ``"deep-iql"`` or ``"hysteretic-dqn"``."""
        return LEARNER_NAMES[self.mixer]

    @property
    def independent(self) -> bool:
        """Whether each agent learns from its own TD error (no mixer)."""
        return self.mixer in INDEPENDENT_MIXERS

    @property
    def negative_weight(self) -> float:
        """The weight of a squared TD error whose TD error is negative (1: none)."""
        if self.negative_rate is not None:
            return self.negative_rate
        return HYSTERETIC_NEGATIVE_RATE if self.mixer == "hysteretic" else 1.0

    @property
    def display_name(self) -> str:  # type: ignore[override]
        return DISPLAY_NAMES[self.mixer]

    @property
    def anneals(self) -> bool:
        """ε anneals over the L learning episodes (eq. 18), unless over a fixed number of
        steps (``anneal_steps``)."""
        return self.anneal_steps is None

    @property
    def explores_by_steps(self) -> bool:
        """ε counts environment steps where it anneals over ``anneal_steps``."""
        return self.anneal_steps is not None

    @property
    def auto_fuses(self) -> bool:
        """Whether ``step=auto`` takes the fused step on a CPU (:data:`AUTO_FUSED_MIXERS`,
        per-agent networks of one hidden layer, QMIX's one-layer hypernetworks)."""
        return (
            self.mixer in AUTO_FUSED_MIXERS
            and not self.share
            and self.hidden_layers == 1
            and self.hypernet_layers == 1
        )

    def schedule(self, learn_episodes: int) -> list[float]:
        """ε schedule (start, end, anneal fraction, after), the length it anneals over (L,
        or ``anneal_steps``), ``train_every``."""
        return [*epsilon_schedule(self, learn_episodes), self.train_every]

    def __post_init__(self) -> None:
        known = ", ".join(MIXERS)
        require(self.mixer in MIXERS, "mixer", f"must be one of {known} (got {self.mixer!r})")
        steps = ", ".join(STEPS)
        require(self.step in STEPS, "step", f"must be one of {steps} (got {self.step!r})")
        if self.grad_clip is not None:
            require(self.grad_clip > 0, "grad_clip", f"must be > 0 (got {self.grad_clip})")
        layers = self.hidden_layers
        require(layers >= 1, "hidden_layers", f"must be >= 1 (got {layers})")
        hyper = self.hypernet_layers
        require(hyper in (1, 2), "hypernet_layers", f"must be 1 or 2 (got {hyper})")
        require(
            hyper == 1 or self.mixer == "qmix",
            "hypernet_layers",
            f"applies to qmix only, not {self.name}",
        )
        if self.anneal_steps is not None:
            count = self.anneal_steps
            require(count >= 1, "anneal_steps", f"must be >= 1 (got {count})")
        if self.negative_rate is not None:
            rate = self.negative_rate
            require(0 < rate <= 1, "negative_rate", f"must be in (0, 1] (got {rate})")
            require(
                self.mixer == "hysteretic",
                "negative_rate",
                f"applies to hysteretic-dqn only, not {self.name}",
            )
        for name in (
            "hidden",
            "mixer_hidden",
            "buffer_size",
            "batch_size",
            "train_every",
            "target_every",
            "hypernet_hidden",
        ):
            value = getattr(self, name)
            require(value >= 1, name, f"must be >= 1 (got {value})")
        require(self.batch_size <= self.buffer_size, "batch_size", "must be <= buffer_size")
        require(self.lr > 0, "lr", f"must be > 0 (got {self.lr})")
        check_discount(self.gamma)
        for name in ("eps_start", "eps_end", "eps_after"):
            value = getattr(self, name)
            require(0 <= value <= 1, name, f"must be in [0, 1] (got {value})")
        fraction = self.anneal_fraction
        require(0 < fraction <= 1, "anneal_fraction", f"must be in (0, 1] (got {fraction})")


#: The paper's battlefield settings (Section V-B).
BATTLEFIELD_DEEP = dict(
    buffer_size=100_000, batch_size=720, train_every=240, target_every=2_400, mixer_hidden=64
)


def epsilon(
    episode: int, total_episodes: int, config: DeepConfig, step: int = 1, by_steps: bool = False
) -> float:
    """Eq. (18): ε of the ``episode``-th learning episode (1-based) out of ``L``; where ε
    anneals over ``anneal_steps``, or the budget counts steps (``by_steps``: ``L`` is then
    a number of environment steps), ε of the ``step``-th environment step (1-based)."""
    done = step if config.explores_by_steps or by_steps else episode
    start, end, fraction, after, length = epsilon_schedule(config, total_episodes)
    return annealed_epsilon(done, int(length), start, end, fraction, after)


def epsilon_schedule(config: DeepConfig, budget: int) -> tuple[float, float, float, float, int]:
    """(start, end, anneal fraction, after, length) for :func:`annealed_epsilon`: eq. (18)
    over the ``budget``, or linear over ``anneal_steps`` and then ``eps_end``."""
    if config.anneal_steps is not None:
        return (config.eps_start, config.eps_end, 1.0, config.eps_end, config.anneal_steps)
    return (config.eps_start, config.eps_end, config.anneal_fraction, config.eps_after, budget)


def scheduled_work(
    before: int, after: int, stored: int, config: DeepLearnerConfig
) -> tuple[bool, bool]:
    """The schedule of every deep learner: once its environment steps have gone from
    ``before`` to ``after``, (take a gradient step, copy the target networks). A gradient
    step is due at every multiple of ``train_every`` crossed, once the replay holds
    enough to learn from (``stored``; ``config.ready``); a target copy at every multiple of
    ``target_every`` crossed."""
    step = after // config.train_every > before // config.train_every
    copy = after // config.target_every > before // config.target_every
    return step and config.ready(stored), copy
