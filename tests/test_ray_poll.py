"""How a Ray sweep ends when its cluster goes away under it, against a stand-in for Ray
(no Ray needed): a task the cluster lost ends the sweep at once, before the progress
relay is asked (asking it could wait on the dead head until Ray itself killed the
process with status 1), and a relay that cannot be made anew is one line."""

from __future__ import annotations

import threading
import time
from types import SimpleNamespace

import pytest

from cmarlcd.errors import BackendLost
from cmarlcd.sweeps.backends.ray_cluster import RayBackend


class RayError(Exception):
    pass


class RayTaskError(RayError):
    pass


class GetTimeoutError(RayError):
    pass


class RayActorError(RayError):
    pass


class FakeRay:
    """Every task ``wait`` is asked about is done and lost; the relay's ``take`` hangs
    (``relay_hangs``) or finds the actor gone; making a relay anew fails."""

    exceptions = SimpleNamespace(
        RayError=RayError,
        RayTaskError=RayTaskError,
        GetTimeoutError=GetTimeoutError,
        RayActorError=RayActorError,
    )

    def __init__(self, relay_hangs: bool) -> None:
        self.relay_hangs = relay_hangs
        self.remote_calls = 0

    def wait(self, refs, num_returns, timeout):
        return list(refs), []

    def get(self, ref, timeout=None):
        if ref == "take":
            if self.relay_hangs:
                time.sleep(30)  # a call to a head that is gone
            raise RayActorError("the relay's node died")
        raise RayError("the task's node died")

    def remote(self, **options):
        self.remote_calls += 1
        raise AssertionError("the relay's class is sent to the cluster once, at the start")


def backend(ray: FakeRay, pending: dict) -> RayBackend:
    made = object.__new__(RayBackend)
    relay = SimpleNamespace(take=SimpleNamespace(remote=lambda: "take"))

    def gone():
        raise ConnectionError("GCS unreachable")

    made.__dict__.update(
        ray=ray,
        failure=None,
        lost=False,
        watch=SimpleNamespace(lost=None),
        pending=pending,
        on_gpu=set(),
        relay=relay,
        relay_class=SimpleNamespace(remote=gone),
        head=None,
        address="127.0.0.1:6379",
        on_progress=lambda *_: None,
    )
    return made


def within(seconds: float, call):
    """``call()``'s result or exception, failing the test if it takes longer."""
    outcome: dict = {}

    def run() -> None:
        try:
            outcome["value"] = call()
        except BaseException as exc:  # handed to the test
            outcome["error"] = exc

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    thread.join(seconds)
    assert not thread.is_alive(), f"still waiting after {seconds} s"
    if "error" in outcome:
        raise outcome["error"]
    return outcome["value"]


def test_a_lost_task_ends_the_sweep_before_the_relay_is_asked() -> None:
    sweep = backend(FakeRay(relay_hangs=True), {"task-ref": 0})
    assert within(5, lambda: sweep.poll(0.1)) == []  # what finished before is stored first
    with pytest.raises(BackendLost, match="lost a task"):
        within(5, lambda: sweep.poll(0.1))


def test_a_relay_that_cannot_be_made_anew_is_one_line() -> None:
    ray = FakeRay(relay_hangs=False)
    sweep = backend(ray, {})
    with pytest.raises(BackendLost) as lost:
        within(5, lambda: sweep.poll(0.01))
    assert "went away as the progress relay was made anew (GCS unreachable)" in str(lost.value)
    assert "\n" not in str(lost.value) and sweep.lost and ray.remote_calls == 0


def test_why_a_cluster_could_not_be_joined_keeps_the_cause() -> None:
    from cmarlcd.sweeps.backends.ray_cluster import why

    try:
        try:
            raise PermissionError("token is missing or incorrect\nmore")
        except PermissionError as cause:
            raise ConnectionError("Failed to connect to Ray cluster at 10.0.0.2:6379") from cause
    except ConnectionError as exc:
        said = why(exc)
    assert said == (
        "Failed to connect to Ray cluster at 10.0.0.2:6379 "
        "(PermissionError: token is missing or incorrect)"
    )
    assert why(ValueError("")) == "ValueError"
