"""Merging the output folders of a sharded batch into what one unsharded run writes.

``robolab merge DIR_1 ... DIR_N --out DIR`` reads each shard's ``shard.json``
(:mod:`robolab.grading.course.shards`) and batch state, checks that the shards belong
together, and hands the union of their results to :class:`~robolab.grading.course.Course`,
which writes the gradebook, feedback, exports and class report exactly as ``robolab
grade`` does; the roster, overrides and late policy are given to the merge and applied
there, once, to every row.

The merge refuses, naming the folders: a folder that is not a shard's output; shards
cut from different file lists or a different N; a slice given twice; a submission in
two shards; a shard that has not finished its slice; shards graded by different
graders (the robolab version, grading code, hidden tests, solution and time limit of a
lab, :func:`~robolab.grading.course.batch.grader_fingerprint`). It says which shards are missing.
"""

from __future__ import annotations

import os
from collections import defaultdict
from collections.abc import Sequence
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path

from robolab.grading.course.batch import STATE_FILE, BatchState, display_path
from robolab.grading.course.late import parse_time
from robolab.grading.course.shards import read_manifest

__all__ = ["MergeError", "ShardOutput", "merged_state", "read_shards"]


class MergeError(ValueError):
    """The shards cannot be merged (every reason found, one per line)."""


@dataclass
class ShardOutput:
    """One shard's output folder: its manifest and its graded entries by submission name."""

    folder: Path
    manifest: dict
    entries: dict[str, dict]  # name -> batch state entry

    @property
    def label(self) -> str:
        return f"shard {self.manifest['shard']}/{self.manifest['of']} ({display_path(self.folder)})"


def read_shards(folders: Sequence[Path]) -> list[ShardOutput]:
    """Read every shard folder (a ``MergeError`` listing each one that is not a shard)."""
    shards, problems = [], []
    for folder in folders:
        folder = Path(folder)
        if not folder.is_dir():
            problems.append(f"{display_path(folder)} is not a folder")
            continue
        try:
            manifest = read_manifest(folder)
            state = BatchState.load(folder)
        except ValueError as exc:
            problems.append(str(exc))
            continue
        by_name = {e["result"]["name"]: e for e in state.entries.values()}
        shards.append(ShardOutput(folder, manifest, by_name))
    if problems:
        raise MergeError("\n".join(problems))
    if not shards:
        raise MergeError("no shard folders given")
    return shards


def _check(shards: list[ShardOutput]) -> None:
    problems = []
    first = shards[0]
    for s in shards[1:]:
        if (s.manifest["batch"], s.manifest["of"]) != (
            first.manifest["batch"],
            first.manifest["of"],
        ):
            problems.append(
                f"{s.label} and {first.label} were cut from different batches (another file "
                "list, changed files, or another N): grade every shard from the same files "
                "with the same N"
            )
    count = first.manifest["of"]
    seen: dict[int, ShardOutput] = {}
    for s in shards:
        k = s.manifest["shard"]
        if k in seen:
            problems.append(f"shard {k}/{count} given twice: {s.label} and {seen[k].label}")
        seen.setdefault(k, s)
    missing = sorted(set(range(1, count + 1)) - set(seen))
    if missing:
        problems.append(
            f"missing shard(s) {', '.join(map(str, missing))} of {count}: grade them with "
            + ", ".join(f"--shard {k}/{count}" for k in missing[:5])
            + (" ..." if len(missing) > 5 else "")
        )
    owner: dict[str, ShardOutput] = {}
    for s in shards:
        for name in s.manifest["members"]:
            if name in owner and owner[name] is not s:
                problems.append(f"submission {name} is in {owner[name].label} and in {s.label}")
            owner.setdefault(name, s)
        unfinished = [n for n in s.manifest["members"] if n not in s.entries]
        if unfinished:
            problems.append(
                f"{s.label} has not finished: {len(unfinished)} of {len(s.manifest['members'])} "
                f"submission(s) not graded ({', '.join(unfinished[:3])}"
                + (", ..." if len(unfinished) > 3 else "")
                + "); run its command again"
            )
    graders: dict[str | None, dict[str, ShardOutput]] = defaultdict(dict)
    for s in shards:
        for name in s.manifest["members"]:
            entry = s.entries.get(name)
            if entry is not None:
                graders[entry["result"]["lab"]].setdefault(entry["grader"], s)
    for lab, by_grader in graders.items():
        if len(by_grader) > 1:
            which = "; ".join(
                f"{s.label}: robolab {s.manifest['robolab']}, grader {g}"
                for g, s in by_grader.items()
            )
            problems.append(
                f"lab {lab!r} was graded by different graders ({which}): the robolab version, "
                "the hidden tests, the solutions or --timeout differ; regrade with one"
            )
    if problems:
        raise MergeError("\n".join(dict.fromkeys(problems)))


def merged_state(shards: list[ShardOutput], out: Path) -> tuple[BatchState, dict[str, datetime]]:
    """The union of the shards' results as a batch state of ``out`` (not saved), and each
    submission's modification time as the shard saw it (for the late policy).

    The state's keys are the submissions' paths relative to the batch's common folder,
    the same on every node, so that the roster matches them as it matches an unsharded
    batch's files.
    """
    _check(shards)
    if (Path(out) / STATE_FILE).exists():
        raise MergeError(
            f"--out {display_path(out)} holds a grading batch ({STATE_FILE}); merge into a "
            "new folder"
        )
    for s in shards:
        if Path(out).resolve() == s.folder.resolve():
            raise MergeError(f"--out {display_path(out)} is {s.label}; merge into a new folder")
    state = BatchState(Path(out))
    modified = {}
    members = [(name, m, s) for s in shards for name, m in s.manifest["members"].items()]
    for name, member, s in sorted(members, key=lambda x: os.fsencode(x[1]["relative"])):
        state.entries[member["relative"]] = dict(s.entries[name])
        if member.get("modified"):
            modified[name] = parse_time(member["modified"], f"{s.label}: modified")
    return state, modified
