"""The blood battlefield (Section V-B, Fig. 5): two troops fire at each other.

Each side (0 and 1) has the same troop: by default four marines (units 0-3) and two
gunners (units 4-5). Units never move. Every turn each live unit picks a live opponent
(action ``j`` = opponent unit ``j``) and all attacks resolve at once from the turn's
starting state: an attack hits with the attacker's hit rate, a target loses the sum of
the damage of the hits on it (HP floors at 0), and units at 0 HP are destroyed at the end
of the turn. Every unit of a side, alive or not, receives ``+2`` per opponent destroyed
that turn and, when the game ends, ``+10`` for a win, ``-10`` for a loss and ``0`` for a
tie. A side wins when every opponent is destroyed and it still has a live unit; both
troops wiped out in one turn is a tie, and so is a game still running after 100 turns
(the episode cap, :attr:`GameSpec.max_steps`: a truncation, since the turn count is not
part of the state).

A side observes ``s = [hp_1..hp_n, alive_1..alive_n]``: its opponents' HP and which of its
own units are alive (its own HP it does not see). :func:`encode_side_state` numbers it
mixed-radix, opponents' HP first, own alive flags last; a live unit sees one of
``4^4 * 7^2 * 2^5 = 401,408`` states (its own flag is always set), as the paper counts,
and a side's index ranges over twice that, ``802,816``, since it also says which unit is
alive.

Choices the paper leaves open (the documentation's interpretation choices, docs/choices.md):

* [choice] unit stats (Fig. 5 is not in the text): marine HP 3, damage 1, hit rate 0.8;
  gunner HP 6, damage 2, hit rate 0.6 (:data:`MARINE`, :data:`GUNNER`);
* [choice] an attack on a destroyed opponent (only a learner that ignores the masks
  makes one) is lost;
* [choice] a destroyed unit's only legal action is ``0``, and the game ignores what it
  plays, so every agent always has a legal action;
* [choice] hit draws are made in unit order, side 0 first, one per live unit.

The transition is written once, as kernels over the state arrays
``env = (hp, stats, hit_rate, payoff, log, status)`` (:func:`new_env`);
:meth:`Battlefield.spec` wraps them in the game protocol (:mod:`cmarlcd.games.spec`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cmarlcd.compiled import kernel
from cmarlcd.errors import require
from cmarlcd.games.spec import GameKernels, GameSpec

#: The two sides.
N_SIDES = 2
#: ``status[OUTCOME]`` while the game runs, and its values once it has ended by a wipe-out.
RUNNING, WIN_0, WIN_1, TIE = -1, 0, 1, 2
#: Index of the turn counter and of the outcome in ``status``.
TURN, OUTCOME = 0, 1
#: Rows of ``stats``: each slot's full hit points and its damage per hit.
HP, DAMAGE = 0, 1
#: Rows of ``log`` (per side): the target each unit attacked last turn (-1: none) and
#: whether it hit; and the damage each unit received.
TARGET, HIT, RECEIVED = 0, 1, 2
NO_TARGET = -1


#: The largest HP and damage of a unit (the damage a unit receives in a turn is summed
#: over at most eight attackers, far inside int64).
MAX_UNIT_STAT = 99


@dataclass(frozen=True)
class Unit:
    """A kind of unit (Fig. 5): its hit points, damage per hit and hit rate."""

    hp: int
    damage: int
    hit_rate: float

    def __post_init__(self) -> None:
        for name in ("hp", "damage"):
            value = getattr(self, name)
            require(
                float(value).is_integer() and 1 <= value <= MAX_UNIT_STAT,
                name,
                f"must be a whole number in 1..{MAX_UNIT_STAT} (got {value})",
            )
            object.__setattr__(self, name, int(value))  # 6 and 6.0: one unit
        rate = self.hit_rate
        require(
            bool(np.isfinite(rate)) and 0 < rate <= 1, "hit_rate", f"must be in (0, 1] (got {rate})"
        )
        object.__setattr__(self, "hit_rate", float(rate))


#: [choice] The marine (see the documentation's interpretation choices, docs/choices.md).
MARINE = Unit(hp=3, damage=1, hit_rate=0.8)
#: [choice] The gunner.
GUNNER = Unit(hp=6, damage=2, hit_rate=0.6)


@dataclass(frozen=True)
class Battlefield:
    """The rules of one blood battlefield; the defaults are the paper's.

    Both sides field the same troop: ``marines`` marines, then ``gunners`` gunners.
    """

    marine: Unit = MARINE
    """Stats of a marine."""
    gunner: Unit = GUNNER
    """Stats of a gunner."""
    marines: int = 4
    """Marines per side (units ``0..marines-1``)."""
    gunners: int = 2
    """Gunners per side (the next units)."""
    kill_reward: float = 2.0
    """Reward to every unit of a side per opponent destroyed in a turn."""
    win_reward: float = 10.0
    """Reward to the winner (its negative to the loser) when the game ends."""
    max_turns: int = 100
    """A game still running after this many turns is a tie."""

    def __post_init__(self) -> None:
        units = self.marines + self.gunners
        require(self.marines >= 0, "marines", f"must be >= 0 (got {self.marines})")
        require(self.gunners >= 0, "gunners", f"must be >= 0 (got {self.gunners})")
        require(1 <= units <= 8, "units", f"marines + gunners must be in 1..8 (got {units})")
        require(self.max_turns >= 1, "max_turns", f"must be >= 1 (got {self.max_turns})")

    @property
    def units(self) -> tuple[Unit, ...]:
        """One side's units in slot order."""
        return (self.marine,) * self.marines + (self.gunner,) * self.gunners

    @property
    def n_units(self) -> int:
        """Units per side (also each unit's action count: one per opponent slot)."""
        return self.marines + self.gunners

    @property
    def hp_states(self) -> int:
        """Joint HP values the opponents can show: the product of (HP + 1)."""
        return int(np.prod([unit.hp + 1 for unit in self.units]))

    @property
    def n_states(self) -> int:
        """State indices of a side: opponents' HP x which of its own units are alive."""
        return self.hp_states * 2**self.n_units

    @property
    def unit_states(self) -> int:
        """States a live unit can observe (its own alive flag is set): the paper's count."""
        return self.n_states // 2

    def new_env(self) -> tuple[np.ndarray, ...]:
        """Fresh state arrays of one game: see :func:`new_env`."""
        return new_env(self)

    def spec(self) -> GameSpec:
        """The game protocol: 2 x ``n_units`` agents in two teams, states per side."""
        n = self.n_units
        names = [f"marine_{u}" for u in range(self.marines)]
        names += [f"gunner_{u}" for u in range(self.gunners)]
        return GameSpec(
            name="blood_battlefield_v0",
            kernels=KERNELS,
            new_env=self.new_env,
            agents=tuple(f"side{k}_{name}" for k in range(N_SIDES) for name in names),
            action_counts=np.full(N_SIDES * n, n, dtype=np.int64),
            n_states=self.n_states,
            max_steps=self.max_turns,
            teams=(tuple(range(n)), tuple(range(n, 2 * n))),
            n_features=2 * n,
            state_determines_features=True,  # see battle_features
        )


def new_env(rules: Battlefield) -> tuple[np.ndarray, ...]:
    """The state arrays of one game of ``rules``, ``(hp, stats, hit_rate, payoff, log,
    status)``:

    * ``hp`` (2, n) int64: each unit's HP now (0 = destroyed);
    * ``stats`` (2, n) int64: rows HP (full hit points) and DAMAGE (per hit) of each slot;
    * ``hit_rate`` (n,) float64: each slot's hit rate;
    * ``payoff`` (2,) float64: the kill reward and the win reward;
    * ``log`` (2, 3, n) int64: last turn's TARGET and HIT of each unit, and the damage
      RECEIVED by each;
    * ``status`` (2,) int64: TURN and OUTCOME.
    """
    n = rules.n_units
    units = rules.units
    stats = np.array([[u.hp for u in units], [u.damage for u in units]], dtype=np.int64)
    hit_rate = np.array([u.hit_rate for u in units], dtype=np.float64)
    payoff = np.array([rules.kill_reward, rules.win_reward], dtype=np.float64)
    hp = np.zeros((N_SIDES, n), dtype=np.int64)
    log = np.zeros((N_SIDES, 3, n), dtype=np.int64)
    status = np.array([0, RUNNING], dtype=np.int64)
    return hp, stats, hit_rate, payoff, log, status


# ------------------------------------------------------------------------- kernels


@kernel
def battle_reset(env, rng) -> None:
    """Protocol ``reset``: every unit at full HP, turn 0, nothing attacked yet."""
    hp, stats, _, _, log, status = env
    for k in range(N_SIDES):
        for u in range(hp.shape[1]):
            hp[k, u] = stats[HP, u]
            log[k, TARGET, u] = NO_TARGET
            log[k, HIT, u] = 0
            log[k, RECEIVED, u] = 0
    status[TURN] = 0
    status[OUTCOME] = RUNNING


@kernel
def attack(env, joint, rng) -> None:
    """Every live unit fires at its target, all from the turn's starting HP: one hit draw
    per live unit (side 0 first, in unit order); the damage each unit receives is summed
    in ``log[:, RECEIVED]``. An attack on a destroyed opponent is lost."""
    hp, stats, hit_rate, _, log, _ = env
    n = hp.shape[1]
    for k in range(N_SIDES):
        for u in range(n):
            log[k, RECEIVED, u] = 0
    for k in range(N_SIDES):
        for u in range(n):
            log[k, TARGET, u] = NO_TARGET
            log[k, HIT, u] = 0
            if hp[k, u] == 0:
                continue
            target = joint[k * n + u]
            log[k, TARGET, u] = target
            if rng.random() < hit_rate[u] and hp[1 - k, target] > 0:
                log[k, HIT, u] = 1
                log[1 - k, RECEIVED, target] += stats[DAMAGE, u]


@kernel
def battle_step(env, joint, rng, rewards) -> None:
    """Protocol ``step``: one turn (:func:`attack`, then the damage lands at once);
    ``rewards[k]`` := side k's reward: the kill reward per opponent destroyed, plus the
    win reward (or its negative) when the game ends with a winner."""
    hp, _, _, payoff, log, status = env
    n = hp.shape[1]
    attack(env, joint, rng)
    destroyed_0, destroyed_1, alive_0, alive_1 = 0, 0, 0, 0
    for u in range(n):
        for k in range(N_SIDES):
            before = hp[k, u]
            hp[k, u] = max(before - log[k, RECEIVED, u], 0)
            if before > 0 and hp[k, u] == 0:
                if k == 0:
                    destroyed_0 += 1
                else:
                    destroyed_1 += 1
        alive_0 += hp[0, u] > 0
        alive_1 += hp[1, u] > 0
    kill, win = payoff[0], payoff[1]
    rewards[0] = kill * destroyed_1
    rewards[1] = kill * destroyed_0
    status[TURN] += 1
    if alive_0 == 0 and alive_1 == 0:
        status[OUTCOME] = TIE
    elif alive_1 == 0:
        status[OUTCOME] = WIN_0
        rewards[0] += win
        rewards[1] -= win
    elif alive_0 == 0:
        status[OUTCOME] = WIN_1
        rewards[0] -= win
        rewards[1] += win


@kernel
def encode_side_state(hp, stats, side: int) -> int:
    """Side ``side``'s state index: its opponents' HP (mixed radix HP + 1, slot 0 the
    least significant), then its own units' alive flags (bit ``u`` for unit ``u``)."""
    n = hp.shape[1]
    index, radix = 0, 1
    for j in range(n):
        index += hp[1 - side, j] * radix
        radix *= stats[HP, j] + 1
    for u in range(n):
        if hp[side, u] > 0:
            index += radix << u
    return index


@kernel
def battle_state(env, team: int) -> int:
    """Protocol ``state``: :func:`encode_side_state` of side ``team``."""
    return encode_side_state(env[0], env[1], team)


@kernel
def battle_done(env) -> bool:
    """Protocol ``done``: a troop has been wiped out (the 100-turn tie is the cap)."""
    return env[5][OUTCOME] != RUNNING


@kernel
def battle_legal(env, masks) -> None:
    """Protocol ``legal``: a live unit may fire at any live opponent; a destroyed unit's
    only action is 0 (ignored)."""
    hp = env[0]
    n = hp.shape[1]
    for k in range(N_SIDES):
        for u in range(n):
            agent = k * n + u
            for j in range(masks.shape[1]):
                masks[agent, j] = False
            if hp[k, u] == 0:
                masks[agent, 0] = True
            else:
                for j in range(n):
                    masks[agent, j] = hp[1 - k, j] > 0


@kernel
def battle_features(env, team: int, out) -> None:
    """Protocol ``features``: side ``team``'s state ``s`` as numbers, [choice] each
    opponent's HP as a fraction of its full HP, then 1.0 / 0.0 for each own unit alive
    (the same information as the state index, scaled to [0, 1] for the networks)."""
    hp, stats = env[0], env[1]
    n = hp.shape[1]
    for j in range(n):
        out[j] = hp[1 - team, j] / stats[HP, j]
    for u in range(n):
        out[n + u] = 1.0 if hp[team, u] > 0 else 0.0


#: The compiled protocol of every battlefield (the rules travel in the state arrays).
KERNELS = GameKernels(
    battle_reset, battle_step, battle_state, battle_done, battle_legal, battle_features
)


def decode_side_state(index: int, rules: Battlefield) -> tuple[tuple[int, ...], tuple[bool, ...]]:
    """Inverse of :func:`encode_side_state`: (opponents' HP, own units alive)."""
    require(0 <= index < rules.n_states, "state", f"must be in [0, {rules.n_states})")
    hp = []
    for unit in rules.units:
        index, value = divmod(index, unit.hp + 1)
        hp.append(value)
    alive = tuple(bool(index >> u & 1) for u in range(rules.n_units))
    return tuple(hp), alive


def outcome(env) -> int:
    """RUNNING, WIN_0, WIN_1 or TIE (a game cut at ``max_turns`` is still RUNNING)."""
    return int(env[5][OUTCOME])


#: The paper's battlefield.
PAPER = Battlefield()
#: Its protocol: 12 agents in two teams of 6, 802,816 state indices per side, 100 turns.
SPEC = PAPER.spec()
