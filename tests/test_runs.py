"""A run's identity: a setting added after runs were stored stays out of it at the value
that keeps the old behaviour, so earlier stores resume with their seeds and numbers."""

from __future__ import annotations

from dataclasses import dataclass

from cmarlcd.learners.deep.coordination import DeepCMARLCDConfig
from cmarlcd.learners.deep.designs import BATTLEFIELD_DEEP_CMARLCD
from cmarlcd.runs import RunSpec, Settings, added_setting, as_stored, identity


@dataclass(frozen=True)
class Example:
    rate: float = 0.1
    mode: str = added_setting("old", "9.9")


@dataclass(frozen=True)
class NewDefault(Settings):
    """A setting whose default changed when it was added: new runs take "new", the
    stored ones ran as "old"."""

    rate: float = 0.1
    mode: str = added_setting("new", "9.9", before="old")

    def to_config(self) -> dict:
        return identity(self)


def test_an_added_setting_at_its_default_is_left_out_of_the_identity() -> None:
    assert identity(Example()) == {"rate": 0.1}
    assert identity(Example(rate=0.2)) == {"rate": 0.2}
    assert identity(Example(mode="new")) == {"rate": 0.1, "mode": "new"}


def test_an_added_setting_with_a_new_default_is_left_out_at_its_value_from_before() -> None:
    assert identity(NewDefault()) == {"rate": 0.1, "mode": "new"}
    assert identity(NewDefault(mode="old")) == {"rate": 0.1}


def test_a_stored_identity_without_an_added_setting_reads_as_before() -> None:
    """A run stored before the setting existed ran the old way, whatever today's default."""
    assert NewDefault.from_config({"rate": 0.2}) == NewDefault(rate=0.2, mode="old")
    assert NewDefault.from_config({"rate": 0.2, "mode": "new"}) == NewDefault(rate=0.2)
    assert as_stored(Example, {"rate": 0.3}) == {"rate": 0.3, "mode": "old"}
    for settings in (NewDefault(), NewDefault(mode="old"), NewDefault(rate=0.5)):
        assert NewDefault.from_config(settings.to_config()) == settings


def test_deep_cmarl_cd_acting_from_its_network_keeps_the_identity_it_had_before() -> None:
    """``act_from`` came in 0.6.0: at "network" (the behaviour before it) a config's
    identity, and so its run's seeds, are what they were; acting from the memory is
    another run."""
    before = identity(DeepCMARLCDConfig())
    assert not {"act_from", "record", "record_step", "ways"} & set(before)
    assert identity(BATTLEFIELD_DEEP_CMARLCD)["act_from"] == "memory"

    def seeds(config) -> list[int]:
        spec = RunSpec.make("dsn", "deep-cmarl-cd", _Settings(config), 0, 0)
        return spec.seed_sequence().generate_state(2).tolist()

    assert seeds(DeepCMARLCDConfig()) == seeds(DeepCMARLCDConfig(act_from="network"))
    assert seeds(DeepCMARLCDConfig()) != seeds(DeepCMARLCDConfig(act_from="memory"))


class _Settings:
    def __init__(self, learner) -> None:
        self.learner = learner

    def to_config(self) -> dict:
        return {"learner": identity(self.learner)}

    def stream(self) -> None:
        return None
