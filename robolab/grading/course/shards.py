"""Cutting one batch into N shards that any scheduler can grade apart, then merge.

``robolab grade FILES... --shard K/N --out DIR_K`` grades the K-th of N slices of the
batch. The slices depend on the file list alone, never on the machine: each submission
is known by its path relative to the common folder of all the files (so the same
folder mounted at ``/data`` on one node and ``/scratch/x`` on another gives the same
slices), the order of the arguments does not matter, and the submissions are dealt
out by expected cost (the lab's grading time, :data:`EXPECTED_SECONDS`), most costly
first, each to the least loaded shard (the "longest processing time first" rule:
its most loaded shard is within 4/3 of the best possible split).

Each shard writes ``shard.json`` beside its gradebook: which slice it is, an identity
of the whole batch (the relative paths and contents of all the files), the members of
its slice with their modification times (the late policy needs them at merge time,
where the files may not be), and the robolab version. :mod:`robolab.grading.course.merge`
reads it.
"""

from __future__ import annotations

import hashlib
import heapq
import json
import os
import re
from collections.abc import Sequence
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path

from robolab.grading.course.batch import atomic_write

__all__ = [
    "EXPECTED_SECONDS",
    "SHARD_FILE",
    "Shard",
    "batch_identity",
    "deal",
    "parse_shard",
    "read_manifest",
    "write_manifest",
]

#: The manifest a shard writes beside its gradebook.
SHARD_FILE = "shard.json"
_FORMAT = 1

#: CPU seconds to grade one submission of each lab (its worker, pytest and a share of the
#: process's start). bayes, beam_model and mcl are measured by ``benchmarks/shards.py``
#: (2026-12-02, the mean over a correct, a partial and a wrong submission); the others are
#: estimated from their hidden tests' size. Only their ratios matter; a lab not listed
#: costs the median.
EXPECTED_SECONDS = {
    "bayes": 2.6,
    "beam_model": 5.1,
    "demo": 2.0,
    "ekf_mapping": 10.0,
    "ekf_slam": 8.0,
    "fastslam": 8.0,
    "frames": 3.0,
    "graph_slam": 8.0,
    "landmark_pf": 6.0,
    "mcl": 12.1,
    "odometry_mapping": 6.0,
}
_MEDIAN = sorted(EXPECTED_SECONDS.values())[len(EXPECTED_SECONDS) // 2]


@dataclass(frozen=True)
class Shard:
    """The ``index``-th (1-based) of ``count`` slices of a batch."""

    index: int
    count: int

    def __post_init__(self):
        if not 1 <= self.index <= self.count:
            raise ValueError(
                f"--shard {self.index}/{self.count}: K must be between 1 and N ({self.count})"
            )

    def __str__(self) -> str:
        return f"{self.index}/{self.count}"


def parse_shard(text: str) -> Shard:
    """``"K/N"`` as a :class:`Shard` (a clear ``ValueError`` naming ``--shard`` otherwise)."""
    match = re.fullmatch(r"\s*(\d+)\s*/\s*(\d+)\s*", text)
    if not match:
        raise ValueError(f"--shard {text!r}: expected K/N, e.g. 3/8 (the 3rd of 8 slices)")
    index, count = int(match[1]), int(match[2])
    if count < 1:
        raise ValueError(f"--shard {text}: N must be at least 1")
    return Shard(index, count)


def deal(relative: Sequence[str], labs: Sequence[str | None], count: int) -> list[int]:
    """The shard (0-based) of each submission: most costly first, to the least loaded shard.

    Parameters
    ----------
    relative
        Each submission's path relative to the batch's common folder (unique).
    labs
        The lab each is graded as (its expected cost, :data:`EXPECTED_SECONDS`).
    count
        The number of shards.

    Returns
    -------
    list of int
        ``shard[i]`` for submission ``i``; the same whatever the order of the input.
    """
    if len(relative) != len(labs):
        raise ValueError(f"deal: {len(relative)} paths but {len(labs)} labs")
    if count < 1:
        raise ValueError(f"deal: count must be at least 1, got {count}")
    cost = [EXPECTED_SECONDS.get(lab or "", _MEDIAN) for lab in labs]
    # a total order that ignores the input order: cost, then the relative path's bytes
    order = sorted(range(len(relative)), key=lambda i: (-cost[i], os.fsencode(relative[i])))
    loads = [(0.0, 0, k) for k in range(count)]  # (load, members, shard): ties to fewer, lower
    shard = [0] * len(relative)
    for i in order:
        load, members, k = heapq.heappop(loads)
        shard[i] = k
        heapq.heappush(loads, (load + cost[i], members + 1, k))
    return shard


def batch_identity(relative: Sequence[str], digests: Sequence[str | None]) -> str:
    """A digest of the whole batch: every relative path with its content's sha256.

    Shards cut from different file lists (or from files that changed between the
    nodes) have different identities, and :mod:`~robolab.grading.course.merge` refuses them.
    """
    h = hashlib.sha256()
    for rel, digest in sorted(zip(relative, digests, strict=True), key=lambda p: os.fsencode(p[0])):
        h.update(os.fsencode(rel) + b"\0" + (digest or "unreadable").encode() + b"\n")
    return h.hexdigest()[:20]


def _mtime(path: Path) -> str | None:
    try:
        return datetime.fromtimestamp(os.stat(path).st_mtime, tz=timezone.utc).isoformat()
    except OSError:
        return None


def write_manifest(
    out: Path, shard: Shard, identity: str, total: int, members: Sequence[tuple[str, str, Path]]
) -> Path:
    """Write ``out/shard.json``: the slice, the batch identity and ``members``.

    ``members`` are ``(name, relative path, path)`` of the submissions of this slice.
    """
    import robolab

    data = {
        "format": _FORMAT,
        "shard": shard.index,
        "of": shard.count,
        "batch": identity,
        "submissions_in_batch": total,
        "robolab": robolab.__version__,
        "members": {
            name: {"relative": os.fsdecode(rel), "modified": _mtime(path)}
            for name, rel, path in members
        },
    }
    path = Path(out) / SHARD_FILE
    atomic_write(path, json.dumps(data, indent=1) + "\n")
    return path


def read_manifest(folder: Path) -> dict:
    """The ``shard.json`` of a shard's output folder (``ValueError`` when it is not one)."""
    path = Path(folder) / SHARD_FILE
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ValueError(
            f"{os.fsdecode(folder)} is not a shard's output (no {SHARD_FILE}): "
            "grade it with --shard K/N"
        ) from None
    except (OSError, ValueError) as exc:
        raise ValueError(f"{os.fsdecode(path)} cannot be read: {exc}") from None
    if not isinstance(data, dict) or data.get("format") != _FORMAT:
        raise ValueError(f"{os.fsdecode(path)} is not a shard manifest this robolab reads")
    return data
