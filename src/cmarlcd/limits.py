"""The largest sizes a sweep, a run or a command accepts, checked before anything is planned.

A sweep lists its runs before it starts (to find those the store already holds, order them
by cost and hand them out), and a run allocates its evaluation arrays up front, so a size
far beyond any real protocol would spend minutes and gigabytes before anything is shown.
Every size a user can give (runs, rounds, episodes, evaluation episodes, seed batch, games,
starting points) is checked against these caps in constant time, by arithmetic on the
options, and refused in one line otherwise. Each cap is far above the paper's full
protocol, which is quoted beside it.
"""

from __future__ import annotations

from cmarlcd.errors import require

MAX_RUNS = 200_000
"""Runs of one sweep. The paper's whole protocol is 2,502 runs, ``reproduce --preset
paper`` with the learner comparison 18,752; listing 200,000 runs takes a few seconds.
Larger studies are split by ``--seed``, each its own sweep on one store."""

MAX_EPISODES = 100_000_000
"""Learning or evaluation episodes of one run (the paper's largest budget: 500,000). An
evaluation keeps 16 bytes per episode, so the cap is 1.6 GB of memory per worker."""

MAX_STEPS = 10_000_000_000
"""Learning steps of one run counted in environment steps (EPyMARL's protocol: 2.05M)."""

MAX_GAMES = 1_000_000_000
"""Games of one repeated-game run before it counts as a failure (default: 10,000,000)."""

MAX_SEED_BATCH = 1_000
"""Seeds (or rounds) of a deep learner trained together in one stacked model (default:
10); each holds its own replay buffer, so memory grows with the batch."""

MAX_GPU_TASKS = 256
"""Deep tasks that share one GPU (default 8): each local one is a process with a CUDA
context of its own."""

MAX_SEED = 2**63 - 1
"""The largest root seed: the store keeps seeds as SQLite's 64-bit integers."""

MAX_WORKERS = 10_000
"""Worker processes, or CPUs of a Ray cluster, one sweep uses."""

MAX_CURVE_POINTS = 1_000
"""Points of a learning curve (default: 20): each is an evaluation of its own."""

MAX_STARTS = 100_000
"""Starting points of the Theorem 1 check (default: 100)."""


def check_at_most(value: int, cap: int, parameter: str, what: str = "") -> None:
    """``value`` is within ``cap``, or a one-line error naming the option and the cap."""
    extra = f" ({what})" if what else ""
    require(value <= cap, parameter, f"must be <= {cap:,} (got {value:,}){extra}")


def check_run_count(runs: int, parameter: str = "runs") -> None:
    """A sweep of ``runs`` runs is within :data:`MAX_RUNS`; ``parameter`` is the option
    that multiplies it (``runs``, ``rounds``)."""
    require(
        runs <= MAX_RUNS,
        parameter,
        f"the sweep would hold {runs:,} runs, more than the {MAX_RUNS:,} one sweep "
        "may hold; split it into sweeps of different --seed",
    )


def check_episodes(episodes: int, parameter: str) -> None:
    """A learning or evaluation budget within :data:`MAX_EPISODES`."""
    check_at_most(episodes, MAX_EPISODES, parameter)


def check_steps(steps: int, parameter: str) -> None:
    """A learning budget of environment steps within :data:`MAX_STEPS`."""
    check_at_most(steps, MAX_STEPS, parameter)


def check_seed(seed: int, parameter: str = "seed") -> None:
    """A root seed in ``[0, MAX_SEED]``."""
    require(0 <= seed <= MAX_SEED, parameter, f"must be in [0, 2^63 - 1] (got {seed})")


def check_workers(workers: int | None) -> None:
    """``None`` (all cores) or a count in ``[1, MAX_WORKERS]``."""
    require(workers is None or workers >= 1, "workers", f"must be >= 1 (got {workers})")
    if workers is not None:
        check_at_most(workers, MAX_WORKERS, "workers")


def check_gpu_tasks(gpu_tasks: int) -> None:
    """Deep tasks sharing one GPU, in ``[1, MAX_GPU_TASKS]``."""
    require(gpu_tasks >= 1, "gpu_tasks", f"must be >= 1 (got {gpu_tasks})")
    check_at_most(gpu_tasks, MAX_GPU_TASKS, "gpu_tasks")


def check_seed_batch(seed_batch: int) -> None:
    """A seed batch in ``[1, MAX_SEED_BATCH]``."""
    require(seed_batch >= 1, "seed_batch", f"must be >= 1 (got {seed_batch})")
    check_at_most(seed_batch, MAX_SEED_BATCH, "seed_batch")
