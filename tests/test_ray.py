"""The Ray backend: a local Ray of 2 CPUs stores exactly what local processes store."""

from __future__ import annotations

import importlib.util

import pytest

from cmarlcd.experiments import repeated as rep
from cmarlcd.experiments import theorem
from cmarlcd.experiments.sensor_network import DsnSweep
from cmarlcd.experiments.tournament import Tournament, battlefield_learners
from cmarlcd.learners.tabular.coordination import RepeatedConfig
from cmarlcd.registry import LEARNERS
from cmarlcd.sweeps.runner import run_sweep
from cmarlcd.sweeps.store import ResultStore

ray = pytest.importorskip("ray")
pytestmark = pytest.mark.slow  # Ray starts in seconds, sweeps run in tens
DEEP = importlib.util.find_spec("torch") is not None


@pytest.fixture(scope="module")
def local_ray():
    """One local Ray for the module (starting one costs seconds); the sweeps join it."""
    ray.init(num_cpus=2, include_dashboard=False, object_store_memory=80 * 1024**2)
    yield
    ray.shutdown()


def without_timings(metrics: dict) -> dict:
    return {k: v for k, v in metrics.items() if k != "seconds" and not k.endswith("_seconds")}


def tiny_sweeps() -> dict[str, tuple[list, int]]:
    """(specs, seed batch) of a tiny sweep of each experiment."""
    dsn_learners = [LEARNERS["cmarl-cd"], *([LEARNERS["vdn"]] if DEEP else [])]
    players = ["cmarl-cd", "la-oca", *(["vdn"] if DEEP else [])]
    known = battlefield_learners()
    return {
        "repeated": (
            rep.RepeatedSweep(1, (2, 3), (2,), 2, 0, RepeatedConfig()).specs(),
            1,
        ),
        "dsn": (
            DsnSweep(
                learners=tuple(dsn_learners), episodes=(60,), runs=3, eval_episodes=20
            ).specs(),
            2,
        ),
        "tournament": (
            Tournament(tuple(known[p] for p in players), 2, 30, 30, 0).specs(),
            2,
        ),
        "theorem1": (theorem.specs(((2, 2),), starts=5), 1),
    }


# the commands' sweeps on a Ray each starts itself, against local processes, are in
# tests/test_commands_e2e.py (the user's path); Theorem 1's checks have no --backend
@pytest.mark.parametrize("experiment", ["theorem1"])
def test_local_ray_stores_what_local_processes_store(local_ray, tmp_path, experiment) -> None:
    specs, seed_batch = tiny_sweeps()[experiment]
    stored = {}
    for backend in ("process", "ray"):
        with ResultStore(tmp_path / f"{backend}.sqlite") as store:
            done = run_sweep(specs, store, workers=2, backend=backend, seed_batch=seed_batch)
            assert done.computed == len(specs)
            stored[backend] = {r.key: without_timings(r.metrics) for r in store.records()}
            assert store.claims() == []
    assert len(stored["ray"]) == len(specs)
    assert stored["ray"] == stored["process"]


def test_a_ray_sweep_resumes_from_the_store(local_ray, tmp_path) -> None:
    specs, _ = tiny_sweeps()["repeated"]
    with ResultStore(tmp_path / "s.sqlite") as store:
        run_sweep(specs[:3], store, workers=2, backend="ray")
        done = run_sweep(specs, store, workers=2, backend="ray")
    assert (done.reused, done.computed) == (3, len(specs) - 3)


def test_a_node_with_another_version_is_one_line(local_ray, tmp_path, monkeypatch) -> None:
    """The driver says it runs another version: every task refuses, and the sweep ends
    with a ConfigError naming the backend (one line on the command line)."""
    from cmarlcd.errors import ConfigError
    from cmarlcd.sweeps.backends import ray_cluster as ray_backend

    monkeypatch.setattr(ray_backend, "__version__", "0.0.0-elsewhere")
    specs, _ = tiny_sweeps()["repeated"]
    with ResultStore(tmp_path / "s.sqlite") as store, pytest.raises(ConfigError) as err:
        run_sweep(specs, store, workers=2, backend="ray")
    assert err.value.parameter == "backend"
    assert "runs cmarl-cd" in err.value.message and "0.0.0-elsewhere" in err.value.message


def test_an_experiment_registered_outside_the_package_runs_on_ray(local_ray, tmp_path) -> None:
    """The toy experiment of tests/test_runner.py (registered at the top of that module)
    reaches Ray's workers, which import the module, and stores what local processes do."""
    from tests.test_runner import specs as toy_specs

    todo = toy_specs(scales=(1, 2), runs=3)
    stored = {}
    for backend in ("process", "ray"):
        with ResultStore(tmp_path / f"{backend}.sqlite") as store:
            assert run_sweep(todo, store, workers=2, backend=backend).computed == len(todo)
            stored[backend] = {r.key: r.metrics for r in store.records()}
    assert stored["ray"] == stored["process"]


def test_ray_and_local_processes_write_the_same_live_curves(local_ray, tmp_path) -> None:
    """--log-dir: one folder a run, its scalars (but the rates, wall-clock) the same."""
    import csv

    specs, seed_batch = tiny_sweeps()["dsn"]
    found = {}
    for backend in ("process", "ray"):
        logs = tmp_path / f"{backend}-logs"
        with ResultStore(tmp_path / f"{backend}.sqlite") as store:
            run_sweep(specs, store, workers=2, backend=backend, seed_batch=seed_batch, logs=logs)
        found[backend] = {
            folder.name: {
                (row["tag"], row["step"], row["value"])
                for row in csv.DictReader((folder / "scalars.csv").open())
                if not row["tag"].startswith("rate/")
            }
            for folder in logs.iterdir()
        }
    assert len(found["ray"]) == len(specs) and all(found["ray"].values())
    assert found["ray"] == found["process"]
