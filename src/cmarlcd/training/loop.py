"""The one training loop: episodes of a game of one or two teams, played through sides.

Each team of a game is played by one *side* (:mod:`cmarlcd.training.protocol`): a tabular
learner, VDN or QMIX, or a fixed policy. A cooperative game of one team is a play with one
side; a two-team game (the battlefield) is a match, one side per team, any pairing and
self-play included. Each side acts from its own team's state (``game.state(env, k)``,
or ``game.features`` for the deep learners) and learns from its own reward
(``rewards[k]``).

Two compiled templates (:mod:`cmarlcd.compiled`), bound to the game's kernels and the two
sides' kernels (``first``, ``second``; a one-team game's second side is :class:`NoSide`,
which has no agents and does nothing):

* :func:`learn_turns` -- the learning stage. It can stop in the middle of an episode and
  go on where it stopped (its place is kept in ``clock``): when a side's memory might
  not hold another episode (tables grow between calls) and when a side asks for a pause
  (a deep side's gradient step every ``train_every`` turns, taken in Python between two
  calls, exactly on schedule).
* :func:`play_greedy` -- the evaluation stage: every side plays its fixed greedy strategy,
  and each episode's returns, length and termination are written down.

:class:`Play` drives one game; :class:`PlayBatch` drives plays that learn together, so
that the deep sides of many plays (the rounds of a tournament pairing, the seeds of a
DSN row) train as one stacked model (:class:`cmarlcd.training.deep_side.DeepGroup`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from cmarlcd.compiled import Unbound, shared_kernel, specialise
from cmarlcd.errors import require
from cmarlcd.games.spec import GameSpec
from cmarlcd.progress import report_progress
from cmarlcd.training.protocol import ENDED, EPISODES, IDLE, LENGTH, PENDING, TURNS, Side

game = Unbound("game")
first = Unbound("first")
second = Unbound("second")

#: Episodes per compiled call while learning (progress is reported between calls).
CHUNK_EPISODES = 2000
#: The most teams a game may have: the loop is compiled for a first and a second side.
MAX_TEAMS = 2
#: What a learning budget counts: episodes, or environment steps (turns).
BUDGET_UNITS = ("episodes", "steps")


def learn_turns(env, a, b, width, episodes, max_steps, env_rng, rng_a, rng_b, clock) -> None:
    """Template: learning turns until ``clock[EPISODES] == episodes``, a side asks for a
    pause, or a side's memory might not hold another episode (a call then goes on where
    the last one stopped).

    Per turn, for each side: it enters the state (its first visit initialises it), the
    previous turn is handed to ``observe``, and it acts; then the game steps on both
    sides' actions at once. After each episode (terminated, or cut at ``max_steps``),
    each side's ``end_episode``. A pause comes right after the ``observe`` that asked for
    it; ``clock[ENDED]`` then says whether that turn was the episode's last. The clock is
    read into locals on entry and written back on every return.
    """
    n_a, n_b = a.counts.shape[0], b.counts.shape[0]
    legal = np.zeros((n_a + n_b, width), dtype=np.bool_)
    joint = np.zeros(n_a + n_b, dtype=np.int64)
    team_rewards = np.zeros(2)
    done, length, pending, turns = clock[EPISODES], clock[LENGTH], clock[PENDING], clock[TURNS]
    ended = 0
    while done < episodes:
        if length < 0:
            if not (first.fits(a, max_steps) and second.fits(b, max_steps)):
                break
            game.reset(env, env_rng)
            length = 0
        terminal = length > 0 and game.done(env)
        over = terminal or length == max_steps
        key_a = first.enter(a, env, 0, 0, legal, length, terminal)
        key_b = second.enter(b, env, 1, n_a, legal, length, terminal)
        if pending:
            first.observe(a, length - 1, key_a, terminal)
            second.observe(b, length - 1, key_b, terminal)
            pending = 0
            if first.pause(a) or second.pause(b):
                ended = 1 if over else 0
                break
        if over:
            first.end_episode(a, length)
            second.end_episode(b, length)
            done += 1
            length = -1
            continue
        first.act(a, key_a, rng_a, joint[:n_a])
        second.act(b, key_b, rng_b, joint[n_a:])
        game.step(env, joint, env_rng, team_rewards)
        record_turn(a, length, joint[:n_a], team_rewards[0])
        record_turn(b, length, joint[n_a:], team_rewards[1])
        length += 1
        pending = 1
        turns += 1
    clock[EPISODES], clock[LENGTH], clock[PENDING], clock[TURNS] = done, length, pending, turns
    clock[ENDED] = ended


@shared_kernel  # takes a plug-in's tables: see cmarlcd.compiled.shared_kernel
def record_turn(side, t: int, joint, reward: float) -> None:
    """Write turn ``t`` (the side's joint action and reward) into the side's episode."""
    for i in range(joint.shape[0]):
        side.joints[t, i] = joint[i]
    side.rewards[t] = reward


def play_greedy(
    env, a, b, width, episodes, max_steps, env_rng, rng_a, rng_b, returns, lengths, terminated
) -> None:
    """Template: ``episodes`` episodes with both sides' fixed greedy strategies, writing
    each episode's return of each team (``returns[e, k]``, undiscounted), its turns and
    whether it terminated (rather than reaching ``max_steps``). ``rng_a`` and ``rng_b``
    are the sides' own evaluation streams."""
    n_a, n_b = a.counts.shape[0], b.counts.shape[0]
    legal = np.zeros((n_a + n_b, width), dtype=np.bool_)
    joint = np.zeros(n_a + n_b, dtype=np.int64)
    team_rewards = np.zeros(2)
    for e in range(episodes):
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
        returns[e, 0], returns[e, 1] = return_a, return_b
        lengths[e] = turns
        terminated[e] = game.done(env)


# ------------------------------------------------------------- the absent side


class NoSideData(NamedTuple):
    """The second side of a one-team game: no agents, nothing to learn."""

    counts: np.ndarray
    joints: np.ndarray
    rewards: np.ndarray


class NoSide(Side):
    """The absent second side of a one-team game."""

    kernels = IDLE

    def __init__(self, max_steps: int) -> None:
        self.data = NoSideData(
            np.zeros(0, np.int64), np.zeros((max_steps, 0), np.int64), np.zeros(max_steps)
        )


# ------------------------------------------------------------------------ plays


@dataclass(frozen=True)
class Outcome:
    """An evaluation stage: per episode, each team's undiscounted return, the turns
    played and whether the episode terminated (rather than reaching the step cap)."""

    returns: np.ndarray
    """(episodes, teams)"""
    lengths: np.ndarray
    terminated: np.ndarray


class Play:
    """One game played by its sides (one per team), with the game's own stream.

    Args:
        spec: a game of one or two teams.
        sides: one side per team, in team order.
        env_rng: the game's randomness while learning.
        agent_rngs: each side's randomness while learning.
    """

    def __init__(
        self,
        spec: GameSpec,
        sides: Sequence[Side],
        env_rng: np.random.Generator,
        agent_rngs: Sequence[np.random.Generator],
    ) -> None:
        require(
            1 <= spec.n_teams <= MAX_TEAMS,
            "game",
            f"the loop plays games of 1 to {MAX_TEAMS} teams; {spec.name} has {spec.n_teams}",
        )
        require(len(sides) == spec.n_teams, "sides", "needs one side per team of the game")
        self.spec, self.sides = spec, list(sides)
        self.env = spec.new_env()
        self._eval_env = spec.new_env()
        """The evaluation's own game: an evaluation between two turns of a learning
        episode leaves that episode as it was."""
        self.env_rng, self.agent_rngs = env_rng, tuple(agent_rngs)
        self._all = self.sides + [NoSide(spec.max_steps)] * (MAX_TEAMS - len(self.sides))
        self._rngs = self.agent_rngs + (env_rng,) * (MAX_TEAMS - len(self.agent_rngs))
        self._streams = (env_rng, *self._rngs)
        self._width, self._max_steps = spec.width, spec.max_steps
        bound = {"game": spec.kernels, "first": self._all[0].kernels}
        bound["second"] = self._all[1].kernels
        self._learn = specialise(learn_turns, **bound)
        self._play_greedy = specialise(play_greedy, **bound)
        self.clock = np.array([0, -1, 0, 0, 0], dtype=np.int64)

    @property
    def episodes(self) -> int:
        """Learning episodes whose end-of-episode work is done."""
        return int(self.clock[EPISODES])

    @property
    def finished(self) -> int:
        """Learning episodes played to their last turn (one more than :attr:`episodes`
        when the loop paused at an episode's last turn)."""
        return int(self.clock[EPISODES] + self.clock[ENDED])

    @property
    def turns(self) -> int:
        """Learning turns played so far."""
        return int(self.clock[TURNS])

    def advance(self, goal: int) -> None:
        """One call of the compiled loop towards ``goal`` learning episodes, then the
        sides' work between calls."""
        a, b = (side.data for side in self._all)
        self._learn(self.env, a, b, self._width, goal, self._max_steps, *self._streams, self.clock)
        for side in self.sides:
            side.between_calls()

    def learn_until(self, goal: int) -> None:
        """Call the loop until ``goal`` learning episodes are done (a side that pauses
        takes its step between calls on its own)."""
        while self.episodes < goal:
            self.advance(goal)
            self.require_alone()

    def learned_turns(self, goal: int) -> bool:
        """Whether ``goal`` learning turns are played and the episode they end in is
        done: a budget of environment steps ends at the end of the episode in which it is
        reached (as EPyMARL's ``t_max`` does)."""
        return self.turns >= goal and self.clock[LENGTH] < 0

    def episode_goal(self, turns: int) -> int:
        """How many episodes the loop may finish, at most, before the first episode end
        at or after ``turns`` learning turns: each episode lasts at most ``max_steps``
        turns, so fewer episodes than this cannot reach ``turns`` (at least one more,
        where ``turns`` is reached inside the episode in play)."""
        left = max(turns - self.turns, 1)
        return self.episodes + -(-left // self._max_steps)

    def learn_turns_until(self, goal: int) -> None:
        """Call the loop until ``goal`` learning turns are played, and the episode they
        end in (:meth:`learned_turns`); whatever the calls, the play stops at the same
        turn, with the same streams."""
        while not self.learned_turns(goal):
            self.learn_until(self.episode_goal(goal))

    def require_alone(self) -> None:
        """Refuse to go on when a side waits for its group's step: a play whose deep
        sides learn in a group learns through its :class:`PlayBatch`."""
        require(
            not self.due(),
            "play",
            "a side of this play learns in a batch with other plays: call the batch's "
            "learn(), not the play's",
        )

    def due(self) -> bool:
        """Whether a side waits for its group's gradient step."""
        return any(side.due() for side in self.sides)

    def evaluate(self, episodes: int, rng: np.random.Generator) -> Outcome:
        """Every side's greedy strategy for ``episodes`` episodes, the game's randomness
        drawn from ``rng`` (on a game of its own: learning goes on where it stopped);
        what the sides draw themselves (a tabular side's unseen states) comes from two
        streams spawned from ``rng``'s seed, which leave the game's draws as they are."""
        episodes = int(episodes)
        returns = np.zeros((episodes, MAX_TEAMS))
        lengths = np.zeros(episodes, dtype=np.int64)
        terminated = np.zeros(episodes, dtype=np.bool_)
        a, b = (side.data for side in self._all)
        side_rngs = rng.spawn(MAX_TEAMS)
        spec = self.spec
        self._play_greedy(
            self._eval_env, a, b, spec.width, episodes, spec.max_steps, rng, *side_rngs,
            returns, lengths, terminated,
        )  # fmt: skip
        return Outcome(returns[:, : spec.n_teams], lengths, terminated)

    def visited(self, side: int) -> int:
        """States side ``side`` holds values for (0 for a deep side)."""
        return self.sides[side].visited()

    def memory_bytes(self) -> int:
        """Bytes held by the sides' tables, or networks and replay buffers."""
        return sum(side.memory_bytes() for side in self.sides)


class Group:
    """What :class:`PlayBatch` asks of a group of sides that learn as one model."""

    def train(self) -> None:
        """The work due once its learning sides have all paused."""


class PlayBatch:
    """Plays that learn together (the rounds of a tournament pairing, the seeds of a DSN
    row), so that the deep sides of each learner train as one stacked model
    (:class:`cmarlcd.training.deep_side.DeepGroup`): each play runs until its deep sides
    have played ``train_every`` more turns, then every group takes one step for all its
    plays. Each play learns exactly what it would alone (up to float rounding in the
    batched products); a play that has finished learning keeps (:meth:`Side.freeze`)
    what it finished with.

    Args:
        plays: the plays, each with its sides.
        groups: the groups their deep sides belong to.
        learn_episodes: each play's learning stage.
    """

    def __init__(
        self,
        plays: Sequence[Play],
        groups: Sequence[Group],
        learn_episodes: int,
        unit: str = "episodes",
    ) -> None:
        require(unit in BUDGET_UNITS, "unit", f"must be one of {BUDGET_UNITS} (got {unit!r})")
        self.plays, self.groups = list(plays), list(groups)
        self.learn_episodes, self.unit = int(learn_episodes), unit

    def _learned(self, play: Play) -> bool:
        if self.unit == "steps":
            return play.learned_turns(self.learn_episodes)
        return play.episodes >= self.learn_episodes

    def _progress(self, play: Play) -> float:
        """The play's learning so far in episodes (in episodes of ``max_steps`` steps
        where the stage counts steps)."""
        if self.unit == "steps":
            return play.turns / play._max_steps
        return float(play.episodes)

    def _goal(self, play: Play) -> int:
        """The episodes the play's next call may reach."""
        if self.unit == "steps":
            return min(play.episode_goal(self.learn_episodes), play.episodes + CHUNK_EPISODES)
        return min(self.learn_episodes, play.episodes + CHUNK_EPISODES)

    def learn(self, paused: Callable[[], None] | None = None) -> None:
        """Every play learns for its whole learning stage (``learn_episodes`` episodes,
        or as many environment steps where ``unit`` is ``"steps"``, to the end of the
        episode in play), progress reported as episodes finish; ``paused()`` is called
        each time all plays have paused, before the groups' step."""
        learning = list(self.plays)
        while learning:
            before = sum(self._progress(play) for play in learning)
            for play in learning:
                while not self._learned(play) and not play.due():
                    play.advance(self._goal(play))
                if self._learned(play):
                    for side in play.sides:
                        side.freeze()
            report_progress(sum(self._progress(play) for play in learning) - before)
            learning = [play for play in learning if not self._learned(play)]
            if paused is not None:
                paused()
            for group in self.groups:
                group.train()
