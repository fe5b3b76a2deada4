"""Study: redesigns of deep CMARL-CD's update, measured by the stream-equivalence test.

Each design runs on the object API (:class:`DegreeAgent`'s networks and schedule): the
package's own updates, and the prototype of one more. All but ``replayed`` keep an
**exact record**: ``R_max(s)`` is a maximum kept per state (a keyed memory; with one-hot
states it is a table), so a visit is classified once, as the table classifies it, with
the table's tolerance. They differ in what the degree network is regressed to:

* ``replayed``: the package's first design (``update="replayed"``: targets recomputed
  from the network's present degrees at every replay; an expectile record).
* ``frozen``: *frozen per-visit targets* (a prototype here). When an episode ends, its
  visits are folded backwards into one target per state, the table's rule applied once
  per visit to the
  degrees of a *target copy* of the degree network (as in DQN; refreshed every
  ``target_every`` steps); each (state, target) is stored in a ring and replayed until
  met (fitted targets, as in neural fitted Q): replaying a visit converges to its
  target instead of adding to it.
* ``keyed``: the package's keyed update (``update="keyed"``,
  :mod:`cmarlcd.learners.deep.degree_memory`) under the table's rule for first visits
  (``unseen_record="first-visit"``): the same targets, but folded onto the state's
  entry in a keyed memory (the network's degrees only for a state not in it), and the
  network regressed to the memory, every kept state alike. With one-hot states the
  memory is the table and the network its distillation.
* ``keyed-estimate``: ``keyed`` with ``unseen_record="estimate"``: a state not in the
  memory is compared with a record network's estimate, not ``-inf``.
* ``keyed-once-kept``: ``keyed`` with ``unseen_record="estimate-once-kept"``: the same
  once the memory keeps any state; an episode folded into an empty memory is taken by
  the table's rule.

For each design and checkpoint it prints, over every state the stream has visited, the
share where both learners' greedy joint actions agree (a design that learns what the
table learns: 100 %), the share of (state, agent) pairs that agree, and the largest
difference of their coordination degrees (0), with the wall time so far.

With ``--own-play L`` each design (and the table, ``table``) learns from its own play
instead, L episodes, and its greedy policy is evaluated as the DSN's tables are: the share
of ``--eval-episodes`` episodes that return the optimum, 42, in 3 steps.

Usage: python benchmarks/deep_cmarlcd_designs.py [--designs replayed,frozen,keyed]
           [--checkpoints 1000,10000] [--seed S] [--set NAME=VALUE ...]
           [--own-play L [--eval-episodes E]]
       (--set: deep CMARL-CD's settings for every design, e.g. lr=1e-2)
"""

from __future__ import annotations

import argparse
import copy
import os
import platform
import time
from collections import deque
from dataclasses import fields, replace

import numpy as np
import torch

from cmarlcd.errors import ConfigError
from cmarlcd.experiments.sensor_network import optimal_episodes
from cmarlcd.games.sensor_network import SensorNetworkEnv
from cmarlcd.learners import CMARLCDStochastic, DeepCMARLCDConfig, StochasticConfig
from cmarlcd.learners.deep.config import scheduled_work
from cmarlcd.learners.deep.degree_agent import DegreeAgent
from cmarlcd.learners.deep.designs import REPLAYED_DEEP_CMARLCD
from cmarlcd.learners.max_return import RECORD, TIE, compare_return
from cmarlcd.learners.tabular.coordination import coordination_rule
from cmarlcd.testing.streams import Stream
from cmarlcd.training.episodes import play_episodes

#: The table's rule and tolerance (the paper's DSN settings).
TABLE = StochasticConfig()


class ExactRecordAgent(DegreeAgent):
    """Deep CMARL-CD with an exact record and per-state targets folded once per visit;
    subclasses say where a state's base degrees come from and what is replayed."""

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self.records: dict[int, float] = {}
        self.params = TABLE.params()
        self.fitted = 0  # targets stored (learning starts at a batch's worth)

    def observe(self, state, joint_action, reward: float) -> None:
        self._visits.append((int(state), tuple(int(a) for a in joint_action), float(reward)))
        self.steps += 1
        step, copy_now = scheduled_work(self.steps - 1, self.steps, self.fitted, self.config)
        if step:
            self.fit()
        if copy_now:
            self.sync()

    def end_episode(self, final_state=None, terminated: bool = True) -> None:
        """The table's backward pass (Algorithm 2, lines 13-19) on per-state targets."""
        targets: dict[int, np.ndarray] = {}
        g = 0.0
        for state, joint, reward in reversed(self._visits):
            g = reward + self.params.gamma * g
            best = self.records.get(state, -np.inf)
            outcome = compare_return(g, best, self.params.tolerance)
            if outcome == RECORD:
                self.records[state] = g
            if outcome not in (RECORD, TIE):
                continue
            rows = targets.get(state)
            if rows is None:
                rows = self.base(state)
            probs = np.zeros_like(rows)
            legal = np.ones(rows.shape[1], dtype=np.bool_)
            for i, action in enumerate(joint):
                count = int(self.counts[i])
                coordination_rule(
                    rows[i], probs[i], legal, count, action, outcome == RECORD, self.params
                )
            targets[state] = rows
        self.store(targets)
        self._visits.clear()
        self.episode += 1

    def regress(self, states: list[int], rows: list[np.ndarray]) -> None:
        """One Adam step of the degree network towards ``rows`` at ``states``."""
        model = self.model
        x = torch.tensor([states], device=self.device)
        target = torch.as_tensor(np.stack(rows)[None], device=self.device, dtype=torch.float32)
        valid = model.valid.to(target.dtype)
        loss = (((model.agents(x) - target) ** 2) * valid).sum(dim=(2, 3)).mean()
        model.optimizer.zero_grad()
        loss.backward()
        model.optimizer.step()

    def network_rows(self, network, state: int) -> np.ndarray:
        c = self.config
        with torch.no_grad():
            out = network(torch.tensor([[state]], device=self.device))[0, 0]
        return out.clamp(c.c_min, c.c_max).cpu().numpy().astype(np.float64)

    def base(self, state: int) -> np.ndarray:
        raise NotImplementedError

    def store(self, targets: dict[int, np.ndarray]) -> None:
        raise NotImplementedError

    def fit(self) -> None:
        raise NotImplementedError

    def sync(self) -> None:
        """Nothing to copy (a design with a target copy refreshes it here)."""


class Frozen(ExactRecordAgent):
    """Targets from a target copy of the degree network, replayed from a ring."""

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self.target_agents = copy.deepcopy(self.model.agents).requires_grad_(False)
        self.ring: deque[tuple[int, np.ndarray]] = deque(maxlen=self.config.buffer_size)

    def base(self, state: int) -> np.ndarray:
        return self.network_rows(self.target_agents, state)

    def store(self, targets: dict[int, np.ndarray]) -> None:
        self.ring.extend(targets.items())
        self.fitted = len(self.ring)

    def fit(self) -> None:
        picks = self.replay_rng.integers(len(self.ring), size=self.config.batch_size)
        chosen = [self.ring[k] for k in picks]
        self.regress([s for s, _ in chosen], [rows for _, rows in chosen])

    def sync(self) -> None:
        self.target_agents.load_state_dict(self.model.agents.state_dict())


#: Each design: how it is made, and the settings it starts from (``--set`` goes on top).
DESIGNS = {
    "keyed": (DegreeAgent, DeepCMARLCDConfig(unseen_record="first-visit")),
    "keyed-estimate": (DegreeAgent, DeepCMARLCDConfig(unseen_record="estimate")),
    "keyed-once-kept": (DegreeAgent, DeepCMARLCDConfig(unseen_record="estimate-once-kept")),
    "replayed": (DegreeAgent, REPLAYED_DEEP_CMARLCD),
    # the prototype learns once a batch's worth of targets is stored, as it always did,
    # on the schedule it was measured with (a step per 50 environment steps)
    "frozen": (Frozen, DeepCMARLCDConfig(update="replayed", train_every=50, target_every=500)),
}


def make_design(name: str, changes: dict, counts, episodes: int, seed: int):
    """Design ``name`` with its settings and ``changes``, for the DSN's 43 states."""
    factory, base = DESIGNS[name]
    return factory(counts, replace(base, **changes), episodes, n_states=43, seed=seed)


def config_with(settings: list[str]) -> dict:
    """``NAME=VALUE`` settings as changes to a config, checked on deep CMARL-CD's
    defaults (ValueError names a setting it does not have; ConfigError a bad value)."""
    config = DeepCMARLCDConfig()
    types = {f.name: type(getattr(config, f.name)) for f in fields(config)}
    changes = {}
    for item in settings:
        name, _, value = item.partition("=")
        if name not in types:
            raise ValueError(f"no setting {name!r} (one of {', '.join(types)})")
        kind = types[name]
        changes[name] = value.lower() in ("1", "true") if kind is bool else kind(value)
    replace(config, **changes)  # validates the values
    return changes


def own_play(name: str, changes: dict, episodes: int, evals: int, seed: int):
    """(success rate of the greedy policy, seconds) after ``episodes`` of own play."""
    env = SensorNetworkEnv()
    counts = [int(env.action_space(agent).n) for agent in env.possible_agents]
    if name == "table":
        learner = CMARLCDStochastic(counts, seed=seed)
    else:
        learner = make_design(name, changes, counts, episodes, seed)
    start = time.perf_counter()
    play_episodes(env, learner, episodes, seed=seed)
    stats = play_episodes(env, learner, evals, learn=False)
    return float(optimal_episodes(stats).mean()), time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--designs", default="replayed,frozen,keyed")
    parser.add_argument("--checkpoints", default="1000,10000")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--set", dest="settings", action="append", default=[])
    parser.add_argument("--own-play", type=int, default=0)
    parser.add_argument("--eval-episodes", type=int, default=2_000)
    args = parser.parse_args()
    marks = sorted({int(part) for part in args.checkpoints.split(",")})
    designs = args.designs.split(",")
    known = [*DESIGNS, "table"] if args.own_play else list(DESIGNS)
    if unknown := [name for name in designs if name not in known]:
        parser.error(f"--designs: no design {unknown[0]!r} (one of {', '.join(known)})")
    try:
        changes = config_with(args.settings)
    except (ValueError, ConfigError) as why:  # exit status 2, one line
        parser.error(f"--set: {why}")
    print(
        f"# {platform.processor() or platform.machine()}, {os.cpu_count()} cores; seed {args.seed}"
    )
    print(f"# deep CMARL-CD settings: {', '.join(args.settings) or 'defaults'}")
    if args.own_play:
        print(f"design    own play  greedy success over {args.eval_episodes:,} episodes  wall s")
        for name in designs:
            rate, seconds = own_play(name, changes, args.own_play, args.eval_episodes, args.seed)
            print(f"{name:<9} {args.own_play:>8,}  {100 * rate:>38.1f} %  {seconds:>6.0f}")
        return
    print("design    episodes  states  joint agree  agents agree  largest difference  wall s")
    for name in designs:
        env = SensorNetworkEnv()
        counts = [int(env.action_space(agent).n) for agent in env.possible_agents]
        reference = CMARLCDStochastic(counts, seed=args.seed)
        candidate = make_design(name, changes, counts, marks[-1], args.seed)
        stream, start = Stream(env, reference, candidate, args.seed), time.perf_counter()
        for mark in marks:
            stream.play(mark - stream.episodes)
            point = stream.compare()
            print(
                f"{name:<9} {mark:>8,}  {point.states:>6}  {100 * point.agreement:>10.1f} %  "
                f"{100 * point.agent_agreement:>11.1f} %  {point.max_difference:>18.3f}  "
                f"{time.perf_counter() - start:>6.0f}",
                flush=True,
            )


if __name__ == "__main__":
    main()
