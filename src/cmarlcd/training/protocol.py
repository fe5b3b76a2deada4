"""What the training loop asks of a side: the side protocol (a leaf module).

A *side* is the learners of one team of a game: a tabular learner
(:mod:`cmarlcd.training.tabular_side`), VDN or QMIX (:mod:`cmarlcd.training.deep_side`),
or a fixed joint policy (:mod:`cmarlcd.training.policy_side`). The one loop of
:mod:`cmarlcd.training.loop` plays a game of one or two teams through its sides and sees
each side only through its compiled *side kernels* (:class:`SideKernels`) and the side's
own NamedTuple of arrays (``data``). Everything a side does between two calls of the loop
(grow its tables, take a gradient step) is a method of :class:`Side`.
"""

from __future__ import annotations

from typing import Any, NamedTuple

from cmarlcd.compiled import shared_kernel

#: Entries of a learning stage's ``clock``: episodes finished, turns into the current
#: episode (-1 between episodes), whether its last turn still awaits ``observe``, the
#: turns played so far, and whether the episode in play has ended (its last turn
#: observed) with its end-of-episode work still to come when the loop paused.
EPISODES, LENGTH, PENDING, TURNS, ENDED = range(5)


class SideKernels(NamedTuple):
    """How the loop drives one side (``side`` is the side's own NamedTuple of arrays;
    ``team`` its team; ``offset`` its first agent in the game's joint action and masks).

    ``fits(side, max_steps)``: one more episode fits in the side's memory;
    ``enter(side, env, team, offset, legal, length, terminal) -> key``: the side observes
    the state of turn ``length`` (``key`` names it for ``act`` and ``observe``; a
    ``terminal`` state is never acted in);
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


class Side:
    """One team's learners as the loop sees them, with the work due between loop calls."""

    kernels: SideKernels
    data: tuple
    """The side's arrays, as its kernels read them (``data.counts``: its agents' action
    counts; ``data.joints`` and ``data.rewards``: the episode's turns so far)."""

    def between_calls(self) -> None:
        """Work due when the learning loop has stopped (grow tables, a gradient step)."""

    def visited(self) -> int:
        """States the side holds values for (0 when it generalises across states)."""
        return 0

    def memory_bytes(self) -> int:
        """Bytes of the side's tables, or networks and replay buffer."""
        return 0

    def due(self) -> bool:
        """Whether the side stopped the loop for work only its group can do."""
        return False

    def freeze(self) -> None:
        """Learning has finished (a side trained in a group keeps its values)."""


# ------------------------------------------------ the kernels of a side that does nothing


@shared_kernel  # takes a plug-in's tables: see cmarlcd.compiled.shared_kernel
def fits_always(side, max_steps: int) -> bool:
    """``fits``: the side's memory does not grow."""
    return True


@shared_kernel
def enter_nothing(side, env, team, offset, legal, length, terminal) -> int:
    return 0


@shared_kernel
def act_nothing(side, key, rng, joint) -> None:
    pass


@shared_kernel
def observe_nothing(side, t, next_key, terminal) -> None:
    pass


@shared_kernel
def end_nothing(side, length) -> None:
    pass


@shared_kernel
def never_pause(side) -> bool:
    """``pause``: a side that learns inside the loop (or not at all) never stops it."""
    return False


@shared_kernel
def greedy_nothing(side, env, team, offset, legal, rng, joint) -> None:
    pass


#: A side that never learns nor acts: the absent second side of a one-team game; a fixed
#: policy replaces its ``greedy``.
IDLE = SideKernels(
    fits_always,
    enter_nothing,
    act_nothing,
    observe_nothing,
    end_nothing,
    never_pause,
    greedy_nothing,
)
