"""The paper's experimental protocols (importing this registers them with the runner)."""

from cmarlcd.experiments import repeated, sensor_network

__all__ = ["repeated", "sensor_network"]
