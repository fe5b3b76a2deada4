"""The paper's experimental protocols (importing this registers them with the runner)."""

from cmarlcd.experiments import repeated

__all__ = ["repeated"]
