"""A tournament match's kept policies (``--save-policies``) and its evaluation replayed
from them (``cmarl-cd evaluate``).

A match keeps two policies, one file per team (``…-team0``, ``…-team1``, each naming the
other as its ``partner``): a tabular side's greedy joint action of every state it visited
while learning (what it plays elsewhere is its ``unseen`` reading: each agent's lowest
legal action, or a uniform legal one drawn from its side's evaluation stream), and a deep
side's agent networks as its kernels read them (a copy of the weights it evaluated with).
Both are taken when learning has ended, before the evaluation, so replaying them with the
match's evaluation stream plays the very episodes the match was scored on
(:func:`cmarlcd.training.loop.play_greedy`: the game's kernels in the same order, the
same draws), hence the stored wins and ties.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from cmarlcd.errors import require
from cmarlcd.policies.greedy import NetworkPolicy, TablePolicy

#: The file-name part of each team's policy of a match.
TEAM_PARTS = ("team0", "team1")


def match_policies(match: Any, names: tuple[str, str], unseen: str) -> dict[str, Any]:
    """Each team's greedy policy of a :class:`cmarlcd.training.match.Match` that has
    finished learning, by :data:`TEAM_PARTS` (``names``: the learner of each team)."""
    from cmarlcd.training.tabular_side import TabularSide

    kept: dict[str, Any] = {}
    for team, side in enumerate(match.sides):
        meta = {"game": "battlefield", "team": team, "learner": names[team],
                "opponent": names[1 - team], "partner_part": TEAM_PARTS[1 - team]}  # fmt: skip
        if isinstance(side, TabularSide):
            kept[TEAM_PARTS[team]] = visited_table(side, {**meta, "inputs": "state",
                                                          "unseen": unseen})  # fmt: skip
        else:
            from cmarlcd.policies.learned import side_network

            kept[TEAM_PARTS[team]] = side_network(side, meta)
    return kept


def visited_table(side: Any, metadata: Mapping[str, Any]) -> TablePolicy:
    """A tabular side's greedy joint action in every state it visited, keyed by state
    index (the kernels' greedy over its tables, as it plays them at evaluation)."""
    from cmarlcd.learners.tabular.protocol import greedy_policy

    data = side.data
    visited = np.flatnonzero(data.rows >= 0)
    actions = greedy_policy(side.config, data.tables, data.counts)[data.rows[visited]]
    counts = data.counts
    # a state it never visited: each agent's lowest legal action (the "lowest" reading,
    # which a PettingZoo loop's act() plays); evaluate and play follow the match's reading
    fresh = np.zeros(len(counts), np.int64)
    keys = [int(s) for s in visited]
    return TablePolicy(actions, np.ones(len(keys), bool), fresh, counts, keys, metadata)


def replay_match(
    policies: tuple[Any, Any], spec: Any, episodes: int, rng: np.random.Generator
) -> Any:
    """``episodes`` greedy episodes of the two teams' kept policies on the battlefield
    ``spec``, the game drawing from ``rng`` and each side from its stream spawned from
    it, as :meth:`cmarlcd.training.loop.Play.evaluate` draws them; the outcome, counted
    by :func:`cmarlcd.training.match.tally`."""
    from cmarlcd.training.loop import MAX_TEAMS, Outcome
    from cmarlcd.training.match import tally

    game, env = spec.kernels, spec.new_env()
    side_rngs = rng.spawn(MAX_TEAMS)
    legal = np.zeros((spec.n_agents, spec.width), np.bool_)
    joint = np.zeros(spec.n_agents, np.int64)
    x = np.zeros(spec.n_features, np.float32)
    rewards = np.zeros(2)
    returns = np.zeros((episodes, 2))
    lengths = np.zeros(episodes, np.int64)
    terminated = np.zeros(episodes, np.bool_)
    for e in range(episodes):
        game.reset(env, rng)
        turns, total = 0, np.zeros(2)
        while turns < spec.max_steps:
            joint_action(policies, spec, env, legal, x, side_rngs, joint)
            game.step(env, joint, rng, rewards)
            total += rewards
            turns += 1
            if game.done(env):
                break
        returns[e], lengths[e], terminated[e] = total, turns, game.done(env)
    return tally(Outcome(returns, lengths, terminated))


def by_team(policy: Any, partner: Any) -> tuple[Any, Any]:
    """A match's two kept policies in team order (team 0's first), or one clear error."""
    teams = sorted((policy, partner), key=lambda p: int(p.metadata["team"]))
    require([int(p.metadata["team"]) for p in teams] == [0, 1], "policy",
            "a match's two files are its team 0 and team 1")  # fmt: skip
    return teams[0], teams[1]


def joint_action(policies, spec, env, legal, x, rngs, joint) -> None:
    """``joint`` := both teams' greedy joint actions now (team 0's agents first), each as
    its side plays at evaluation, drawing from its own stream of ``rngs``."""
    offset = 0
    for team, policy in enumerate(policies):
        n = len(policy.counts)
        joint[offset : offset + n] = team_action(
            policy, spec.kernels, env, team, offset, legal, x, rngs[team], spec.action_counts
        )
        offset += n


def team_action(policy, game, env, team, offset, legal, x, rng, action_counts) -> np.ndarray:
    """One team's greedy joint action now, as its side plays it at evaluation."""
    from cmarlcd.learners.policy import uniform_legal_action

    n = len(policy.counts)
    if isinstance(policy, TablePolicy):
        state = int(game.state(env, team))
        if policy.row(state) is not None:
            return policy.greedy_many([state], [None])[0]
        game.legal(env, legal)  # a state it never visited: its unseen reading
        rows = legal[offset : offset + n]
        if policy.metadata.get("unseen") == "random":
            return np.array([uniform_legal_action(rows[i], int(policy.counts[i]), rng.random())
                             for i in range(n)], np.int64)  # fmt: skip
        return np.array([int(np.argmax(rows[i])) for i in range(n)], np.int64)
    require(isinstance(policy, NetworkPolicy), "policy", "a match's side is a table or networks")
    game.features(env, team, x)
    game.legal(env, legal)
    counts = action_counts[offset : offset + n]
    masks = [legal[offset + i, : counts[i]] for i in range(n)]
    return policy.greedy_many([x], [masks])[0].astype(np.int64)


def evaluate_match(
    policy: Any, partner: Any, spec: Any, episodes: int | None, seed: int | None
) -> dict[str, Any]:
    """A match's two kept policies (``policy`` and the other team's ``partner``) played
    as the match's evaluation was (its episodes and stream), or ``episodes`` from
    ``seed``: each team's wins, the ties."""
    from cmarlcd.experiments.tournament import Pairing

    require(partner is not None, "policy", "a match's policy plays with its partner's file")
    pairing = Pairing.from_config(spec.config)
    teams = by_team(policy, partner)
    game = pairing.rules.spec()
    for team, kept in enumerate(teams):
        theirs = [int(c) for c in kept.counts]
        ours = [int(c) for c in game.action_counts[list(game.teams[team])]]
        require(theirs == ours, "policy", f"team {team}'s agents have {theirs} actions; "
                f"the game's {ours}")  # fmt: skip
    own = episodes is None and seed is None
    count = pairing.eval_episodes if episodes is None else episodes
    require(count >= 1, "episodes", f"must be >= 1 (got {count})")
    if own:  # the match's own evaluation stream: the last of its seed's four
        rng = np.random.default_rng(spec.seed_sequence().spawn(4)[3])
    else:
        rng = np.random.default_rng(0 if seed is None else seed)
    result = replay_match(teams, game, count, rng)
    team = int(policy.metadata["team"])
    return {
        "game": "battlefield", "algorithm": spec.algorithm, "episodes": count,
        "team": team, "learners": [p.metadata.get("learner") for p in teams],
        "wins": list(result.wins), "ties": result.ties,
        "win_rate": result.win_rate(team), "mean_steps": result.turns / count,
        "seeds": "the match's own evaluation" if own else f"seed {0 if seed is None else seed}",
    }  # fmt: skip
