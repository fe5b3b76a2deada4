"""Policy files: a table's as ``.npz`` (its metadata a JSON string under
``__metadata__``), a network's as ``.safetensors`` (readable without PyTorch; its
metadata a JSON string under ``cmarlcd``). The metadata names the learner, its settings,
the experiment, the run's identity (so its seeds: ``evaluate`` replays the run's own
last evaluation), what the learner read (``inputs``, the agents' order) and the version
that wrote it. A file that is missing, truncated, of another format or of a newer one is
refused in one line."""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import numpy as np

from cmarlcd.errors import ConfigError, require
from cmarlcd.policies.greedy import NetworkPolicy, TablePolicy
from cmarlcd.policies.keeping import POLICY
from cmarlcd.runs import RunSpec, run_name

#: The policy files' format (a file of a larger one is refused).
FORMAT = 1
SUFFIXES = {"table": ".npz", "network": ".safetensors"}


def file_name(identity: dict[str, Any]) -> str:
    """``train-vdn-seed0-run2-1a2b3c4d``: the run's identity, its config's digest last."""
    return run_name(identity["experiment"], identity["algorithm"], identity["config_json"],
                    identity["root_seed"], identity["run_index"])  # fmt: skip


def write_policy(
    directory: Path,
    policy: TablePolicy | NetworkPolicy,
    identity: dict[str, Any],
    version: str,
    part: str | None = None,
) -> Path:
    """Write ``policy`` of the run ``identity`` (experiment, algorithm, config_json,
    stream_json, root_seed, run_index) into ``directory``, whole or not at all; ``part``:
    which of a run's policies it is (a match's team), appended to the file's name."""
    directory.mkdir(parents=True, exist_ok=True)
    meta = {**policy.metadata, **identity, "format": FORMAT, "kind": policy.kind,
            "version": version}  # fmt: skip
    if isinstance(policy, TablePolicy):
        meta["keys"] = None if policy.keys is None else [_plain(k) for k in policy.keys]
    stem = file_name(identity) if part is None else f"{file_name(identity)}-{part}"
    path = directory / (stem + SUFFIXES[policy.kind])
    partial = path.with_name(f".{path.name}.{os.getpid()}.part")
    text = json.dumps(meta)
    if policy.kind == "table":
        with partial.open("wb") as out:
            np.savez(out, **policy.arrays(), __metadata__=np.array(text))
    else:
        from safetensors.numpy import save_file

        arrays = {k: np.ascontiguousarray(v) for k, v in policy.arrays().items()}
        save_file(arrays, str(partial), metadata={"cmarlcd": text})
    partial.chmod(0o666 & ~_umask())  # as any file the user makes (safetensors writes 0600)
    os.replace(partial, path)
    return path


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def keep_policy(
    metrics: dict[str, Any], spec: RunSpec, directory: Path | None, version: str
) -> Path | None:
    """Take a run's policy out of its ``metrics`` (it is never stored) and write it into
    ``directory`` where one is given; the file (a run of several policies, a match's
    ``{part: policy}``, writes one file a part, each naming the others' files under
    ``partners``: the last is returned), or None."""
    policy = metrics.pop(POLICY, None)
    if policy is None or directory is None:
        return None
    identity = {"experiment": spec.experiment, "algorithm": spec.algorithm,
                "config_json": spec.config_json, "stream_json": spec.stream_json,
                "root_seed": spec.root_seed, "run_index": spec.run_index}  # fmt: skip
    if not isinstance(policy, dict):
        return write_policy(directory, policy, identity, version)
    names = {part: f"{file_name(identity)}-{part}{SUFFIXES[p.kind]}" for part, p in policy.items()}
    path = None
    for part, one in policy.items():
        one.metadata["partners"] = {k: v for k, v in names.items() if k != part}
        path = write_policy(directory, one, identity, version, part)
    return path


def load_partner(path: Path, policy: TablePolicy | NetworkPolicy, part: str) -> Any:
    """The policy of ``part`` kept beside ``policy`` (read from ``path``) by the same
    run, or one clear error."""
    partners = policy.metadata.get("partners") or {}
    require(part in partners, "policy", f"{path}: its run kept no {part} policy")
    other = Path(path).parent / partners[part]
    require(other.is_file(), "policy", f"{path}: its {part} policy {other.name} is not beside it")
    return load_policy(other)


def load_policy(path: str | os.PathLike) -> TablePolicy | NetworkPolicy:
    """The policy kept in ``path``, ready to act (:meth:`TablePolicy.act`,
    :meth:`NetworkPolicy.act`)."""
    path = Path(path)
    require(path.is_file(), "policy", f"{path}: no such file")
    kinds = {suffix: kind for kind, suffix in SUFFIXES.items()}
    require(
        path.suffix in kinds,
        "policy",
        f"{path}: not a policy file (.npz for a table, .safetensors for a network)",
    )
    try:
        arrays, meta = _read(path, kinds[path.suffix])
    except ConfigError:
        raise
    except Exception as error:  # a truncated or foreign file: whatever its reader says
        first = str(error).strip().splitlines()[0] if str(error).strip() else type(error).__name__
        raise ConfigError("policy", f"{path}: not a readable policy file ({first})") from None
    require(
        meta.get("format", FORMAT + 1) <= FORMAT,
        "policy",
        f"{path}: written by cmarl-cd {meta.get('version', '?')} in a newer format "
        f"({meta.get('format')}); this is format {FORMAT}",
    )
    if meta["kind"] == "table":
        keys = meta.pop("keys")
        keys = None if keys is None else [_hashable(k) for k in keys]
        return TablePolicy(arrays["actions"], arrays["seen"], arrays["fresh"], arrays["counts"],
                           keys, meta)  # fmt: skip
    return NetworkPolicy(arrays, meta)


def _read(path: Path, kind: str) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    if kind == "table":
        with np.load(path, allow_pickle=False) as data:
            arrays = {k: data[k] for k in data.files}
        require("__metadata__" in arrays, "policy", f"{path}: an .npz without cmarl-cd's metadata")
        meta = json.loads(str(arrays.pop("__metadata__")))
    else:
        from safetensors import safe_open
        from safetensors.numpy import load_file

        with safe_open(str(path), framework="numpy") as data:
            text = (data.metadata() or {}).get("cmarlcd")
        require(text is not None, "policy", f"{path}: a .safetensors without cmarl-cd's metadata")
        arrays, meta = load_file(str(path)), json.loads(text)
    require(meta.get("kind") == kind, "policy", f"{path}: its metadata says {meta.get('kind')}")
    return arrays, meta


def _plain(key: Any) -> Any:
    """A state as JSON keeps it (tuples as lists, numpy numbers as Python's)."""
    if isinstance(key, tuple | list):
        return [_plain(k) for k in key]
    return key.item() if isinstance(key, np.generic) else key


def _hashable(key: Any) -> Any:
    """:func:`_plain`'s inverse: lists back to tuples."""
    return tuple(_hashable(k) for k in key) if isinstance(key, list) else key
