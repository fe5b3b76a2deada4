"""Level-Based Foraging (``games/foraging``): every rule on a hand-made state, the
observations, resets, the ParallelEnv, task names, and a short form of the check against
the ``lbforaging`` package (``benchmarks/check_foraging.py`` runs it at full length)."""

from __future__ import annotations

import numpy as np
import pytest
from pettingzoo.test import parallel_api_test, parallel_seed_test

from cmarlcd.errors import ConfigError
from cmarlcd.games.foraging import Foraging, ForagingEnv
from cmarlcd.games.foraging import kernels as k

NONE, NORTH, SOUTH, WEST, EAST, LOAD = range(6)


def place(rules: Foraging, agents: list[tuple[int, int, int]], foods: dict) -> tuple:
    """A game of ``rules`` in a hand-made state: agents (row, column, level), foods
    {(row, column): level}; ``food_spawned`` their levels summed."""
    env = rules.new_env()
    players, field, _, status, _, _ = env
    for i, (row, col, level) in enumerate(agents):
        players[i] = (row, col, level)
    for (row, col), level in foods.items():
        field[row, col] = level
    status[k.STEP], status[k.FOOD_SPAWNED], status[k.OVER] = 0, sum(foods.values()), 0
    return env


def step(env: tuple, *actions: int) -> float:
    """One step of the compiled game; the team's reward."""
    team = np.zeros(1)
    k.forage_step(env, np.array(actions, dtype=np.int64), np.random.default_rng(0), team)
    return float(team[0])


def cells(env: tuple) -> list[tuple[int, int]]:
    return [(int(r), int(c)) for r, c, _ in env[0]]


RULES = Foraging(size=5, players=2, foods=1)


# ------------------------------------------------------------------- loading


def test_two_agents_load_a_food_that_needs_both() -> None:
    """Levels 1 and 2 next to a level-3 food: together they load it, each rewarded in
    proportion to its level, normalised so that the episode's foods make 1."""
    env = place(RULES, [(2, 1, 1), (1, 2, 2)], {(2, 2): 3})
    team = step(env, LOAD, LOAD)
    assert env[1][2, 2] == 0
    assert env[4][:2].tolist() == [1 * 3 / (3 * 3), 2 * 3 / (3 * 3)]
    assert team == pytest.approx(1.0)
    assert k.forage_done(env)  # no food left


def test_one_agent_alone_fails_and_pays_the_penalty() -> None:
    rules = Foraging(size=5, players=2, foods=1, penalty=0.1)
    env = place(rules, [(2, 1, 1), (1, 2, 2)], {(2, 2): 3})
    team = step(env, LOAD, NONE)
    assert env[1][2, 2] == 3  # still there
    assert env[4][:2].tolist() == [-0.1, 0.0]
    assert team == -0.1 and not k.forage_done(env)


def test_a_strong_enough_agent_loads_alone_and_the_food_counts_its_share() -> None:
    """Two foods (levels 2 and 4): the first loaded alone is worth 2/6 of the episode."""
    rules = Foraging(size=7, players=2, foods=2)
    env = place(rules, [(1, 2, 2), (5, 5, 1)], {(1, 1): 2, (4, 5): 4})
    assert step(env, LOAD, NONE) == pytest.approx(2 / 6)
    assert env[4][:2].tolist() == [2 * 2 / (2 * 6), 0.0]
    assert not k.forage_done(env)


def test_an_agent_next_to_a_food_that_does_not_load_is_not_counted() -> None:
    env = place(RULES, [(2, 1, 2), (1, 2, 2)], {(2, 2): 2})
    step(env, LOAD, NONE)
    assert env[4][:2].tolist() == [1.0, 0.0]  # the whole food to the loader


# ------------------------------------------------------------------- moves


def test_moves_and_invalid_actions() -> None:
    env = place(RULES, [(0, 0, 1), (4, 4, 1)], {(2, 2): 1})
    step(env, NORTH, EAST)  # both off the grid: played as NONE
    assert cells(env) == [(0, 0), (4, 4)]
    step(env, SOUTH, WEST)
    assert cells(env) == [(1, 0), (4, 3)]
    env = place(RULES, [(2, 1, 1), (4, 4, 1)], {(2, 2): 1})
    step(env, EAST, LOAD)  # onto the food: invalid; LOAD with no food near: invalid
    assert cells(env) == [(2, 1), (4, 4)] and env[1][2, 2] == 1


def test_two_agents_aiming_at_one_cell_both_stay() -> None:
    env = place(RULES, [(0, 0, 1), (0, 2, 1)], {(3, 3): 1})
    step(env, EAST, WEST)
    assert cells(env) == [(0, 0), (0, 2)]


def test_an_agent_cannot_enter_the_cell_of_one_that_stays_but_two_can_swap() -> None:
    env = place(RULES, [(0, 0, 1), (0, 1, 1)], {(3, 3): 1})
    step(env, EAST, NONE)
    assert cells(env) == [(0, 0), (0, 1)]
    step(env, EAST, WEST)
    assert cells(env) == [(0, 1), (0, 0)]
    step(env, EAST, EAST)  # a train: the leader's cell is free when the follower moves
    assert cells(env) == [(0, 2), (0, 1)]


def test_the_step_cap_truncates_where_the_last_food_terminates() -> None:
    rules = Foraging(size=5, players=2, foods=1, max_steps=3)
    assert rules.spec().max_steps == 3
    env = ForagingEnv(rules)
    env.reset(seed=0)
    for _ in range(3):
        _, _, terminations, truncations, _ = env.step(dict.fromkeys(env.agents, NONE))
    assert not any(terminations.values()) and all(truncations.values()) and not env.agents


def test_masks_are_every_action_unless_invalid_ones_are_masked() -> None:
    masks = np.zeros((2, 6), dtype=np.bool_)
    env = place(RULES, [(0, 0, 1), (2, 1, 1)], {(2, 2): 1})
    k.forage_legal(env, masks)
    assert masks.all()
    env = place(Foraging(size=5, players=2, foods=1, mask_invalid=True), [(0, 0, 1), (2, 1, 1)],
                {(2, 2): 1})  # fmt: skip
    k.forage_legal(env, masks)
    assert masks[0].tolist() == [True, False, True, False, True, False]
    assert masks[1].tolist() == [True, True, True, True, False, True]


# ------------------------------------------------------------------- observations


def observation(env: tuple, rules: Foraging, agent: int) -> list[float]:
    out = np.zeros(rules.players * rules.observation_size, dtype=np.float32)
    k.forage_features(env, 0, out)
    width = rules.observation_size
    return out[agent * width : (agent + 1) * width].tolist()


def test_full_sight_sees_everything_in_absolute_coordinates_itself_first() -> None:
    rules = Foraging(size=5, players=2, foods=2)
    env = place(rules, [(0, 0, 1), (4, 4, 2)], {(2, 2): 3})
    assert observation(env, rules, 1) == [2, 2, 3, -1, -1, 0, 4, 4, 2, 0, 0, 1]


def test_a_food_at_the_edge_of_sight_is_seen_and_one_beyond_is_not() -> None:
    rules = Foraging(size=7, players=2, foods=2, sight=1)
    env = place(rules, [(3, 3, 1), (0, 6, 1)], {(4, 4): 2, (5, 1): 1})
    # the window is rows and columns 2..4: (4, 4) at its corner, (5, 1) outside
    assert observation(env, rules, 0) == [2, 2, 2, -1, -1, 0, 1, 1, 1, -1, -1, 0]


def test_at_the_grid_s_edge_the_window_is_cut_and_agents_further_in_are_seen() -> None:
    """At (0, 0) with sight 2 the food window is rows and columns 0..2, but the package
    sees agents up to 2 * sight cells in: one at (3, 4) is seen, one at (5, 0) is not."""
    rules = Foraging(size=7, players=3, foods=1, sight=2)
    env = place(rules, [(0, 0, 2), (3, 4, 1), (5, 0, 1)], {(3, 2): 2})
    assert observation(env, rules, 0) == [-1, -1, 0, 0, 0, 2, 3, 4, 1, -1, -1, 0]


# ------------------------------------------------------------------- resets


def reset_many(rules: Foraging, count: int, seed: int = 0):
    env, rng = rules.new_env(), np.random.default_rng(seed)
    for _ in range(count):
        k.forage_reset(env, rng)
        yield env


def test_resets_place_foods_apart_off_the_border_and_agents_on_free_cells() -> None:
    rules = Foraging(size=8, players=3, foods=3)
    for env in reset_many(rules, 2000):
        players, field = env[0], env[1]
        foods = np.argwhere(field > 0)
        assert len(foods) == 3 and env[3][k.FOOD_SPAWNED] == field.sum()
        assert foods.min() >= 1 and foods.max() <= 6
        for a in foods:
            for b in foods:
                gap = np.abs(a - b)
                assert (a == b).all() or (gap.max() >= 2 and gap.sum() >= 3)
        assert len(set(cells(env))) == 3
        assert all(field[r, c] == 0 for r, c in cells(env))
        assert field.max() <= np.sort(players[:, k.LEVEL])[:3].sum()


def test_coop_foods_are_at_the_sum_of_the_lowest_levels() -> None:
    rules = Foraging(size=8, players=4, foods=2, coop=True)
    for env in reset_many(rules, 500):
        lowest = np.sort(env[0][:, k.LEVEL])[:3].sum()
        assert set(env[1][env[1] > 0].tolist()) == {lowest}


def test_an_agent_never_starts_where_it_or_a_later_agent_stood_last_time() -> None:
    """The package's quirk: a reset sees the cells the agents not yet placed stand on."""
    rules = Foraging(size=3, players=2, foods=1)
    before = None
    for env in reset_many(rules, 3000):
        now = cells(env)
        if before is not None:
            assert now[0] not in before and now[1] != before[1]
        before = now


def test_the_same_seed_plays_the_same_episodes() -> None:
    first = [env[0].copy().tolist() + env[1].tolist() for env in reset_many(RULES, 20, seed=4)]
    again = [env[0].copy().tolist() + env[1].tolist() for env in reset_many(RULES, 20, seed=4)]
    other = [env[0].copy().tolist() + env[1].tolist() for env in reset_many(RULES, 20, seed=5)]
    assert first == again and first != other


# ------------------------------------------------------------------- names


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("8x8-2p-2f-coop", Foraging(8, 2, 2, coop=True)),
        ("2s-10x10-3p-3f", Foraging(10, 3, 3, sight=2)),
        ("Foraging-2s-8x8-2p-2f-coop-v3", Foraging(8, 2, 2, sight=2, coop=True)),
        ("15x15-4p-5f,penalty=0.1,max_steps=100", Foraging(15, 4, 5, penalty=0.1, max_steps=100)),
    ],
)
def test_task_names(text: str, expected: Foraging) -> None:
    assert Foraging.from_name(text) == expected
    assert Foraging.from_name(expected.name) == expected


@pytest.mark.parametrize(
    "text",
    ["8x9-2p-2f", "8x8-2p", "8x8-0p-1f", "8x8-2p-2f,penalty=-1", "8x8-2p-2f,speed=3",
     "8x8-2p-2f,max_steps=1.5", "8x8-2p-2f,coop=maybe", "2x2-1p-1f", "9s-8x8-2p-2f",
     "8x8-2p-2f,penalty"],
)  # fmt: skip
def test_bad_names_and_rules_are_refused(text: str) -> None:
    with pytest.raises(ConfigError):
        Foraging.from_name(text)


def test_state_indices_where_they_fit() -> None:
    small = Foraging(5, 2, 1)
    assert small.indexed and small.n_states == (25 * 2) ** 2 * (1 + 25 * 4)
    seen = {int(k.forage_state(env, 0)) for env in reset_many(small, 300)}
    assert len(seen) > 250 and max(seen) < small.n_states
    big = Foraging.from_name("15x15-4p-5f")
    assert not big.indexed and big.n_states == 1


# ------------------------------------------------------------------- the env


def test_parallel_api() -> None:
    parallel_api_test(ForagingEnv("5x5-2p-1f"), num_cycles=300)
    parallel_api_test(ForagingEnv("2s-8x8-3p-2f-coop,mask_invalid=true"), num_cycles=300)


def test_parallel_seed() -> None:
    parallel_seed_test(lambda: ForagingEnv("6x6-2p-2f"), num_cycles=50)


def test_env_observations_are_the_package_layout_and_in_their_spaces() -> None:
    env = ForagingEnv("2s-8x8-2p-2f")
    observations, infos = env.reset(seed=3)
    for agent, observation in observations.items():
        assert observation.shape == (12,) and observation.dtype == np.float32
        assert env.observation_space(agent).contains(observation)
        assert infos[agent]["action_mask"].tolist() == [1] * 6
    assert np.array_equal(env.state(), np.concatenate(list(observations.values())))
    assert "levels A:" in env.render()


# ------------------------------------------------------------------- the package


def test_equal_to_the_package_step_for_step() -> None:
    pytest.importorskip("lbforaging")
    from cmarlcd.testing.foraging import compare_steps

    for name in ("8x8-2p-2f-coop", "2s-8x8-3p-3f,penalty=0.2", "5x5-4p-1f"):
        report = compare_steps(Foraging.from_name(name), 1500, seed=1)
        assert report.equal, report.mismatches
        assert report.loads > 0


def test_resets_distributed_as_the_package_s() -> None:
    pytest.importorskip("lbforaging")
    from cmarlcd.testing.foraging import compare_resets

    report = compare_resets(Foraging.from_name("6x6-3p-2f-coop"), 3000, seed=2)
    assert report.equal, report.p_values
