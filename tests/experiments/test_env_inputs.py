"""What the learners of ``cmarl-cd train`` read: the observations joined, or each
agent's own beside the state, laid out as documented."""

from __future__ import annotations

from cmarlcd.experiments import env_inputs
from tests.tiny_env import TinyEnv


def test_joined_and_own_observations() -> None:
    joined = env_inputs.JoinedObservations(TinyEnv())
    joined.reset(seed=0)
    assert joined.state().tolist() == [1, 0, 0, 1, 0, 0]  # a's observation, then b's
    own = env_inputs.OwnObservations(TinyEnv())
    own.reset(seed=0)
    own.step({"a": 0, "b": 1})
    assert own.state().tolist() == [0, 1, 0] + [0, 1, 0] * 2  # state(), then a's, b's
    stateless = env_inputs.OwnObservations(TinyEnv(state="none"))
    stateless.reset(seed=0)
    assert stateless.state().tolist() == [1, 0, 0] * 2 * 2  # joined stands in for state()
    assert env_inputs.state_shape(own, "own-observations") == env_inputs.StateShape(None, 9, 3)
