"""Two teams, two learners: compiled matches of any two-team game (learning, then greedy
evaluation).

Each side of a match is driven by its own learner (any pairing, self-play included) from
its own side's state (``game.state(env, k)``, or ``game.features`` for the deep
learners) and its own reward (``rewards[k]``). Both learn during the learning stage
(:meth:`Match.learn`) and play their fixed greedy strategies in the evaluation stage
(:meth:`Match.evaluate`).

The loops (:func:`learn_match`, :func:`evaluate_match`) see a side only through its
*side kernels* (:class:`SideKernels`): a tabular learner's side
(:mod:`cmarlcd.training.sides`) maps states to table rows and calls the learner's own
kernels; a deep side (:mod:`cmarlcd.training.deep_side`) acts with its networks'
compiled forward pass and fills its replay buffer. The learning loop can stop in the
middle of an episode and go on where it stopped (its place is kept in ``clock``), so a
deep side takes its gradient steps every ``train_every`` turns, exactly on schedule, in
Python, between two calls.

Both loops are templates (:mod:`cmarlcd.compiled`) bound to the game's kernels and the
two sides' kernels (``first``, ``second``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from cmarlcd.compiled import Unbound, kernel, shared_kernel, specialise
from cmarlcd.errors import require
from cmarlcd.games.spec import GameSpec
from cmarlcd.progress import report_progress

game = Unbound("game")
first = Unbound("first")
second = Unbound("second")

#: Episodes per compiled call while learning (progress is reported between calls).
CHUNK_EPISODES = 2000
#: Entries of a learning stage's ``clock``: episodes finished, turns into the current
#: episode (-1 between episodes), whether its last turn still awaits ``observe``, and
#: the turns played so far.
EPISODES, LENGTH, PENDING, TURNS = range(4)


class SideKernels(NamedTuple):
    """How the match loops drive one side (``side`` is the side's own NamedTuple of
    arrays; ``offset`` its first agent in the game's joint action and masks).

    ``fits(side, max_steps)``: one more episode fits in the side's memory;
    ``enter(side, env, team, offset, legal, length) -> key``: the side observes the state
    of turn ``length`` (``key`` names it for ``act`` and ``observe``);
    ``act(side, key, rng, joint)``: its joint action while learning;
    ``observe(side, t, next_key, terminal)``: turn ``t`` led to ``next_key``;
    ``end_episode(side, length)``; ``pause(side)``: stop the loop now (a deep side's
    gradient step is due); ``greedy(side, env, team, offset, legal, rng, joint)``: its
    fixed greedy joint action (``rng``, the side's evaluation stream, for what it plays
    where it has no greedy choice).
    """

    fits: Any
    enter: Any
    act: Any
    observe: Any
    end_episode: Any
    pause: Any
    greedy: Any


def learn_match(env, a, b, episodes, max_steps, env_rng, rng_a, rng_b, clock) -> None:
    """Template: learning turns until ``clock[EPISODES] == episodes``, a side asks for a
    pause, or a side's memory might not hold another episode (a call then goes on where
    the last one stopped).

    Per turn, for each side: it enters the state (its first visit initialises it), the
    previous turn is handed to ``observe``, and it acts; then the game steps on both
    sides' actions at once. After each episode, each side's ``end_episode``.
    """
    n_a, n_b = a.counts.shape[0], b.counts.shape[0]
    legal = np.zeros((n_a + n_b, max(a.counts.max(), b.counts.max())), dtype=np.bool_)
    joint = np.zeros(n_a + n_b, dtype=np.int64)
    team_rewards = np.zeros(2)
    while clock[EPISODES] < episodes:
        if clock[LENGTH] < 0:
            if not (first.fits(a, max_steps) and second.fits(b, max_steps)):
                return
            game.reset(env, env_rng)
            clock[LENGTH] = 0
        length = clock[LENGTH]
        terminal = length > 0 and game.done(env)
        key_a, key_b = 0, 0
        if not terminal:
            key_a = first.enter(a, env, 0, 0, legal, length)
            key_b = second.enter(b, env, 1, n_a, legal, length)
        if clock[PENDING]:
            first.observe(a, length - 1, key_a, terminal)
            second.observe(b, length - 1, key_b, terminal)
            clock[PENDING] = 0
            if first.pause(a) or second.pause(b):
                return
        if terminal or length == max_steps:
            first.end_episode(a, length)
            second.end_episode(b, length)
            clock[EPISODES] += 1
            clock[LENGTH] = -1
            continue
        first.act(a, key_a, rng_a, joint[:n_a])
        second.act(b, key_b, rng_b, joint[n_a:])
        game.step(env, joint, env_rng, team_rewards)
        record_turn(a, length, joint[:n_a], team_rewards[0])
        record_turn(b, length, joint[n_a:], team_rewards[1])
        clock[LENGTH] = length + 1
        clock[PENDING] = 1
        clock[TURNS] += 1


@shared_kernel  # takes a plug-in's tables: see cmarlcd.compiled.shared_kernel
def record_turn(side, t: int, joint, reward: float) -> None:
    """Write turn ``t`` (the side's joint action and reward) into the side's episode."""
    for i in range(joint.shape[0]):
        side.joints[t, i] = joint[i]
    side.rewards[t] = reward


def evaluate_match(env, a, b, episodes, max_steps, env_rng, rng_a, rng_b, tally) -> None:
    """Template: ``episodes`` episodes with both sides' fixed greedy strategies, counted
    in ``tally`` (see :func:`record_outcome`); ``rng_a`` and ``rng_b`` are the sides'
    own evaluation streams."""
    n_a, n_b = a.counts.shape[0], b.counts.shape[0]
    legal = np.zeros((n_a + n_b, max(a.counts.max(), b.counts.max())), dtype=np.bool_)
    joint = np.zeros(n_a + n_b, dtype=np.int64)
    team_rewards = np.zeros(2)
    for _ in range(episodes):
        game.reset(env, env_rng)
        turns, return_a, return_b = 0, 0.0, 0.0
        while turns < max_steps:
            first.greedy(a, env, 0, 0, legal, rng_a, joint[:n_a])
            second.greedy(b, env, 1, n_a, legal, rng_b, joint[n_a:])
            game.step(env, joint, env_rng, team_rewards)
            return_a += team_rewards[0]
            return_b += team_rewards[1]
            turns += 1
            if game.done(env):
                break
        record_outcome(tally, game.done(env), return_a, return_b, turns)


#: Entries of an evaluation's tally: wins of side 0 and of side 1, ties, the turns of
#: side 0's and side 1's wins, and all turns.
WINS_A, WINS_B, TIES, WIN_TURNS_A, WIN_TURNS_B, ALL_TURNS = range(6)


@kernel
def record_outcome(tally, terminated: bool, return_a: float, return_b: float, turns: int) -> None:
    """Count one episode. [choice] A side won an episode that terminated with its return
    above the other's, an episode cut at the turn cap or with equal returns is a tie. On
    the battlefield this is exactly its rule: a winner has destroyed all six opponents
    and returns at least 6 x 2 + 10 = 22, the loser at most 5 x 2 - 10 = 0, and a mutual
    wipe-out gives both sides 12."""
    if terminated and return_a > return_b:
        tally[WINS_A] += 1
        tally[WIN_TURNS_A] += turns
    elif terminated and return_b > return_a:
        tally[WINS_B] += 1
        tally[WIN_TURNS_B] += turns
    else:
        tally[TIES] += 1
    tally[ALL_TURNS] += turns


@dataclass(frozen=True)
class MatchResult:
    """An evaluation stage: episodes won by each side, tied, and their turns."""

    episodes: int
    wins: tuple[int, int]
    ties: int
    win_turns: tuple[int, int]
    """Total turns of each side's won episodes."""
    turns: int

    def win_rate(self, side: int) -> float:
        return self.wins[side] / self.episodes

    def win_steps(self, side: int) -> float:
        """Average turns of the side's won episodes (NaN when it won none)."""
        return self.win_turns[side] / self.wins[side] if self.wins[side] else float("nan")


class MatchSide:
    """What :class:`Match` asks of one side's learner (see :mod:`cmarlcd.training.sides`
    and :mod:`cmarlcd.training.deep_side`)."""

    kernels: SideKernels
    data: tuple
    """The side's arrays, as its kernels read them."""

    def between_calls(self) -> None:
        """Work due when the learning loop has stopped (grow tables, a gradient step)."""

    def visited(self) -> int:
        """States the side holds values for (0 when it generalises across states)."""
        return 0

    def memory_bytes(self) -> int:
        """Bytes of the side's tables, or networks and replay buffer."""
        return 0

    def due(self) -> bool:
        """Whether the side stopped the loop for work only its batch can do."""
        return False

    def freeze(self) -> None:
        """The match has finished learning (a side trained in a batch keeps its values)."""


class Match:
    """Two learners, one per side of a two-team game, with their own streams.

    Args:
        spec: a game of two teams.
        configs: each side's learner config (tabular or deep).
        env_rng: the game's randomness, while learning.
        agent_rngs: each side's randomness (actions; a deep side also spawns its own
            parameter and replay streams from it).
        learn_episodes: the learning stage's length, known in advance because a deep
            side's ε is annealed over it (eq. 18).
        sides: the sides, when made elsewhere (:class:`MatchBatch`); by default each
            config's side on its own.
        unseen: what a tabular side plays at evaluation in a state it never visited,
            ``"lowest"`` (default) or ``"random"``
            (:func:`cmarlcd.training.sides.tabular_greedy`).
    """

    def __init__(
        self,
        spec: GameSpec,
        configs: Sequence[Any],
        env_rng: np.random.Generator,
        agent_rngs: Sequence[np.random.Generator],
        learn_episodes: int,
        sides: Sequence[MatchSide] | None = None,
        unseen: str = "lowest",
    ) -> None:
        from cmarlcd.training.sides import new_side

        require(
            spec.n_teams == 2, "game", f"a match needs two teams; {spec.name} has {spec.n_teams}"
        )
        require(learn_episodes >= 1, "learn_episodes", f"must be >= 1 (got {learn_episodes})")
        self.spec, self.configs = spec, tuple(configs)
        self.env = spec.new_env()
        self.env_rng, self.agent_rngs = env_rng, tuple(agent_rngs)
        self.learn_episodes = int(learn_episodes)
        self.sides = (
            list(sides)
            if sides is not None
            else [
                new_side(spec, team, config, rng, self.learn_episodes, unseen)
                for team, (config, rng) in enumerate(zip(configs, agent_rngs, strict=True))
            ]
        )
        bound = {"game": spec.kernels, "first": self.sides[0].kernels}
        bound["second"] = self.sides[1].kernels
        self._learn = specialise(learn_match, **bound)
        self._evaluate = specialise(evaluate_match, **bound)
        self.clock = np.array([0, -1, 0, 0], dtype=np.int64)

    @property
    def episodes(self) -> int:
        """Learning episodes played so far."""
        return int(self.clock[EPISODES])

    @property
    def turns(self) -> int:
        """Learning turns played so far."""
        return int(self.clock[TURNS])

    def learn(self, episodes: int | None = None) -> None:
        """Both sides learn for ``episodes`` more episodes (default: the rest of the
        learning stage), progress reported as episodes finish."""
        target = self.learn_episodes if episodes is None else self.episodes + int(episodes)
        require(
            target <= self.learn_episodes,
            "episodes",
            f"the learning stage has {self.learn_episodes} episodes",
        )
        while self.episodes < target:
            before = self.episodes
            self.advance(min(target, before + CHUNK_EPISODES))
            report_progress(float(self.episodes - before))

    def advance(self, goal: int) -> None:
        """One call of the compiled loop towards ``goal`` learning episodes, then the
        sides' work between calls."""
        a, b = (side.data for side in self.sides)
        self._learn(
            self.env, a, b, goal, self.spec.max_steps, self.env_rng, *self.agent_rngs, self.clock
        )
        for side in self.sides:
            side.between_calls()

    def due(self) -> bool:
        """Whether a side waits for its batch's gradient step."""
        return any(side.due() for side in self.sides)

    def evaluate(self, episodes: int, rng: np.random.Generator) -> MatchResult:
        """Both sides' greedy strategies for ``episodes`` episodes, the game's randomness
        drawn from ``rng``; what the sides draw themselves (a tabular side's unseen
        states, ``unseen="random"``) comes from two streams spawned from ``rng``'s seed,
        which leave the game's draws as they are."""
        tally = np.zeros(6, dtype=np.int64)
        a, b = (side.data for side in self.sides)
        rng_a, rng_b = rng.spawn(2)
        self._evaluate(self.env, a, b, int(episodes), self.spec.max_steps, rng, rng_a, rng_b, tally)
        report_progress(float(episodes))
        return MatchResult(
            int(episodes),
            (int(tally[WINS_A]), int(tally[WINS_B])),
            int(tally[TIES]),
            (int(tally[WIN_TURNS_A]), int(tally[WIN_TURNS_B])),
            int(tally[ALL_TURNS]),
        )

    def visited(self, side: int) -> int:
        """States side ``side`` holds values for (0 for a deep side)."""
        return self.sides[side].visited()

    def memory_bytes(self) -> int:
        """Bytes held by both sides' tables, or networks and replay buffers."""
        return sum(side.memory_bytes() for side in self.sides)


class MatchBatch:
    """Matches of one pairing (e.g. the rounds of a tournament) learning together, so
    that each deep learner's sides train as one stacked model
    (:class:`cmarlcd.training.deep_side.DeepGroup`): each match runs until its deep
    sides have played ``train_every`` more turns, then every group takes one gradient
    step for all its matches. Each match plays exactly what it would alone (up to float
    rounding in the batched products), and is evaluated with the strategies it finished
    learning with.

    Args:
        spec: a game of two teams.
        configs: the pairing: the learner config of each of its two positions.
        positions: for each match, the positions that play side 0 and side 1
            (``(0, 1)`` or ``(1, 0)``: rounds may swap sides).
        env_rngs, agent_rngs: each match's streams (per side), as for :class:`Match`.
        learn_episodes: each match's learning stage.
        unseen: what the tabular sides play in states they never visited (see
            :class:`Match`).
    """

    def __init__(
        self,
        spec: GameSpec,
        configs: Sequence[Any],
        positions: Sequence[tuple[int, int]],
        env_rngs: Sequence[np.random.Generator],
        agent_rngs: Sequence[Sequence[np.random.Generator]],
        learn_episodes: int,
        unseen: str = "lowest",
    ) -> None:
        from cmarlcd.training.sides import new_sides

        self.learn_episodes = int(learn_episodes)
        sides, self.groups = new_sides(spec, configs, positions, agent_rngs, learn_episodes, unseen)
        self.matches = [
            Match(
                spec,
                [configs[p] for p in order],
                env_rng,
                rngs,
                learn_episodes,
                sides=match_sides,
            )
            for order, env_rng, rngs, match_sides in zip(
                positions, env_rngs, agent_rngs, sides, strict=True
            )
        ]

    def learn(self) -> None:
        """Every match learns for its whole learning stage."""
        total = self.learn_episodes
        while any(m.episodes < total for m in self.matches):
            for match in self.matches:
                before = match.episodes
                while match.episodes < total and not match.due():
                    match.advance(min(total, match.episodes + CHUNK_EPISODES))
                if match.episodes >= total:
                    for side in match.sides:
                        side.freeze()
                report_progress(float(match.episodes - before))
            for group in self.groups:
                group.train()
