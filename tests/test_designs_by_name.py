"""``--set deep-cmarl-cd.design=NAME``: a named design is the settings it was measured
at, so it finds the runs the long settings string stored; the learner's other settings
win, the command's options and the game's settings stay where the design leaves them;
a wrong name is one line."""

from __future__ import annotations

import json
import subprocess
import sys
from dataclasses import replace

import pytest

from cmarlcd import ConfigError, registry
from cmarlcd.cli.options import apply_settings
from cmarlcd.games.foraging.rules import Foraging
from cmarlcd.learners.deep.coordination import DeepCMARLCDConfig
from cmarlcd.learners.deep.designs import DESIGNS, LBF_EPISODE_STEPS, REPEATED_DEEP_CMARLCD

D = "deep-cmarl-cd"
#: shares-cold as the selection run and the field study wrote it (by hand, from the
#: scripts' settings strings).
SHARES_COLD = {
    "update": "critic", "expectile": 0.5, "return_lambda": 0.9, "train_every": 50,
    "target_every": 500, "critic_bootstrap": "greedy", "critic_fit": "imitation",
    "critic_form": "degrees", "temperature_end": 0.01, "temperature_steps": 50_000,
}  # fmt: skip


def settings(text: str, config: DeepCMARLCDConfig | None = None) -> DeepCMARLCDConfig:
    return apply_settings(text, (config or DeepCMARLCDConfig(),))[0]


def test_shares_cold_is_the_settings_the_selection_run_measured() -> None:
    written = ",".join(f"{D}.{k}={v}" for k, v in SHARES_COLD.items())
    assert settings(f"{D}.design=shares-cold") == settings(written)
    assert settings(f"{D}.design=shares-cold,{D}.gamma=0.99").gamma == 0.99


def test_every_design_by_name_is_that_design() -> None:
    for name, design in DESIGNS.items():
        assert settings(f"{D}.design={name}") == design, name
    assert settings(f"{D}.design=Shares-Cold") == DESIGNS["shares-cold"]


def test_the_shared_designs_are_the_bootstrapped_ones_in_the_baselines_model_class() -> None:
    # the field study's VDN and QMIX: one network shared, two hidden layers of 64
    model = f"{D}.share=true,{D}.hidden_layers=2,{D}.hidden=64"
    for kind in ("cold", "range"):
        shared = settings(f"{D}.design=shares-{kind}-bootstrap-shared")
        assert shared == settings(f"{D}.design=shares-{kind}-bootstrap,{model}"), kind
        assert (shared.share, shared.hidden_layers, shared.hidden) == (True, 2, 64)
        assert shared.truncation == "bootstrap" and shared.critic_form == "degrees"
    assert settings(f"{D}.design=shares-range-bootstrap-shared").temperature_unit == "range"


def test_the_anchored_shared_designs_end_cut_episodes_in_what_they_collected() -> None:
    model = f"{D}.share=true,{D}.hidden_layers=2,{D}.hidden=64"
    for kind in ("cold", "range"):
        shared = settings(f"{D}.design=shares-{kind}-shared")
        assert shared == settings(f"{D}.design=shares-{kind},{model}"), kind
        assert shared.truncation == "terminal" and shared.critic_form == "degrees"
        assert (shared.share, shared.hidden_layers, shared.hidden) == (True, 2, 64)
        # the same design as its bootstrapped form but for the cut episodes' returns
        bootstrapped = settings(f"{D}.design=shares-{kind}-bootstrap-shared")
        assert replace(bootstrapped, truncation="terminal") == shared, kind


def test_the_refresh_design_is_the_anchored_range_design_recomputing_its_returns() -> None:
    refresh = settings(f"{D}.design=shares-range-shared-refresh")
    assert refresh == settings(f"{D}.design=shares-range-shared,{D}.refresh_returns=true")
    assert refresh.refresh_returns and refresh.truncation == "terminal"
    assert (refresh.share, refresh.hidden_layers, refresh.return_lambda) == (True, 2, 0.9)


def test_the_slow_refresh_design_recomputes_its_returns_at_vdns_copies() -> None:
    slow = settings(f"{D}.design=shares-range-shared-refresh-slow")
    assert slow == settings(f"{D}.design=shares-range-shared-refresh,{D}.target_every=10000")
    assert slow.refresh_returns and slow.target_every == 200 * Foraging().max_steps
    one_step = settings(f"{D}.design=shares-range-shared-refresh-slow-td")
    assert one_step == replace(slow, return_lambda=0.0) and one_step.bootstraps


def test_the_epsilon_design_is_the_one_step_design_acting_as_vdn() -> None:
    one_step = settings(f"{D}.design=shares-range-shared-refresh-slow-td")
    epsilon = settings(f"{D}.design=shares-epsilon-shared-refresh-slow-td")
    # EPyMARL's VDN: ε from 1 to 0.05 over 50,000 steps; nothing else differs
    vdn = {"behaviour": "epsilon-greedy", "epsilon_start": 1.0, "epsilon_end": 0.05,
           "epsilon_steps": 50_000}  # fmt: skip
    assert epsilon == replace(one_step, **vdn)
    assert one_step.behaviour == "softmax"


def test_the_standardised_design_is_the_one_step_design_with_vdns_rewards() -> None:
    one_step = settings(f"{D}.design=shares-range-shared-refresh-slow-td")
    chosen = settings(f"{D}.design=shares-range-shared-refresh-slow-td-standardised")
    assert chosen == replace(one_step, standardise_rewards=True)
    assert not one_step.standardise_rewards


def test_the_thirteenth_design_is_the_standardised_one_acting_as_vdn() -> None:
    chosen = settings(f"{D}.design=shares-range-shared-refresh-slow-td-standardised")
    epsilon = settings(f"{D}.design=shares-epsilon-shared-refresh-slow-td-standardised")
    vdn = {"behaviour": "epsilon-greedy", "epsilon_start": 1.0, "epsilon_end": 0.05,
           "epsilon_steps": 50_000}  # fmt: skip
    assert epsilon == replace(chosen, **vdn) and epsilon.standardise_rewards


def test_the_epymarl_design_replays_as_the_baselines_do_on_lbf() -> None:
    epymarl = settings(f"{D}.design=shares-range-bootstrap-shared-epymarl")
    # EPyMARL's 32-episode batches and 5,000-episode buffer of 50-step LBF episodes, VDN's
    # learning rate; the rest is shares-range-bootstrap-shared-slow
    assert (epymarl.batch_size, epymarl.buffer_size, epymarl.lr) == (1_600, 250_000, 5e-4)
    slow = settings(f"{D}.design=shares-range-bootstrap-shared-slow")
    assert replace(epymarl, batch_size=400, buffer_size=40_000, lr=1e-3) == slow
    assert (epymarl.train_every, epymarl.target_every) == (50, 10_000)
    assert Foraging().max_steps == LBF_EPISODE_STEPS == 50


def test_the_slow_design_is_shares_cold_bootstrap_with_vdns_target_interval() -> None:
    slow = settings(f"{D}.design=shares-cold-bootstrap-slow")
    assert slow == settings(f"{D}.design=shares-cold-bootstrap,{D}.target_every=10000")
    assert slow.target_every == 50 * 200  # EPyMARL's: 200 episodes of 50 steps
    both = settings(f"{D}.design=shares-range-bootstrap-shared-slow")
    assert both == settings(f"{D}.design=shares-range-bootstrap-shared,{D}.target_every=10000")
    assert (both.share, both.temperature_unit, both.target_every) == (True, "range", 10_000)


def test_the_learners_other_settings_win_in_any_order() -> None:
    for text in (f"{D}.temperature_end=0.5,{D}.design=shares-cold",
                 f"{D}.design=shares-cold,{D}.temperature_end=0.5"):  # fmt: skip
        chosen = settings(text)
        assert chosen.temperature_end == 0.5 and chosen.critic_form == "degrees"


def test_what_the_design_leaves_stays_as_the_command_and_the_game_set_it() -> None:
    assert settings(f"{D}.design=shares", replace(DeepCMARLCDConfig(), gamma=0.95)).gamma == 0.95
    game = replace(DeepCMARLCDConfig(), lr=1e-2, batch_size=50, train_every=10)
    chosen = settings(f"{D}.design=shares", game)
    assert (chosen.lr, chosen.batch_size) == (1e-2, 50)  # the game's
    assert (chosen.update, chosen.train_every) == ("critic", 50)  # the design's
    # a game's settings the design cannot go with are refused in one line
    with pytest.raises(ConfigError, match="record 'expectile' is a record kept in the keyed"):
        settings(f"{D}.design=shares", REPEATED_DEEP_CMARLCD)


def test_a_design_that_does_not_exist_is_one_line_naming_those_that_do() -> None:
    with pytest.raises(ConfigError, match=r"no design 'sharez'; its designs: one-step, "):
        settings(f"{D}.design=sharez")
    with pytest.raises(ConfigError, match="vdn has no setting 'design'"):
        apply_settings("vdn.design=shares", (registry.require_learner("vdn"),))


def test_the_field_finds_the_runs_the_settings_string_stored(tmp_path) -> None:
    pytest.importorskip("torch")
    written = ",".join(f"{D}.{k}={v}" for k, v in SHARES_COLD.items())

    def field(setting: str) -> subprocess.CompletedProcess:
        return subprocess.run(
            [sys.executable, "-m", "cmarlcd", "field", "--tasks", "simple_spread:N=2",
             "--learners", D, "--seeds", "1", "--steps", "1k", "--eval-interval", "1k",
             "--eval-episodes", "2", "--workers", "1", "--no-progress", "--json",
             "--set", setting, "--store", str(tmp_path / "s.sqlite"),
             "--figures", str(tmp_path / "f")],
            capture_output=True, text=True, timeout=600, cwd=tmp_path,
        )  # fmt: skip

    first = field(written)
    assert first.returncode == 0, first.stderr[-3000:]
    again = field(f"{D}.design=shares-cold")
    assert again.returncode == 0, again.stderr[-3000:]
    assert json.loads(first.stdout)["runs_computed"] > 0
    assert json.loads(again.stdout)["runs_computed"] == 0
    wrong = field(f"{D}.design=nope")
    assert wrong.returncode == 2
    assert wrong.stderr.strip().count("\n") == 0 and "no design 'nope'" in wrong.stderr
