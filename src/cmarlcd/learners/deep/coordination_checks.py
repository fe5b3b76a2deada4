"""Deep CMARL-CD's settings checked against each other: one clear line naming the setting
for every combination :class:`~cmarlcd.learners.deep.coordination.DeepCMARLCDConfig`
cannot run (each setting's own range is checked here too, so that the settings class
holds only what the settings are and what they imply)."""

from __future__ import annotations

import numpy as np

from cmarlcd.errors import check_discount, require
from cmarlcd.learners.deep.config import STEPS, DeepLearnerConfig
from cmarlcd.learners.deep.coordination_choices import CHOICES
from cmarlcd.learners.degree_rules import check_degree_settings


def check_coordination_settings(config: DeepLearnerConfig) -> None:
    """Refuse, in one line naming the setting, what deep CMARL-CD's settings (``config``,
    a :class:`~cmarlcd.learners.deep.coordination.DeepCMARLCDConfig`; typed by its base so
    that this module does not import the one that calls it) cannot run."""
    for name, choices in CHOICES.items():
        value = getattr(config, name)
        require(value in choices, name, f"must be one of {', '.join(choices)} (got {value!r})")
    check_combinations(config)
    check_ranges(config)


def check_combinations(config: DeepLearnerConfig) -> None:
    """Refuse the settings that do not go together (each named with what it needs)."""
    require(
        config.keyed or config.record == "maximum",
        "record",
        "'expectile' is a record kept in the keyed memory (update='keyed'); "
        "with a ring of visits the record network's expectile is the setting",
    )
    steps = ", ".join(STEPS)
    require(config.step in STEPS, "step", f"must be one of {steps} (got {config.step!r})")
    require(
        config.step != "fused" or config.fused_covered,
        "step",
        "'fused' is the keyed update with one network per agent of one hidden layer "
        "(update='keyed', share=false, hidden_layers=1) or the shares (update='critic', "
        "critic_form='degrees'); the others take step=autograd (or auto, which falls "
        "back to it)",
    )
    lam = config.return_lambda
    require(0 <= lam <= 1, "return_lambda", f"must be in [0, 1] (got {lam})")
    require(
        lam == 1 or not config.keyed,
        "return_lambda",
        "the keyed memory folds the table's Monte-Carlo returns (1); λ-returns are for "
        "a ring of visits (update='replayed', 'imitation' or 'critic')",
    )
    require(
        config.bootstraps or not config.refresh_returns,
        "refresh_returns",
        "recomputes λ-returns: a ring of visits with return_lambda below 1",
    )
    require(
        config.truncation == "terminal" or (config.bootstraps and not config.refresh_returns),
        "truncation",
        "'bootstrap' is for λ-returns (return_lambda below 1) not recomputed "
        "(refresh_returns false)",
    )
    require(
        not config.standardise_rewards or (config.bootstraps and config.return_lambda == 0),
        "standardise_rewards",
        "standardises the reward of one-step returns (return_lambda 0, update other than "
        f"'keyed'; got return_lambda {config.return_lambda}, update '{config.update}')",
    )
    spread = config.unseen_tolerance
    require(
        bool(np.isfinite(spread)) and spread >= 0,
        "unseen_tolerance",
        f"must be >= 0 (got {spread})",
    )
    require(
        spread == 0 or (config.keyed and config.estimates_unseen),
        "unseen_tolerance",
        "is the keyed memory's tolerance for a state not kept against the record "
        "network's estimate (update='keyed', unseen_record other than 'first-visit')",
    )
    require(
        config.critic_form == "joint" or config.critic_bootstrap == "greedy",
        "critic_form",
        f"'{config.critic_form}' bootstraps from the degrees' greedy joint action "
        "(critic_bootstrap=greedy)",
    )
    step = config.record_step
    in_range = bool(np.isfinite(step)) and 0 < step <= 1
    require(in_range, "record_step", f"must be in (0, 1] (got {step})")
    require(
        config.keyed or config.act_from == "network",
        "act_from",
        "'memory' needs the keyed memory (update='keyed'); "
        f"with update='{config.update}' set act_from=network",
    )


def check_ranges(config: DeepLearnerConfig) -> None:
    """Refuse a setting outside its own range (a count below 1, a rate not above 0, a
    batch larger than its memory, the degrees' and the discount's rules)."""
    for name in ("hidden", "hidden_layers", "record_hidden", "buffer_size", "batch_size",
                 "train_every", "ways"):  # fmt: skip
        value = getattr(config, name)
        require(value >= 1, name, f"must be >= 1 (got {value})")
    require(config.target_every >= 1, "target_every", f"must be >= 1 (got {config.target_every})")
    require(config.batch_size <= config.buffer_size, "batch_size", "must be <= buffer_size")
    require(config.ways <= config.buffer_size, "ways", "must be <= buffer_size")
    for name in ("lr", "record_lr"):
        value = getattr(config, name)
        require(bool(np.isfinite(value)) and value > 0, name, f"must be > 0 (got {value})")
    check_degree_settings(config)
    check_discount(config.gamma)
    tau = config.expectile
    require(0 < tau < 1, "expectile", f"must be in (0, 1) (got {tau})")
    end = config.temperature_end
    require(bool(np.isfinite(end)) and end > 0, "temperature_end", f"must be > 0 (got {end})")
    steps = config.temperature_steps
    require(steps >= 0, "temperature_steps", f"must be >= 0 (got {steps})")
    for name in ("epsilon_start", "epsilon_end"):
        value = getattr(config, name)
        require(0 <= value <= 1, name, f"must be in [0, 1] (got {value})")
    steps = config.epsilon_steps
    require(steps >= 0, "epsilon_steps", f"must be >= 0 (got {steps})")
    for name in ("margin", "tolerance"):
        value = getattr(config, name)
        require(bool(np.isfinite(value)) and value >= 0, name, f"must be >= 0 (got {value})")
