"""Where the deep learners compute: choosing the device, its errors, and models that
make no tensor off their device. The tests marked ``gpu`` run only where torch sees a GPU
(skipped elsewhere, with the reason in pytest's summary)."""

from __future__ import annotations

import multiprocessing
import os
import time
from dataclasses import dataclass

import numpy as np
import pytest

from cmarlcd import devices
from cmarlcd.errors import ConfigError
from cmarlcd.experiments import register
from cmarlcd.runs import Experiment, RunSpec, Settings
from cmarlcd.sweeps.runner import run_sweep
from cmarlcd.sweeps.store import ResultStore

torch = pytest.importorskip("torch")

HAS_GPU = torch.cuda.is_available()
gpu = pytest.mark.skipif(not HAS_GPU, reason="no GPU here (torch.cuda.is_available() is False)")


@pytest.mark.parametrize("device", ["cpu", "cuda", "cuda:0", "cuda:12", "auto"])
def test_every_spelling_of_a_device_is_accepted(device: str) -> None:
    devices.check_device(device)


@pytest.mark.parametrize("device", ["gpu", "CUDA", "cuda:", "cuda:-1", "cuda:x", "", "cpu:0"])
def test_a_device_misspelt_is_refused_with_the_choices(device: str) -> None:
    with pytest.raises(ConfigError, match="cpu, cuda, cuda:N, auto"):
        devices.check_device(device)


@pytest.fixture
def gpus(monkeypatch: pytest.MonkeyPatch):
    """Pretend torch sees ``count`` GPUs."""

    def pretend(count: int) -> None:
        monkeypatch.setattr(torch.cuda, "is_available", lambda: count > 0)
        monkeypatch.setattr(torch.cuda, "device_count", lambda: count)

    return pretend


def test_auto_takes_the_cpu_where_torch_sees_no_gpu(gpus) -> None:
    gpus(0)
    assert devices.resolve("auto") == "cpu"
    assert devices.resolve("cpu") == "cpu"


@pytest.mark.parametrize("device", ["cuda", "cuda:0", "cuda:1"])
def test_a_gpu_asked_for_where_there_is_none_is_refused(gpus, device: str) -> None:
    gpus(0)
    with pytest.raises(ConfigError, match="torch sees no GPU"):
        devices.resolve(device)


def test_gpus_are_named_as_torch_names_them(gpus) -> None:
    gpus(2)
    assert devices.resolve("auto") == "cuda:0"
    assert devices.resolve("cuda") == "cuda:0"
    assert devices.resolve("cuda:1") == "cuda:1"
    with pytest.raises(ConfigError, match="torch sees 2 GPU"):
        devices.resolve("cuda:2")


def test_using_sets_the_device_of_the_block_only() -> None:
    assert devices.current() == "cpu"
    with devices.using("cpu") as device:
        assert device == devices.current() == "cpu"
    with pytest.raises(ConfigError, match="resolved first"):
        devices.set_current("cuda")  # a name to resolve, not a device
    assert devices.current() == "cpu"


# ------------------------------------------------------------- device-agnostic models


def _td_batch(seeds: int, visits: int, agents: int, integer: bool, device: str) -> dict:
    state = (
        torch.zeros((seeds, visits), dtype=torch.int64)
        if integer
        else torch.rand((seeds, visits, 5), generator=torch.Generator().manual_seed(0))
    )
    batch = {
        "state": state,
        "actions": torch.ones((seeds, visits, agents), dtype=torch.int64),
        "reward": torch.arange(seeds * visits, dtype=torch.float32).view(seeds, visits) / 10,
        "next_state": state.clone(),
        "terminal": torch.zeros((seeds, visits), dtype=torch.bool),
    }
    return {key: value.to(device) for key, value in batch.items()}


def _value_decomposition(mixer: str, device: str):
    from cmarlcd.learners.deep.config import DeepConfig
    from cmarlcd.learners.deep.value_decomposition import ValueDecomposition

    seeds = [np.random.SeedSequence(k) for k in range(2)]
    model = ValueDecomposition([3, 3, 2], 5, DeepConfig(mixer=mixer), seeds, device)
    model.set_state_legal(torch.ones((5, 3, 3), dtype=torch.bool))
    return model


def _degree_model(share: bool, device: str, update: str = "keyed"):
    from cmarlcd.learners.deep.coordination import DeepCMARLCDConfig
    from cmarlcd.learners.deep.degree_model import DegreeModel

    seeds = [np.random.SeedSequence(k) for k in range(2)]
    config = DeepCMARLCDConfig(share=share, update=update)
    model = DegreeModel([3, 3, 2], 5, config, seeds, device)
    model.set_state_legal(torch.ones((5, 3, 3), dtype=torch.bool))
    return model


@pytest.mark.parametrize("mixer", ["vdn", "qmix"])
@pytest.mark.parametrize("integer", [True, False], ids=["one-hot", "features"])
def test_a_td_loss_makes_no_tensor_off_the_models_device(mixer: str, integer: bool) -> None:
    """On torch's ``meta`` device every tensor a step makes on the CPU by mistake (an
    ``arange`` without ``device=``) raises: the loss, its gradients and the greedy table
    run there, as they would on a GPU (fused Adam's step itself has no meta kernel)."""
    model = _value_decomposition(mixer, "meta")
    model.td_loss(_td_batch(2, 4, 3, integer, "meta")).backward()
    learnt = [p for p in model.parameters() if p.requires_grad]
    assert learnt and all(p.grad is not None and p.grad.device.type == "meta" for p in learnt)
    assert model.greedy_table().device.type == "meta"


def _memory_batch(seeds: int, states: int, agents: int, integer: bool, device: str) -> dict:
    """A batch drawn from deep CMARL-CD's keyed memory: kept states, their targets and
    records."""
    batch = _td_batch(seeds, states, agents, integer, device)
    return {
        "state": batch["state"],
        "target": torch.full((seeds, states, agents, 3), 1.5, device=device),
        "record": batch["reward"],
    }


@pytest.mark.parametrize("update", ["keyed", "replayed"])
@pytest.mark.parametrize("share", [False, True], ids=["per-agent", "shared"])
@pytest.mark.parametrize("integer", [True, False], ids=["one-hot", "features"])
def test_a_degree_loss_makes_no_tensor_off_the_models_device(
    share: bool, integer: bool, update: str
) -> None:
    """Both updates; the keyed loss (with the record network fitted to the memory's
    records, the default) reaches every parameter, as the replayed one does."""
    model = _degree_model(share, "meta", update)
    make_batch = _memory_batch if update == "keyed" else _td_batch
    model.loss(make_batch(2, 4, 3, integer, "meta")).backward()
    trained = [p for name, p in model.named_parameters() if not name.startswith("target_")]
    assert all(p.grad is not None for p in trained if p.requires_grad)
    assert model.greedy_table().device.type == "meta"


# ------------------------------------------------------------- the commands

DEEP_COMMANDS = {
    "dsn": ["dsn", "--algorithms", "vdn", "--runs", "1", "--episodes", "30"],
    "tournament": ["tournament", "--algorithms", "vdn,qmix", "--rounds", "1"],
    "compare": ["compare", "--learners", "deep-cmarl-cd", "--games", "climbing", "--runs", "1"],
    "scaling": ["scaling", "--preset", "quick", "--algorithms", "vdn", "--runs", "1"],
    "readings": ["readings", "--rounds", "1"],
    "reproduce": ["reproduce", "--preset", "quick"],
    "train": ["train", "--env", "tests.tiny_env:make", "--algorithms", "vdn"],
}


@pytest.mark.parametrize("command", sorted(DEEP_COMMANDS))
@pytest.mark.parametrize(
    ("device", "says"),
    [("cuda", "torch sees no GPU"), ("cuda:1", "torch sees no GPU"), ("gpu", "cpu, cuda")],
)
def test_a_gpu_that_is_not_there_is_refused_before_anything_runs(
    gpus, tmp_path, command: str, device: str, says: str
) -> None:
    """Every command that trains deep learners takes ``--device``; a GPU torch does not
    see, or a device misspelt: one line, exit 2, no store and no figures."""
    from tests.cli.common import assert_rejected_cleanly, invoke

    gpus(0)
    store, figures = tmp_path / "store.sqlite", tmp_path / "figures"
    where = ["--store", str(store), "--figures", str(figures), "--no-progress"]
    result = invoke(*DEEP_COMMANDS[command], *where, "--device", device)
    assert_rejected_cleanly(result, "--device", store, figures)
    assert says in result.stderr


@pytest.mark.parametrize("command", ["dsn", "tournament", "train"])
@pytest.mark.parametrize(("count", "says"), [("0", "must be >= 1"), ("257", "must be <= 256")])
def test_gpu_tasks_out_of_range_are_refused(tmp_path, command: str, count: str, says: str) -> None:
    from tests.cli.common import assert_rejected_cleanly, invoke

    store, figures = tmp_path / "store.sqlite", tmp_path / "figures"
    where = ["--store", str(store), "--figures", str(figures), "--no-progress"]
    result = invoke(*DEEP_COMMANDS[command], *where, "--gpu-tasks", count)
    assert_rejected_cleanly(result, "--gpu-tasks", store, figures)
    assert says in result.stderr


def test_a_tabular_command_has_no_device_option() -> None:
    from tests.cli.common import invoke

    result = invoke("repeated", "--device", "cpu")
    assert result.exit_code == 2 and "No such option" in result.output + result.stderr


def test_a_deep_run_records_its_device_and_a_tabular_one_none(tmp_path) -> None:
    from tests.cli.common import invoke

    store = tmp_path / "store.sqlite"
    args = ["dsn", "--algorithms", "vdn,cmarl-cd", "--runs", "1", "--episodes", "30"]
    where = ["--store", str(store), "--figures", str(tmp_path / "f"), "--workers", "1"]
    result = invoke(*args, "--eval-episodes", "5", *where, "--device", "auto", "--no-progress")
    assert result.exit_code == 0, result.output
    from cmarlcd.sweeps.store import ResultStore

    with ResultStore(store) as opened:
        recorded = {r.key.algorithm: r.metrics.get("device") for r in opened.records()}
    assert recorded == {"vdn": devices.describe(devices.resolve("auto")), "cmarl-cd": None}


# ------------------------------------------------------------- on a GPU (skipped here)


#: Each learner's model, its step and the batch it learns from (deep CMARL-CD's keyed
#: update: a batch of its memory, not a TD batch).
STEPPED_MODELS = {
    "vdn": (lambda device: _value_decomposition("vdn", device), "td_step", "td"),
    "qmix": (lambda device: _value_decomposition("qmix", device), "td_step", "td"),
    "deep-cmarl-cd": (lambda device: _degree_model(False, device), "learn", "memory"),
}


@gpu
@pytest.mark.parametrize("learner", sorted(STEPPED_MODELS))
@pytest.mark.parametrize("integer", [True, False], ids=["one-hot", "features"])
def test_one_gradient_step_agrees_on_cpu_and_gpu(learner: str, integer: bool) -> None:
    """From the same weights and batch, one Adam step (a TD step of VDN or QMIX, a step of
    deep CMARL-CD) gives the same loss and the same new weights within float tolerance."""
    build, step, kind = STEPPED_MODELS[learner]
    batch = {"td": _td_batch, "memory": _memory_batch}[kind]
    on_cpu, on_gpu = build("cpu"), build("cuda:0")
    loss_cpu = getattr(on_cpu, step)(batch(2, 16, 3, integer, "cpu"))
    loss_gpu = getattr(on_gpu, step)(batch(2, 16, 3, integer, "cuda:0"))
    assert loss_gpu == pytest.approx(loss_cpu, rel=1e-4, abs=1e-6)
    for cpu_param, gpu_param in zip(on_cpu.parameters(), on_gpu.parameters(), strict=True):
        torch.testing.assert_close(gpu_param.cpu(), cpu_param, rtol=1e-4, atol=1e-5)


@gpu
def test_a_tiny_tournament_runs_on_the_gpu(tmp_path) -> None:
    from tests.cli.common import invoke

    store = tmp_path / "store.sqlite"
    args = ["tournament", "--algorithms", "vdn,qmix,deep-cmarl-cd", "--rounds", "2"]
    budget = ["--learn-episodes", "300", "--eval-episodes", "100", "--seed-batch", "2"]
    where = ["--store", str(store), "--figures", str(tmp_path / "f"), "--workers", "1"]
    result = invoke(*args, *budget, *where, "--device", "cuda", "--no-progress")
    assert result.exit_code == 0, result.output
    from cmarlcd.sweeps.store import ResultStore

    with ResultStore(store) as opened:
        recorded = {r.metrics["device"] for r in opened.records()}
    assert len(recorded) == 1 and recorded.pop().startswith("cuda:0 (")


# ------------------------------------------------------------- sweeps


@dataclass(frozen=True)
class Chore(Settings):
    """A toy run that says where it ran; ``deep`` runs count as training a deep learner."""

    deep: bool
    index: int


def _where(chore: Chore, seed: np.random.SeedSequence) -> dict:
    if chore.deep:  # long enough for every worker of the GPU's lane to take one
        time.sleep(0.2)
    return {"built_on": devices.current(), "pid": os.getpid()}


register(Experiment("chore", Chore, _where, uses_device=lambda chore: chore.deep))


def _pretended_card(device: str) -> str:
    return f"{device} (a pretended card)"


if multiprocessing.parent_process() is not None and not HAS_GPU:
    # a sweep's worker process (which imports this module for its toy experiment) on a
    # machine without a card: the card the tests below pretend to have in the sweep's
    # process is pretended here too, as a monkeypatch there does not reach a worker
    devices.describe = _pretended_card


def _chores(deep: bool, count: int) -> list[RunSpec]:
    return [RunSpec.make("chore", "toy", Chore(deep, k), 0, 0) for k in range(count)]


@pytest.mark.slow
@pytest.mark.parametrize(("gpu_tasks", "gpu_workers"), [(1, 1), (8, 3)])
def test_with_a_gpu_the_deep_tasks_go_to_the_gpu_workers(
    tmp_path, monkeypatch, gpu_tasks: int, gpu_workers: int
) -> None:
    """Four workers and a (pretended) GPU: every deep run is built on the card by one of
    ``gpu_tasks`` worker processes (at most all workers but one) and records the card;
    the tabular runs run on the CPU in the other workers and record no device."""
    monkeypatch.setattr(devices, "gpu_count", lambda: 1)
    deep, tabular = _chores(True, 12), _chores(False, 12)
    with ResultStore(tmp_path / "store.sqlite") as store:
        run_sweep(deep + tabular, store, workers=4, device="cuda", gpu_tasks=gpu_tasks)
        deep_runs = [r.metrics for r in store.get(s.key for s in deep)]
        tabular_runs = [r.metrics for r in store.get(s.key for s in tabular)]
    assert {(m["built_on"], m["device"]) for m in deep_runs} == {
        ("cuda:0", _pretended_card("cuda:0") if not HAS_GPU else devices.describe("cuda:0"))
    }
    assert {m["built_on"] for m in tabular_runs} == {"cpu"}
    assert not any("device" in m for m in tabular_runs)
    on_the_card = {m["pid"] for m in deep_runs}
    assert len(on_the_card) == gpu_workers
    assert not on_the_card & {m["pid"] for m in tabular_runs}


@pytest.mark.slow
def test_with_a_gpu_deep_batches_alone_each_get_a_gpu_worker(tmp_path, monkeypatch) -> None:
    """Two deep runs and nothing else, four workers allowed: both run at once on the card,
    in two workers (the sweep does not size its pool by the batches alone, which would
    leave one of two workers to the CPU's lane and run the deep ones one after another)."""
    monkeypatch.setattr(devices, "gpu_count", lambda: 1)
    deep = _chores(True, 2)
    with ResultStore(tmp_path / "store.sqlite") as store:
        run_sweep(deep, store, workers=4, device="cuda")
        runs = [r.metrics for r in store.get(s.key for s in deep)]
    assert {m["built_on"] for m in runs} == {"cuda:0"}
    assert len({m["pid"] for m in runs}) == 2


@pytest.mark.slow
def test_one_worker_with_a_gpu_is_the_gpus_lane_and_takes_every_task() -> None:
    """``ProcessBackend(1, ..., "cuda:0")`` built directly: its one worker computes the
    deep runs on the card and the tabular ones too (before, it had no GPU lane and the
    deep runs went to the CPU)."""
    from cmarlcd.sweeps.backends.local import ProcessBackend

    backend = ProcessBackend(1, lambda *_: None, "cuda:0")
    deep, tabular = _chores(True, 1), _chores(False, 1)
    try:
        assert backend.has_room([deep]) and backend.has_room([tabular])
        backend.submit(0, [deep])
        backend.submit(1, [tabular])
        finished: dict[int, list] = {}
        while len(finished) < 2:
            for tag, outcomes, failure in backend.poll(5.0):
                assert failure is None, failure
                finished[tag] = outcomes
    finally:
        backend.close(cancel=True)
    (_, deep_metrics, _), (_, tabular_metrics, _) = finished[0][0], finished[1][0]
    assert deep_metrics["device"].startswith("cuda:0 (")  # the card, or the one pretended
    assert "device" not in tabular_metrics
    assert deep_metrics["pid"] == tabular_metrics["pid"]


@pytest.mark.parametrize(("workers", "gpu_tasks"), [(0, 8), (2, 0)])
def test_a_process_backend_of_no_workers_or_no_gpu_tasks_is_refused(
    workers: int, gpu_tasks: int
) -> None:
    from cmarlcd.errors import ConfigError
    from cmarlcd.sweeps.backends.local import ProcessBackend

    with pytest.raises(ConfigError):
        ProcessBackend(workers, lambda *_: None, "cuda:0", gpu_tasks)


def test_on_the_cpu_a_deep_run_records_the_cpu(tmp_path) -> None:
    with ResultStore(tmp_path / "store.sqlite") as store:
        run_sweep(_chores(True, 2) + _chores(False, 2), store, workers=1)
        recorded = {(r.key.config, r.metrics.get("device")) for r in store.records()}
    assert {device for _, device in recorded} == {"cpu", None}


@pytest.mark.parametrize(
    ("device", "gpus", "expected"),
    [
        ("cpu", 2, "cpu"),
        ("auto", 0, "cpu"),
        ("auto", 2, "cuda"),
        ("cuda:0", 2, "cuda"),
        ("cuda", 0.5, "cuda"),  # a node offering part of a card: deep tasks take shares
    ],
)
def test_a_ray_cluster_takes_a_gpu_where_it_has_one(
    device: str, gpus: float, expected: str
) -> None:
    from cmarlcd.sweeps.backends.ray_cluster import cluster_device

    assert cluster_device(device, gpus) == expected


def test_a_gpu_asked_of_a_ray_cluster_without_one_is_refused() -> None:
    from cmarlcd.sweeps.backends.ray_cluster import cluster_device

    with pytest.raises(ConfigError, match="the Ray cluster has no GPU"):
        cluster_device("cuda", 0)
    with pytest.raises(ConfigError, match="use --device cuda"):  # Ray picks each task's GPU
        cluster_device("cuda:1", 2)
