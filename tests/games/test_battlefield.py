"""The blood battlefield (Section V-B, Fig. 5; the interpretation choices).

Expected values are worked out by hand from the rules: each side fields marines in
slots 0-3 (HP 3, damage 1) and gunners in slots 4-5 (HP 6, damage 2); agents 0-5 are
side 0's units 0-5 and agents 6-11 side 1's, and action ``j`` fires at opponent slot ``j``.
Hand-made positions use rules whose hit rates are 1 (every attack hits) or ``NEVER`` (no
attack ever hits), so no outcome depends on a draw.
"""

from __future__ import annotations

import math
from itertools import product

import numba
import numpy as np
import pytest
from pettingzoo.test import parallel_api_test, parallel_seed_test

from cmarlcd.errors import ConfigError
from cmarlcd.games.battlefield import (
    PAPER,
    RUNNING,
    SPEC,
    TIE,
    WIN_0,
    WIN_1,
    Battlefield,
    BattlefieldEnv,
    Unit,
    decode_side_state,
    encode_side_state,
    outcome,
)
from cmarlcd.games.battlefield.kernels import HIT, KERNELS, NO_TARGET, RECEIVED, TARGET

#: A hit rate so small that no attack hits in any test (Unit needs a rate in (0, 1]).
NEVER = 1e-12
#: Every attack hits.
SURE = Battlefield(marine=Unit(3, 1, 1.0), gunner=Unit(6, 2, 1.0))
#: Nothing ever hits: a stalemate.
STALEMATE = Battlefield(marine=Unit(3, 1, NEVER), gunner=Unit(6, 2, NEVER))
FULL = [3, 3, 3, 3, 6, 6]
DAMAGE = [1, 1, 1, 1, 2, 2]
DEAD = 0  # a destroyed unit's (only legal) action

_reset, _step, _state, _done, _legal, _features = KERNELS


def battle(rules: Battlefield, side0: list[int], side1: list[int]) -> tuple[np.ndarray, ...]:
    """A game of ``rules`` in which the units have the given HP (0 = destroyed)."""
    env = rules.new_env()
    _reset(env, np.random.default_rng(0))
    env[0][0] = side0
    env[0][1] = side1
    return env


def turn(env, actions0: list[int], actions1: list[int], seed: int = 0) -> list[float]:
    """Play one turn; the two sides' rewards."""
    joint = np.array(actions0 + actions1, dtype=np.int64)
    rewards = np.full(2, np.nan)
    _step(env, joint, np.random.default_rng(seed), rewards)
    return rewards.tolist()


def hp(env) -> list[list[int]]:
    return env[0].tolist()


def legal(env) -> np.ndarray:
    masks = np.zeros((12, 6), dtype=np.bool_)
    _legal(env, masks)
    return masks


def expected_masks(hp_now: np.ndarray) -> np.ndarray:
    """A live unit may fire at any live opponent; a destroyed unit only plays 0."""
    masks = np.zeros((12, 6), dtype=np.bool_)
    for k, u in product(range(2), range(6)):
        if hp_now[k, u] > 0:
            masks[6 * k + u] = hp_now[1 - k] > 0
        else:
            masks[6 * k + u, 0] = True
    return masks


def random_legal_joint(hp_now: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Each live unit fires at a uniformly drawn live opponent; destroyed units play 0."""
    joint = np.zeros(12, dtype=np.int64)
    for k, u in product(range(2), range(6)):
        targets = np.flatnonzero(hp_now[1 - k] > 0)
        if hp_now[k, u] > 0 and targets.size:
            joint[6 * k + u] = rng.choice(targets)
    return joint


def mirror(side0: list, side1: list) -> tuple[list, list]:
    return side1, side0


# ---------------------------------------------------------------------- the rules


def test_sizes_match_the_paper() -> None:
    assert PAPER.n_units == 6
    assert [(u.hp, u.damage) for u in PAPER.units] == list(zip(FULL, DAMAGE, strict=True))
    assert [u.hit_rate for u in PAPER.units] == [0.8] * 4 + [0.6] * 2
    assert SPEC.n_agents == 12 and SPEC.teams == (tuple(range(6)), tuple(range(6, 12)))
    assert SPEC.action_counts.tolist() == [6] * 12
    assert SPEC.max_steps == 100
    assert PAPER.unit_states == 4**4 * 7**2 * 2**5 == 401_408
    assert PAPER.n_states == SPEC.n_states == 2 * 401_408 == 802_816


def test_reset_puts_every_unit_at_full_hp() -> None:
    env = battle(SURE, [0] * 6, [1] * 6)
    _reset(env, np.random.default_rng(3))
    assert hp(env) == [FULL, FULL]
    assert not _done(env) and outcome(env) == RUNNING
    for side in (0, 1):
        assert decode_side_state(_state(env, side), PAPER) == (tuple(FULL), (True,) * 6)
    assert (legal(env) == np.ones((12, 6), dtype=np.bool_)).all()


def test_damage_is_the_sum_of_the_hits_on_a_target() -> None:
    # Side 0's M0, M1 and G4 all fire at side 1's G4 (6 HP): 1 + 1 + 2 = 4 -> 2 HP left.
    # Side 1 all fire at side 0's M0 (3 HP): 4 * 1 + 2 * 2 = 8 -> destroyed (floor 0); it
    # still fires this turn, as attacks resolve from the turn's starting state.
    env = battle(SURE, [3, 3, 0, 0, 6, 0], FULL)
    rewards = turn(env, [4, 4, DEAD, DEAD, 4, DEAD], [0] * 6)
    assert hp(env) == [[0, 3, 0, 0, 6, 0], [3, 3, 3, 3, 2, 6]]
    assert rewards == [0.0, 2.0]
    assert outcome(env) == RUNNING and not _done(env)


def test_gunner_at_2_hp_hit_by_a_gunner_and_missed_by_a_marine_is_destroyed() -> None:
    # The paper's example: marines never hit here, gunners always do.
    rules = Battlefield(marine=Unit(3, 1, NEVER), gunner=Unit(6, 2, 1.0))
    env = battle(rules, [3, 0, 0, 0, 6, 0], [3, 0, 0, 0, 2, 0])
    rewards = turn(env, [4, DEAD, DEAD, DEAD, 4, DEAD], [0, DEAD, DEAD, DEAD, 0, DEAD])
    # side 0's M0 takes the gunner's 2 (the marine misses): 3 -> 1
    assert hp(env) == [[1, 0, 0, 0, 6, 0], [3, 0, 0, 0, 0, 0]]
    assert rewards == [2.0, 0.0]
    assert outcome(env) == RUNNING


def test_hp_floors_at_zero_when_overkilled() -> None:
    # Side 0's gunners (2 + 2) on side 1's 1-HP M0, its marines (4 * 1) on the 3-HP M1;
    # side 1's whole troop (4 + 4) on side 0's 3-HP M0.
    env = battle(SURE, [3, 3, 3, 3, 6, 6], [1, 3, 3, 3, 6, 6])
    turn(env, [1, 1, 1, 1, 0, 0], [0, 0, 0, 0, 0, 0])
    assert hp(env) == [[0, 3, 3, 3, 6, 6], [0, 0, 3, 3, 6, 6]]


@pytest.mark.parametrize("swap", [False, True])
def test_units_that_destroy_each_other_are_both_destroyed(swap: bool) -> None:
    # Two 1-HP marines fire at each other: both hit, both are destroyed; a tie, and each
    # side gets the kill reward only.
    rules = Battlefield(marine=Unit(1, 1, 1.0), gunner=Unit(6, 2, 1.0))
    side0, side1 = [1, 0, 0, 0, 0, 0], [0, 1, 0, 0, 0, 0]
    actions0, actions1 = [1, DEAD, DEAD, DEAD, DEAD, DEAD], [DEAD, 0, DEAD, DEAD, DEAD, DEAD]
    if swap:
        side0, side1 = mirror(side0, side1)
        actions0, actions1 = mirror(actions0, actions1)
    env = battle(rules, side0, side1)
    rewards = turn(env, actions0, actions1)
    assert hp(env) == [[0] * 6, [0] * 6]
    assert outcome(env) == TIE and _done(env)
    assert rewards == [2.0, 2.0]


def test_mutual_wipe_out_of_several_units_is_a_tie_with_kill_rewards_only() -> None:
    # Side 0: M0 (1 HP), G4 (2 HP); side 1: M1 (1 HP), G4 (2 HP).
    # Side 0: M0 -> M1 (1 on 1 HP), G4 -> G4 (2 on 2 HP); side 1: M1 -> M0, G4 -> G4 likewise.
    env = battle(SURE, [1, 0, 0, 0, 2, 0], [0, 1, 0, 0, 2, 0])
    rewards = turn(env, [1, DEAD, DEAD, DEAD, 4, DEAD], [DEAD, 0, DEAD, DEAD, 4, DEAD])
    assert hp(env) == [[0] * 6, [0] * 6]
    assert outcome(env) == TIE and _done(env)
    assert rewards == [4.0, 4.0]  # two kills each, no win reward


@pytest.mark.parametrize("swap", [False, True])
def test_winner_gets_10_loser_minus_10_plus_kill_rewards(swap: bool) -> None:
    # Side 0: M0 (3), M1 (1), G4 (6). Side 1: M0 (1), G4 (2).
    # Side 0: M0 -> M0 (1: dies), M1 -> G4 (1), G4 -> G4 (2): 3 on 2 HP, dies.
    # Side 1: M0 -> M1 (1), G4 -> M1 (2): M1 takes 3 on 1 HP, dies.
    # Side 0 wins with M0 and G4 left: 2 kills + 10 = 14; side 1: 1 kill - 10 = -8.
    side0, side1 = [3, 1, 0, 0, 6, 0], [1, 0, 0, 0, 2, 0]
    actions0, actions1 = [0, 4, DEAD, DEAD, 4, DEAD], [1, DEAD, DEAD, DEAD, 1, DEAD]
    after = [[3, 0, 0, 0, 6, 0], [0] * 6]
    expected, winner = [14.0, -8.0], WIN_0
    if swap:
        side0, side1 = mirror(side0, side1)
        actions0, actions1 = mirror(actions0, actions1)
        after = after[::-1]
        expected, winner = expected[::-1], WIN_1
    env = battle(SURE, side0, side1)
    rewards = turn(env, actions0, actions1)
    assert hp(env) == after
    assert outcome(env) == winner and _done(env)
    assert rewards == expected


def test_kill_rewards_count_every_opponent_destroyed_this_turn() -> None:
    # Side 0's four marines each kill a 1-HP marine of side 1's (3 kills: M0..M2), side
    # 1's gunners kill side 0's 1-HP M3 (1 kill); nobody is wiped out.
    env = battle(SURE, [3, 3, 3, 1, 6, 6], [1, 1, 1, 3, 6, 6])
    rewards = turn(env, [0, 1, 2, 3, 4, 4], [4, 4, 4, 4, 3, 3])
    # side 0's G4 takes 4 * 1 -> 2; side 1's M3 takes 1 -> 2, its G4 takes 2 + 2 -> 2
    assert hp(env) == [[3, 3, 3, 0, 2, 6], [0, 0, 0, 2, 2, 6]]
    assert rewards == [6.0, 2.0]
    assert outcome(env) == RUNNING
    # a turn without kills is worth nothing: side 0 fires at destroyed M0 (lost), side 1's
    # M3, G4 and G5 at side 0's G5 (6 HP): 1 + 2 + 2 = 5 -> 1
    assert turn(env, [0, 0, 0, DEAD, 0, 0], [DEAD, DEAD, DEAD, 5, 5, 5]) == [0.0, 0.0]
    assert hp(env) == [[3, 3, 3, 0, 2, 1], [0, 0, 0, 2, 2, 6]]


def test_a_destroyed_unit_does_not_act_and_cannot_be_hit() -> None:
    # Side 0's M0 is destroyed but its action points at side 1's live G4; side 1's
    # gunners fire at that destroyed M0 (lost attacks).
    env = battle(SURE, [0, 3, 3, 3, 6, 6], FULL)
    rewards = turn(env, [4, 0, 0, 0, 1, 1], [1, 1, 1, 1, 0, 0])
    # side 1: M0 takes 3 * 1 -> 0, M1 takes 2 + 2 -> 0, G4 untouched (6)
    # side 0: M1 takes 4 * 1 -> 0, M0 stays destroyed
    assert hp(env) == [[0, 0, 3, 3, 6, 6], [0, 0, 3, 3, 6, 6]]
    assert rewards == [4.0, 2.0]
    log = env[4]
    assert log[0, TARGET, 0] == NO_TARGET and log[0, HIT, 0] == 0
    assert log[1, RECEIVED, 4] == 0  # the destroyed M0's target took nothing
    assert log[0, RECEIVED, 0] == 0  # the gunners' shots at the destroyed M0 were lost
    assert log[1, HIT, 4] == log[1, HIT, 5] == 0
    # Masks: live units may only fire at M2, M3, G4, G5; destroyed units only play 0.
    live = [False, False, True, True, True, True]
    only_0 = [True, False, False, False, False, False]
    masks = legal(env)
    for k, u in product(range(2), range(6)):
        assert masks[6 * k + u].tolist() == (only_0 if u < 2 else live)


def random_episode(rules: Battlefield, seed: int, masked: bool = True) -> list:
    """One game of random actions, checking the rules after every turn."""
    env = rules.new_env()
    game_rng, action_rng = np.random.default_rng(seed), np.random.default_rng(seed + 10_000)
    _reset(env, game_rng)
    full = np.array([u.hp for u in rules.units])
    damage = np.array([u.damage for u in rules.units])
    rewards = np.zeros(2)
    turns = []
    for _ in range(rules.max_turns):
        before = env[0].copy()
        masks = legal(env)
        assert (masks == expected_masks(before)).all()
        if masked:
            joint = random_legal_joint(before, action_rng)
            assert all(masks[i, a] for i, a in enumerate(joint))
        else:
            joint = action_rng.integers(0, 6, size=12)
        _step(env, joint, game_rng, rewards)
        after = env[0]
        assert (after >= 0).all() and (after <= full).all()
        assert (after[before == 0] == 0).all()  # the destroyed stay destroyed
        log = env[4]
        received = np.zeros((2, 6), dtype=np.int64)
        for k, u in product(range(2), range(6)):
            target = log[k, TARGET, u]
            if before[k, u] == 0:
                assert target == NO_TARGET  # dead units do not act
                continue
            assert target == joint[6 * k + u]
            if log[k, HIT, u]:  # a hit: only ever on an opponent alive at the turn's start
                assert before[1 - k, target] > 0
                received[1 - k, target] += damage[u]
        assert (after == np.maximum(before - received, 0)).all()
        kills = ((before > 0) & (after == 0)).sum(axis=1)
        alive = (after > 0).any(axis=1)
        expected = [2.0 * kills[1], 2.0 * kills[0]]
        if alive[0] and not alive[1]:
            expected = [expected[0] + 10, expected[1] - 10]
            assert outcome(env) == WIN_0
        elif alive[1] and not alive[0]:
            expected = [expected[0] - 10, expected[1] + 10]
            assert outcome(env) == WIN_1
        elif not alive.any():
            assert outcome(env) == TIE
        else:
            assert outcome(env) == RUNNING
        assert rewards.tolist() == expected
        assert bool(_done(env)) == (not alive.all())
        turns.append(before)
        if _done(env):
            break
    return turns


@pytest.mark.parametrize("masked", [True, False])
def test_random_episodes_obey_the_rules(masked: bool) -> None:
    finished = 0
    for seed in range(150):
        turns = random_episode(PAPER, seed, masked)
        finished += len(turns) < 100
    assert finished > 100  # most random battles end well before the cap


def test_random_episodes_with_sure_hits_obey_the_rules() -> None:
    for seed in range(100):
        random_episode(SURE, seed, masked=seed % 2 == 0)


def test_hit_rates_marine_08_gunner_06() -> None:
    # Unit u of each side alone against unit u of the other: the damage each takes is the
    # opponent's damage with its hit rate, else 0.
    trials = 4000
    for u in range(6):
        env = PAPER.new_env()
        rng = np.random.default_rng(u)
        _reset(env, rng)
        side = [0] * 6
        side[u] = FULL[u]
        joint = np.full(12, u, dtype=np.int64)
        rewards = np.zeros(2)
        hits = 0
        for _ in range(trials):
            env[0][0] = side
            env[0][1] = side
            _step(env, joint, rng, rewards)
            taken = FULL[u] - env[0][:, u]
            assert set(taken.tolist()) <= {0, DAMAGE[u]}
            hits += int((taken > 0).sum())
        rate = 0.8 if u < 4 else 0.6
        n = 2 * trials
        assert abs(hits / n - rate) < 4 * math.sqrt(rate * (1 - rate) / n)


# ------------------------------------------------------------------ state indices


def test_features_are_the_state_vector_scaled() -> None:
    """s = [opponents' HP / full HP, own units alive] (the paper's, scaled for the networks)."""
    env = PAPER.new_env()
    _reset(env, np.random.default_rng(0))
    env[0][:] = [[3, 0, 2, 1, 6, 0], [1, 3, 0, 3, 3, 6]]
    out = np.zeros(SPEC.n_features)
    _features(env, 0, out)
    assert out.tolist() == pytest.approx([1 / 3, 1, 0, 1, 0.5, 1, 1, 0, 1, 1, 1, 0])
    _features(env, 1, out)
    assert out.tolist() == pytest.approx([1, 0, 2 / 3, 1 / 3, 1, 0, 1, 1, 0, 1, 1, 1])


def test_state_round_trip_on_random_positions() -> None:
    rng = np.random.default_rng(7)
    stats = PAPER.new_env()[1]
    full = np.array(FULL)
    for _ in range(2000):
        position = rng.integers(0, full + 1, size=(2, 6))
        for side in (0, 1):
            index = int(encode_side_state(position, stats, side))
            assert 0 <= index < PAPER.n_states
            opponents, alive = decode_side_state(index, PAPER)
            assert opponents == tuple(position[1 - side].tolist())
            assert alive == tuple((position[side] > 0).tolist())
            for u in np.flatnonzero(position[side]):  # a live unit sees its own flag set
                assert decode_side_state(index, PAPER)[1][u]
            # a side does not see its own HP, only whether each unit is alive
            other = position.copy()
            other[side] = np.where(position[side] > 0, rng.integers(1, full + 1), 0)
            assert int(encode_side_state(other, stats, side)) == index
    for index in rng.integers(0, PAPER.n_states, size=2000):
        opponents, alive = decode_side_state(int(index), PAPER)
        position = np.zeros((2, 6), dtype=np.int64)
        position[1] = opponents
        position[0] = np.where(alive, full, 0)
        assert int(encode_side_state(position, stats, 0)) == index
        assert int(encode_side_state(position[::-1].copy(), stats, 1)) == index
    for bad in (-1, PAPER.n_states):
        with pytest.raises(ConfigError) as error:
            decode_side_state(bad, PAPER)
        assert error.value.parameter == "state"


@numba.njit
def _encode_every_position(stats, side, opponent_hps):
    """The index of every (opponents' HP, own alive flags) of ``side``, alive as bits."""
    n = stats.shape[1]
    position = np.zeros((2, n), dtype=np.int64)
    out = np.zeros((opponent_hps.shape[0], 2**n), dtype=np.int64)
    for c in range(opponent_hps.shape[0]):
        for alive in range(2**n):
            for u in range(n):
                position[1 - side, u] = opponent_hps[c, u]
                position[side, u] = 1 + (c + u) % stats[0, u] if alive >> u & 1 else 0
            out[c, alive] = encode_side_state(position, stats, side)
    return out


@pytest.mark.parametrize("side", [0, 1])
def test_a_side_has_802816_distinct_states_a_live_unit_401408(side: int) -> None:
    opponent_hps = np.array(list(product(*(range(h + 1) for h in FULL))), dtype=np.int64)
    assert opponent_hps.shape[0] == 4**4 * 7**2
    indices = _encode_every_position(PAPER.new_env()[1], side, opponent_hps)
    assert indices.min() >= 0 and indices.max() < 802_816
    # one index per position, and every index used
    assert (np.bincount(indices.ravel(), minlength=802_816) == 1).all()
    patterns = np.arange(64)
    for u in range(6):
        with_u_alive = indices[:, (patterns >> u & 1) == 1].ravel()
        distinct = np.count_nonzero(np.bincount(with_u_alive, minlength=802_816))
        assert distinct == 4**4 * 7**2 * 2**5 == PAPER.unit_states


# ------------------------------------------------------------------------ symmetry


@numba.njit
def _random_battles(env, episodes, max_turns, game_rng, action_rng):
    """Win counts of side 0 and side 1, and ties, over games of uniformly random legal
    actions; the winner read off the HP (the side with a live unit left)."""
    hp = env[0]
    n = hp.shape[1]
    joint = np.zeros(2 * n, dtype=np.int64)
    rewards = np.zeros(2)
    counts = np.zeros(3, dtype=np.int64)
    for _ in range(episodes):
        _reset(env, game_rng)
        for _ in range(max_turns):
            for k in range(2):
                live = 0
                for j in range(n):
                    live += hp[1 - k, j] > 0
                for u in range(n):
                    joint[k * n + u] = 0
                    if hp[k, u] > 0:
                        pick = int(action_rng.random() * live)
                        for j in range(n):
                            if hp[1 - k, j] > 0:
                                if pick == 0:
                                    joint[k * n + u] = j
                                    break
                                pick -= 1
            _step(env, joint, game_rng, rewards)
            if _done(env):
                break
        alive0, alive1 = False, False
        for u in range(n):
            alive0 = alive0 or hp[0, u] > 0
            alive1 = alive1 or hp[1, u] > 0
        if alive0 and not alive1:
            counts[0] += 1
        elif alive1 and not alive0:
            counts[1] += 1
        else:
            counts[2] += 1
    return counts


def test_random_sides_win_equally_often() -> None:
    env = PAPER.new_env()
    wins0, wins1, ties = _random_battles(
        env, 20_000, 100, np.random.default_rng(1), np.random.default_rng(2)
    )
    assert wins0 + wins1 + ties == 20_000
    assert wins0 + wins1 > 15_000
    assert abs(wins0 - wins1) < 4 * math.sqrt(wins0 + wins1)


# --------------------------------------------------------------------- ParallelEnv


def test_parallel_api() -> None:
    env = BattlefieldEnv()
    parallel_api_test(env, num_cycles=300)
    assert env.metadata["name"] == "blood_battlefield_v0"
    assert env.possible_agents[:6] == [f"side0_marine_{u}" for u in range(4)] + [
        f"side0_gunner_{u}" for u in range(2)
    ]
    assert env.possible_agents[6:] == [a.replace("side0", "side1") for a in env.possible_agents[:6]]
    for agent in env.possible_agents:
        assert env.action_space(agent).n == 6
        assert env.observation_space(agent).n == 802_816
    assert env.state_space.n == 802_816
    parallel_api_test(BattlefieldEnv(STALEMATE), num_cycles=300)  # 100 turns, then truncated


def test_parallel_seed() -> None:
    parallel_seed_test(BattlefieldEnv, num_cycles=50)


def test_env_runs_the_same_game_as_the_kernels() -> None:
    env = BattlefieldEnv()
    game = PAPER.new_env()
    rng, action_rng = np.random.default_rng(5), np.random.default_rng(6)
    rewards = np.zeros(2)
    asymmetric = 0
    for episode in range(20):
        observations, infos = env.reset(seed=5 if episode == 0 else None)
        _reset(game, rng)
        steps = 0
        while True:
            states = [_state(game, 0), _state(game, 1)]
            assert env.state() == env.state(0) == states[0] and env.state(1) == states[1]
            assert decode_side_state(env.state(1), PAPER) == (
                tuple(env.hp[0].tolist()),
                tuple((env.hp[1] > 0).tolist()),
            )
            if (env.hp[0] != env.hp[1]).any():
                asymmetric += 1
                assert env.state(0) != env.state(1)
            # every agent of the last step (all of them) observes its side's state
            assert observations == {a: states[i // 6] for i, a in enumerate(env.possible_agents)}
            masks = legal(game)
            for i, agent in enumerate(env.possible_agents):
                assert infos[agent]["action_mask"].dtype == np.int8
                assert infos[agent]["action_mask"].tolist() == masks[i].astype(int).tolist()
            if not env.agents:
                break
            before = env.hp.copy()
            joint = random_legal_joint(game[0], action_rng)
            actions = dict(zip(env.agents, joint.tolist(), strict=True))
            observations, team_rewards, terminations, truncations, infos = env.step(actions)
            _step(game, joint, rng, rewards)
            steps += 1
            assert (env.hp == game[0]).all()
            assert team_rewards == {a: rewards[i // 6] for i, a in enumerate(env.possible_agents)}
            taken = [infos[a]["damage_taken"] for a in env.possible_agents]
            lost = (before - env.hp).ravel()
            assert all(d == min(t, h) for d, t, h in zip(lost, taken, before.ravel(), strict=True))
            assert set(terminations.values()) == {bool(_done(game))}
            assert set(truncations.values()) == {not _done(game) and steps == 100}
            assert env.turn == steps
    assert asymmetric > 20


def test_stalemate_is_truncated_after_100_turns_as_a_running_game() -> None:
    env = BattlefieldEnv(STALEMATE)
    assert env.spec.max_steps == 100
    env.reset(seed=0)
    fire = {agent: 0 for agent in env.possible_agents}
    for step in range(1, 101):
        assert env.agents == env.possible_agents
        _, rewards, terminations, truncations, _ = env.step(fire)
        assert set(rewards.values()) == {0.0}
        assert set(terminations.values()) == {False}
        assert set(truncations.values()) == {step == 100}
    assert env.agents == []
    assert env.hp.tolist() == [FULL, FULL]
    assert env.turn == 100 and env.outcome == RUNNING and not _done(env.env)
    assert env.render_text().splitlines()[-1] == "tie (100 turns)"
    with pytest.raises(RuntimeError, match="reset"):
        env.step(fire)


def test_a_game_won_on_turn_100_is_a_win_not_a_truncation() -> None:
    env = BattlefieldEnv(SURE)
    env.reset(seed=0)
    fire = {agent: 0 for agent in env.possible_agents}  # the two M0s fire at each other
    for _ in range(99):  # both lose 1 HP a turn; put them back at 3 HP before each turn
        env.hp[:] = [[3, 0, 0, 0, 0, 0], [3, 0, 0, 0, 0, 0]]
        _, rewards, terminations, truncations, _ = env.step(fire)
        assert set(rewards.values()) == {0.0}
        assert not any(terminations.values()) and not any(truncations.values())
    env.hp[:] = [[3, 0, 0, 0, 0, 0], [1, 0, 0, 0, 0, 0]]
    _, rewards, terminations, truncations, _ = env.step(fire)
    assert env.turn == 100 and env.outcome == WIN_0
    assert all(terminations.values()) and not any(truncations.values())
    assert {a: r for a, r in rewards.items() if a.startswith("side0")} == dict.fromkeys(
        env.possible_agents[:6], 12.0
    )
    assert {a: r for a, r in rewards.items() if a.startswith("side1")} == dict.fromkeys(
        env.possible_agents[6:], -10.0
    )


def test_state_of_a_bad_side_raises() -> None:
    env = BattlefieldEnv()
    env.reset(seed=0)
    for bad in (2, -1):
        with pytest.raises(ConfigError) as error:
            env.state(bad)
        assert error.value.parameter == "side"


def test_render_shows_hp_attacks_destroyed_units_and_outcome(
    capsys: pytest.CaptureFixture[str],
) -> None:
    env = BattlefieldEnv(SURE, render_mode="ansi")
    env.reset(seed=0)
    text = env.render()
    lines = text.splitlines()
    side0 = next(line for line in lines if line.startswith("side 0"))
    side1 = next(line for line in lines if line.startswith("side 1"))
    for line in (side0, side1):
        assert all(f"M{u} 3/3" in line for u in range(4))
        assert all(f"G{u} 6/6" in line for u in (4, 5))
    assert "->" not in text
    # everyone fires at slot 0: both M0 take 4 + 4 = 8 and are destroyed
    env.step({agent: 0 for agent in env.agents})
    text = env.render()
    assert "M0->M0" in text and "G5->M0" in text
    for k in (0, 1):
        line = next(line for line in text.splitlines() if line.startswith(f"side {k}:"))
        assert "M0 x" in line and "M1 3/3" in line and "M0 3/3" not in line
    assert "wins" not in text and "tie" not in text
    # side 1 down to G5 at 1 HP; side 0's M1 finishes it and side 0 wins
    env.hp[1] = [0, 0, 0, 0, 0, 1]
    targets = {agent: 5 if agent.startswith("side0") else 1 for agent in env.agents}
    _, _, terminations, _, _ = env.step(targets)
    assert all(terminations.values())
    text = env.render()
    assert text.splitlines()[-1] == "side 0 wins"
    assert "G5 x" in next(line for line in text.splitlines() if line.startswith("side 1:"))
    human = BattlefieldEnv(render_mode="human")
    human.reset(seed=1)
    assert human.render() is None
    assert "G4 6/6" in capsys.readouterr().out


# -------------------------------------------------------------------- validation


@pytest.mark.parametrize(
    ("make", "parameter"),
    [
        (lambda: Unit(hp=0, damage=1, hit_rate=0.5), "hp"),
        (lambda: Unit(hp=3, damage=0, hit_rate=0.5), "damage"),
        (lambda: Unit(hp=3, damage=1, hit_rate=0.0), "hit_rate"),
        (lambda: Unit(hp=3, damage=1, hit_rate=1.5), "hit_rate"),
        (lambda: Unit(hp=3, damage=1, hit_rate=float("nan")), "hit_rate"),
        (lambda: Battlefield(marines=0, gunners=0), "units"),
        (lambda: Battlefield(marines=-1), "marines"),
        (lambda: Battlefield(gunners=-1), "gunners"),
        (lambda: Battlefield(max_turns=0), "max_turns"),
        (lambda: BattlefieldEnv(render_mode="rgb_array"), "render_mode"),
    ],
)
def test_bad_configuration_raises_config_error(make, parameter: str) -> None:
    with pytest.raises(ConfigError) as error:
        make()
    assert error.value.parameter == parameter
