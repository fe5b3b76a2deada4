"""Each reading of what Section V-B leaves open reaches the game or the learner it names,
and the defaults play exactly what the package played before they were settings."""

from __future__ import annotations

import json
from collections import Counter
from dataclasses import asdict
from pathlib import Path

import numpy as np
import pytest

from cmarlcd.errors import ConfigError
from cmarlcd.experiments import settings_of
from cmarlcd.experiments import tournament as tour
from cmarlcd.experiments import tournament_claims as claim_checks
from cmarlcd.experiments import tournament_results as match_results
from cmarlcd.games import battlefield
from cmarlcd.games.battlefield import GUNNER, MARINE, Unit
from cmarlcd.learners.tabular.automata import LAOCA, AutomatonConfig
from cmarlcd.learners.tabular.coordination import CMARLCDStochastic, StochasticConfig
from cmarlcd.sweeps.store import RunKey, RunRecord
from cmarlcd.training.tabular_side import TabularSide

DATA = Path(__file__).parent.parent / "data"
LEARNERS = tour.battlefield_learners()
TABULAR = (LEARNERS["cmarl-cd"], LEARNERS["la-oca"])


# ------------------------------------------------------------------ the discount


@pytest.mark.parametrize(
    ("learner", "config"),
    [(CMARLCDStochastic, StochasticConfig(gamma=0.0)), (LAOCA, AutomatonConfig(gamma=0))],
)
def test_gamma_0_makes_the_return_the_turns_own_reward(learner, config) -> None:
    agent = learner([2], config, seed=0)
    for state, reward in ((0, 2.0), (1, 10.0)):  # 2 now, 10 one turn later
        agent.act(state)
        agent.observe(state, (0,), reward)
    agent.end_episode()
    # γ = 0: G_0 = r_1 = 2 (not 2 + γ 10), G_1 = r_2 = 10
    assert agent.max_return(0) == 2.0 and agent.max_return(1) == 10.0


def test_the_tournament_gamma_and_tolerance_reach_the_tabular_learners_only() -> None:
    readings = tour.Readings(gamma=0.0, tolerance=0.5)
    contest = tour.Tournament((*TABULAR, LEARNERS["vdn"]), rounds=1, readings=readings)
    played = {config.name: config for config in contest.playing}
    assert played["cmarl-cd"].gamma == played["la-oca"].gamma == 0.0
    assert played["cmarl-cd"].tolerance == played["la-oca"].tolerance == 0.5
    assert played["vdn"] == LEARNERS["vdn"]  # the deep learner keeps its own settings
    stored = {spec.algorithm: spec.config for spec in contest.specs()}  # as the store keeps them
    pair = stored["cmarl-cd vs vdn"]
    learners = dict(zip(pair["algorithms"], pair["learners"], strict=True))
    assert learners["cmarl-cd"]["gamma"] == 0.0 and learners["vdn"]["gamma"] == 0.9
    typed = {spec.algorithm: settings_of(spec) for spec in contest.specs()}
    assert typed["la-oca vs la-oca"].learners[0].params().tolerance == 0.5
    # a match of two deep learners is the same match under every tabular reading
    default = {s.algorithm: s.key for s in tour.Tournament(contest.learners, rounds=1).specs()}
    assert {s.algorithm: s.key for s in contest.specs()}["vdn vs vdn"] == default["vdn vs vdn"]


@pytest.mark.parametrize("field", ["gamma", "tolerance", "unseen"])
def test_bad_readings_are_rejected(field) -> None:
    bad = {"gamma": 1.5, "tolerance": -1.0, "unseen": "highest"}[field]
    with pytest.raises(ConfigError, match=field):
        tour.Readings(**{field: bad})


# -------------------------------------------------------------- unseen states


def unseen_side(unseen: str) -> tuple[TabularSide, tuple, np.ndarray]:
    """A CMARL-CD side 0 that has visited nothing, in a battle where side 1 has lost
    units 1 and 4 (so those targets are illegal)."""
    spec = battlefield.SPEC
    side = TabularSide(spec, 0, TABULAR[0], unseen)
    env = spec.new_env()
    spec.kernels.reset(env, np.random.default_rng(0))
    env[0][1, [1, 4]] = 0
    legal = np.zeros((spec.n_agents, int(spec.action_counts.max())), dtype=np.bool_)
    return side, env, legal


def greedy_draws(unseen: str, seed: int, turns: int = 300) -> np.ndarray:
    side, env, legal = unseen_side(unseen)
    rng = np.random.default_rng(seed)
    joint = np.zeros(6, dtype=np.int64)
    draws = []
    for _ in range(turns):
        side.kernels.greedy(side.data, env, 0, 0, legal, rng, joint)
        draws.append(joint.copy())
    return np.array(draws)


def test_unseen_lowest_plays_the_lowest_legal_target_and_draws_nothing() -> None:
    draws = greedy_draws("lowest", seed=0)
    assert (draws == 0).all()  # target 0 is alive
    side, env, legal = unseen_side("lowest")
    env[0][1, 0] = 0  # now targets 0, 1 and 4 are gone
    rng = np.random.default_rng(0)
    before = rng.bit_generator.state
    joint = np.zeros(6, dtype=np.int64)
    side.kernels.greedy(side.data, env, 0, 0, legal, rng, joint)
    assert (joint == 2).all() and rng.bit_generator.state == before


def test_unseen_random_draws_uniformly_among_legal_targets_from_its_generator() -> None:
    draws = greedy_draws("random", seed=1)
    counts = Counter(draws.ravel().tolist())
    assert set(counts) == {0, 2, 3, 5}  # the four live opponents, never 1 or 4
    assert all(abs(n / draws.size - 0.25) < 0.05 for n in counts.values())  # 1,800 draws
    assert (greedy_draws("random", seed=1) == draws).all()  # seeded
    assert not (greedy_draws("random", seed=2) == draws).all()


@pytest.mark.slow
def test_unseen_random_changes_the_evaluation_not_what_was_learned() -> None:
    contests = [
        tour.Tournament(TABULAR[:1], rounds=1, learn_episodes=300, eval_episodes=300, readings=r)
        for r in (tour.Readings(), tour.Readings(unseen="random"))
    ]
    (lowest,), (random,) = (contest.specs() for contest in contests)
    assert random.config["unseen"] == "random" and "unseen" not in lowest.config
    assert lowest.seed_sequence().entropy == random.seed_sequence().entropy
    assert lowest.seed_sequence().spawn_key == random.seed_sequence().spawn_key
    a = tour.play(settings_of(lowest), lowest.seed_sequence(), 0)
    b = tour.play(settings_of(random), random.seed_sequence(), 0)
    assert a["learn_turns"] == b["learn_turns"] and a["visited_states"] == b["visited_states"]
    assert (a["wins"], a["turns"]) != (b["wins"], b["turns"])


# ----------------------------------------------------------------- unit stats


def test_unit_stats_reach_the_game_s_damage_and_hit_draws() -> None:
    readings = tour.Readings(marine=Unit(4, 2, 1.0), gunner=Unit(5, 3, 1.0))
    (spec,) = tour.Tournament(TABULAR[:1], rounds=1, readings=readings).specs()
    assert spec.config["battlefield"] == {
        "marine": {"hp": 4, "damage": 2, "hit_rate": 1.0},
        "gunner": {"hp": 5, "damage": 3, "hit_rate": 1.0},
    }
    rules = settings_of(spec).rules
    assert rules.n_states == 5**4 * 6**2 * 2**6  # the state space follows the HP
    game = rules.spec()
    env = game.new_env()
    game.kernels.reset(env, np.random.default_rng(0))
    assert env[0].tolist() == [[4, 4, 4, 4, 5, 5]] * 2
    rewards = np.zeros(2)
    # side 0: every marine fires at unit 0, the gunners at unit 4; side 1 holds fire on 5
    joint = np.array([0, 0, 0, 0, 4, 4] + [5] * 6, dtype=np.int64)
    game.kernels.step(env, joint, np.random.default_rng(7), rewards)
    # hit rate 1: every shot lands, 4 x 2 on a 4-HP marine and 2 x 3 on a 5-HP gunner
    assert env[0][1].tolist() == [0, 4, 4, 4, 0, 5]
    # side 1 fired 4 x 2 + 2 x 3 = 14 at side 0's gunner 5: destroyed
    assert env[0][0].tolist() == [4, 4, 4, 4, 5, 0]


def test_a_hit_rate_below_1_misses_as_often_as_it_says() -> None:
    rules = tour.Readings(marine=Unit(3, 1, 0.3)).rules()
    game = rules.spec()
    env = game.new_env()
    rng = np.random.default_rng(3)
    joint = np.array([0, 0, 0, 0, 0, 0] + [0] * 6, dtype=np.int64)
    hits, shots = 0, 0
    for _ in range(4000):
        game.kernels.reset(env, rng)
        game.kernels.step(env, joint, rng, np.zeros(2))
        hits += int(env[4][0, 1, :4].sum())  # the marines' HIT flags, side 0
        shots += 4
    assert abs(hits / shots - 0.3) < 0.02


def test_the_default_readings_are_the_paper_s_battlefield() -> None:
    assert tour.Readings().rules() == battlefield.PAPER
    assert tour.Readings().rules().spec().n_states == battlefield.SPEC.n_states == 802_816
    assert (Unit(3, 1, 0.8), Unit(6, 2, 0.6)) == (MARINE, GUNNER)


def test_unit_stats_a_table_cannot_index_are_refused_for_tabular_learners() -> None:
    huge = tour.Readings(marine=Unit(40, 1, 0.5), gunner=Unit(40, 2, 0.5))
    with pytest.raises(ConfigError, match="marine"):
        tour.Tournament(TABULAR, rounds=1, readings=huge)
    tour.Tournament((LEARNERS["vdn"],), rounds=1, readings=huge)  # a network has no table


# --------------------------------------------------------------- the defaults


def test_default_readings_store_matches_as_before() -> None:
    explicit = tour.Readings(gamma=0.9, tolerance=1e-9, unseen="lowest", marine=MARINE)
    for readings in (tour.Readings(), explicit):
        contest = tour.Tournament(TABULAR, rounds=2, readings=readings)
        for spec in contest.specs():
            assert set(spec.config) == {"algorithms", "learners", "learn_episodes", "eval_episodes"}
    keys = [
        [s.key for s in tour.Tournament(TABULAR, rounds=2, readings=r).specs()]
        for r in (tour.Readings(), explicit)
    ]
    assert keys[0] == keys[1]


def test_default_tournament_plays_the_matches_of_0_5_1() -> None:
    """The reference is the store of cmarl-cd 0.5.1, made before the readings became
    settings (tests/data/tournament-0.5.1.json says how): same seeds, same matches."""
    reference = json.loads((DATA / "tournament-0.5.1.json").read_text())["matches"]
    contest = tour.Tournament(TABULAR, rounds=2, learn_episodes=3000, eval_episodes=3000)
    played = []
    for spec in contest.specs():
        metrics = tour.run(settings_of(spec), spec.seed_sequence())
        kept = {k: v for k, v in metrics.items() if k in reference[0]["metrics"]}
        played.append(
            {
                "algorithms": spec.config["algorithms"],
                "round": spec.run_index,
                "key_config": spec.key.config,  # the same store key: old stores resume
                "metrics": kept,
            }
        )
    played.sort(key=lambda d: (d["algorithms"], d["round"]))
    assert played == reference


# ------------------------------------------------------------------ the store


def stored(
    algorithms: list[str], round_index: int = 0, seed: int = 0, learn: int = 10, **extra
) -> RunRecord:
    """A stored match of ``algorithms`` (as their paper settings, ``gamma=…`` for the
    tabular ones, a dict of name -> γ for each its own) and the readings in ``extra``."""
    gamma = extra.pop("gamma", None)
    learners = []
    for name in algorithms:
        learner = asdict(LEARNERS[name])
        own = gamma.get(name) if isinstance(gamma, dict) else gamma
        if own is not None and name in ("cmarl-cd", "la-oca"):
            learner["gamma"] = own
        learners.append(learner)
    config = {
        "algorithms": algorithms,
        "learners": learners,
        "learn_episodes": learn,
        "eval_episodes": 10,
        **extra,
    }
    key = RunKey("tournament", " vs ".join(algorithms), json.dumps(config), seed, round_index)
    return RunRecord(key=key, metrics={}, wall_seconds=0.0)


def labelled(groups) -> dict[str, list[str]]:
    return {
        match_results.reading_label(match_results.match_reading(g)): sorted(
            r.key.algorithm for r in g
        )
        for g in groups
    }


SURE = {
    kind: {"hp": unit.hp, "damage": unit.damage, "hit_rate": 1.0}
    for kind, unit in (("marine", MARINE), ("gunner", GUNNER))
}


def test_matches_of_two_deep_learners_join_every_tournament_of_their_unit_stats() -> None:
    deep = stored(["vdn", "vdn"])
    default = stored(["cmarl-cd", "vdn"])
    myopic = stored(["cmarl-cd", "vdn"], gamma=0.0)
    other_rules = stored(["cmarl-cd", "vdn"], battlefield=SURE)
    groups = match_results.tournaments([deep, default, myopic, other_rules])
    assert labelled(groups) == {
        "defaults": ["cmarl-cd vs vdn", "vdn vs vdn"],
        "γ = 0": ["cmarl-cd vs vdn", "vdn vs vdn"],
        "hit rate 1": ["cmarl-cd vs vdn"],  # the deep match was played on other rules
    }


def test_a_deep_match_joins_only_tournaments_that_have_both_its_learners() -> None:
    four = ["cmarl-cd", "la-oca", "vdn", "qmix"]
    default = [stored([a, b]) for i, a in enumerate(four) for b in four[i:]]
    lone = stored(["la-oca", "la-oca"], gamma=0.0)  # tournament --algorithms la-oca --gamma 0
    played = {"wins": [1, 1], "ties": 0, "win_turns": [5, 5], "episodes": 2}
    records = [
        RunRecord(r.key, {**played, "sides": r.config["algorithms"]}, 0.0) for r in [*default, lone]
    ]
    groups = match_results.tournaments(records)
    assert labelled(groups)["γ = 0"] == ["la-oca vs la-oca"]
    assert len(labelled(groups)["defaults"]) == 10
    for group in groups:  # every claim is checked, or says why not, without failing
        claims = claim_checks.check_claims(group, match_results.summarize(group))
        assert len(claims) == len(claim_checks.CLAIMS)


def test_tabular_learners_with_settings_of_their_own_stay_one_tournament() -> None:
    own = {"cmarl-cd": 0.5, "la-oca": 0.9}  # possible from the Python API only
    matches = [
        stored(["cmarl-cd", "cmarl-cd"], gamma=own),
        stored(["cmarl-cd", "la-oca"], gamma=own),
        stored(["la-oca", "la-oca"], gamma=own),
    ]
    (group,) = match_results.tournaments(matches)
    assert len(group) == 3
    assert match_results.match_reading(group)["gamma"] == [0.5, 0.9]


def test_seeds_and_budgets_keep_tournaments_apart() -> None:
    matches = [stored(["cmarl-cd", "vdn"]), stored(["cmarl-cd", "vdn"], seed=1)]
    matches += [stored(["cmarl-cd", "vdn"], learn=20), stored(["vdn", "vdn"], seed=1)]
    groups = match_results.tournaments(matches)
    assert sorted(len(g) for g in groups) == [1, 1, 2]
    assert {(g[0].key.root_seed, g[0].config["learn_episodes"]) for g in groups} == {
        (0, 10),
        (1, 10),
        (0, 20),
    }


def test_whole_and_decimal_numbers_are_one_reading() -> None:
    assert tour.Readings(gamma=0) == tour.Readings(gamma=0.0)
    assert Unit(6, 2, 1) == Unit(6.0, 2, 1.0) and isinstance(Unit(6.0, 2, 1).hp, int)
    one = tour.Tournament(TABULAR[:1], rounds=1, readings=tour.Readings(gamma=0))
    other = tour.Tournament(TABULAR[:1], rounds=1, readings=tour.Readings(gamma=0.0))
    assert one.specs()[0].key == other.specs()[0].key


@pytest.mark.parametrize(
    ("stats", "field"),
    [((0, 1, 0.8), "hp"), ((100, 1, 0.8), "hp"), ((3, 10**20, 0.8), "damage"),
     ((3, 1.5, 0.8), "damage"), ((3, 1, 0.0), "hit_rate"), ((3, 1, float("nan")), "hit_rate")],
)  # fmt: skip
def test_impossible_units_are_refused(stats, field) -> None:
    with pytest.raises(ConfigError, match=field):
        Unit(*stats)
