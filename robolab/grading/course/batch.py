"""A durable grading batch: names, the output folder, the lab of each submission, resuming.

``robolab grade`` never loses a grade:

- the output folder is created and probed for writing before anything is graded;
- each submission's result is recorded in ``<out>/.robolab-state.json`` (and its row and
  feedback written, by the caller's ``publish``) as soon as it finishes, every file
  replaced atomically (temporary file + ``os.replace``);
- a later run into the same folder regrades only the submissions whose content (sha256)
  or grader (robolab version, grading code, the lab's hidden tests and solution, the
  time limit) changed, and keeps the rows of the others;
- names are unique and stable: the path relative to the batch's common folder, folders
  joined with ``-``, characters outside ``[A-Za-z0-9._-]`` (and any other letter) replaced
  by ``_``; names that still collide get a short hash of their relative path.

The lab of each submission is decided here (see :func:`assign_labs`): a notebook whose
lab differs from ``--lab``, from a lab its file name names, or from the batch's majority
is graded as that lab and flagged, never silently graded as the lab it claims.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import tempfile
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

from robolab.grading.labs import (
    LabError,
    discover_labs,
    display_path,
    find_lab,
    lab_of_notebook,
    read_submission,
)
from robolab.grading.running.runner import SubmissionResult

__all__ = [
    "STATE_FILE",
    "BatchError",
    "BatchState",
    "Planned",
    "assign_labs",
    "atomic_write",
    "display_path",
    "grader_fingerprint",
    "prepare_out",
    "relative_paths",
    "submission_names",
]

#: The batch's memory of what it graded, inside the output folder.
STATE_FILE = ".robolab-state.json"
_STATE_FORMAT = 1
_MAX_NAME = 100
_UMASK = os.umask(0o022)
os.umask(_UMASK)


class BatchError(ValueError):
    """The batch cannot run: an output folder that cannot be written, a broken state file."""


def atomic_write(path: Path, text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` through a temporary file and ``os.replace``.

    A reader, or a run killed half-way, sees the old file or the new one, never a
    part of either.
    """
    path = Path(path)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        # backslashreplace: a file name that is not UTF-8 (surrogate escapes) stays visible
        with os.fdopen(fd, "w", encoding="utf-8", errors="backslashreplace", newline="") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
        os.chmod(tmp, 0o666 & ~_UMASK)  # as open() would have made it, not mkstemp's 0600
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise


def prepare_out(out: Path) -> Path:
    """Create ``out`` (and ``out/feedback``) and prove it is writable; return it.

    Raises
    ------
    BatchError
        When ``out`` is a file, cannot be created, or cannot be written.
    """
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise BatchError(f"--out {display_path(out)} exists and is not a folder")
    try:
        (out / "feedback").mkdir(parents=True, exist_ok=True)
        atomic_write(out / ".robolab-write-test", "ok\n")
        (out / ".robolab-write-test").unlink()
    except OSError as exc:
        raise BatchError(
            f"--out {display_path(out)} cannot be written: {exc.strerror or exc}"
        ) from None
    return out


def _safe_name(text: str) -> str:
    """File-name-safe text: word characters (any script), ``.``, ``-``; others become ``_``."""
    name = "".join(c if (c.isalnum() or c in "._-") and c.isprintable() else "_" for c in text)
    name = re.sub(r"_+", "_", name).strip("._") or "submission"
    if len(name.encode("utf-8", "surrogatepass")) > _MAX_NAME:
        name = name[:60] + "-" + hashlib.sha1(text.encode("utf-8", "surrogatepass")).hexdigest()[:8]
    return name


def relative_paths(paths: Sequence[str | os.PathLike]) -> list[str]:
    """Each path relative to the common folder of all of them."""
    absolute = [os.path.abspath(os.fsdecode(p)) for p in paths]
    if not absolute:
        return []
    common = os.path.commonpath([os.path.dirname(a) for a in absolute])
    return [os.path.relpath(a, common) for a in absolute]


def submission_names(paths: Sequence[str | os.PathLike]) -> list[str]:
    """Unique, stable, file-name-safe names, one per path (equal paths get equal names).

    The name is the path relative to the paths' common folder without ``.ipynb``,
    folders joined with ``-`` (``x/s.ipynb`` -> ``x-s``). Names that collide after
    that (``x/s.ipynb`` and ``x-s.ipynb``) each get ``-`` and the first hex digits of
    the sha1 of their relative path, so that the result depends only on the paths.
    """
    rel = relative_paths(paths)
    base = {
        r: _safe_name("-".join(_safe_name(part) for part in r.removesuffix(".ipynb").split(os.sep)))
        for r in rel
    }
    groups = Counter(base.values())
    names: dict[str, str] = {}
    taken = {b for b, n in groups.items() if n == 1}
    for r in sorted(base):
        b = base[r]
        if groups[b] == 1:
            names[r] = b
            continue
        digest = hashlib.sha1(os.fsencode(r)).hexdigest()
        for width in range(6, 41):
            candidate = f"{b}-{digest[:width]}"
            if candidate not in taken:
                break
        taken.add(candidate)
        names[r] = candidate
    return [names[r] for r in rel]


def file_digest(path: Path) -> str | None:
    """sha256 of the file's bytes, or None when it is not a readable notebook-sized file."""
    try:
        return hashlib.sha256(read_submission(path)).hexdigest()
    except LabError:
        return None


def grader_fingerprint(lab: str | None, root: Path, timeout: float) -> str:
    """What the grade of a submission of ``lab`` depends on besides the submission itself.

    The robolab version, the grading code, the lab's hidden tests and reference
    solution, and the time limit: when any of them changes, the submission is regraded.
    """
    import robolab

    h = hashlib.sha256(f"{robolab.__version__}\0{lab}\0{timeout!r}".encode())
    # every module of robolab.grading, in all its sub-packages (not only this one's)
    grading = Path(__file__).resolve().parents[1]
    files = sorted(grading.rglob("*.py"), key=lambda f: f.relative_to(grading).as_posix())
    if lab is not None:
        try:
            spec = find_lab(lab, root)
            files += [spec.hidden_tests, spec.solution]
        except LabError:
            pass
    for f in files:
        h.update(f.name.encode())
        try:
            h.update(f.read_bytes())
        except OSError:
            h.update(b"<missing>")
    return h.hexdigest()[:16]


def _path_hint(rel: str, known: set[str]) -> str | None:
    """The one known lab that the relative path names (a folder, the file name or a part of it)."""
    parts = [p.lower().replace("-", "_").replace(" ", "_") for p in Path(rel).with_suffix("").parts]
    found = set()
    for lab in known:
        for part in parts:
            if part == lab or re.search(rf"(^|_){re.escape(lab)}($|_)", part):
                found.add(lab)
    # beam_model also contains "model": keep the longest names only when one contains another
    found = {f for f in found if not any(f != g and f in g for g in found)}
    return found.pop() if len(found) == 1 else None


def assign_labs(
    paths: Sequence[Path], lab: str | None, root: Path
) -> list[tuple[str | None, list[str]]]:
    """The lab to grade each submission as, and the flags that go with it.

    With ``lab`` (``--lab``) every submission is graded as ``lab``; one whose notebook
    names another lab is flagged. Without it the expected lab of a submission is the
    known lab its path names (``alice_bayes.ipynb``, ``bayes/alice.ipynb``), else the
    lab of a strict majority of the batch; a notebook that names another lab (or none)
    is graded as the expected lab and flagged. With no expectation the notebook's own
    lab is used.
    """
    declared: list[str | None] = []
    unreadable = set()
    for i, p in enumerate(paths):
        try:
            declared.append(lab_of_notebook(p))
        except LabError:  # graded as is: grade_submission says what is wrong with it
            declared.append(None)
            unreadable.add(i)
    if lab is not None:
        return [
            (
                lab,
                []
                if d in (None, lab) or i in unreadable
                else [
                    f"lab mismatch: the notebook says lab {d!r} but --lab {lab} was given; "
                    f"graded as {lab!r}"
                ],
            )
            for i, d in enumerate(declared)
        ]
    known = {spec.name for spec in discover_labs(root) if spec.hidden_tests.is_file()}
    counted = Counter(d for d in declared if d is not None)
    majority = None
    if counted:
        top, n = counted.most_common(1)[0]
        if n * 2 > sum(counted.values()) and top in known:
            majority = top
    total = sum(counted.values())
    out = []
    for i, (rel, d) in enumerate(zip(relative_paths(paths), declared, strict=True)):
        hint = _path_hint(rel, known)
        expected = hint or majority
        if expected is None or d == expected or i in unreadable:
            out.append((d, []))
            continue
        why = (
            f"its file name names lab {expected!r}"
            if hint
            else f"most of the batch ({counted[expected]} of {total}) is lab {expected!r}"
        )
        flag = (
            f"lab mismatch: the notebook says lab {d!r} but {why}; graded as {expected!r} "
            f"(if {d!r} is right, grade it alone with --lab {d})"
            if d
            else f"lab missing: the notebook names no lab; graded as {expected!r} ({why})"
        )
        out.append((expected, [flag]))
    return out


@dataclass
class Planned:
    """One submission of a batch, before grading."""

    key: str  # absolute path (surrogate escapes for non-UTF-8 bytes)
    path: Path  # as given
    name: str
    lab: str | None
    flags: list[str]
    digest: str | None
    grader: str
    previous: SubmissionResult | None = None  # a still-valid earlier result


@dataclass
class BatchState:
    """What earlier runs into ``out`` graded: ``{key: {given, digest, grader, result}}``."""

    out: Path
    entries: dict[str, dict] = field(default_factory=dict)

    @classmethod
    def load(cls, out: Path) -> BatchState:
        path = Path(out) / STATE_FILE
        if not path.is_file():
            return cls(Path(out))
        try:
            data = json.loads(path.read_text(encoding="utf-8"))
            if data.get("format") != _STATE_FORMAT:
                raise ValueError(f"format {data.get('format')!r}")
            entries = {k: dict(v) for k, v in data["entries"].items()}
            for v in entries.values():
                SubmissionResult.from_dict(v["result"])
        except (OSError, ValueError, KeyError, TypeError, AttributeError) as exc:
            raise BatchError(
                f"{display_path(path)} is not a robolab batch state ({exc}); "
                "move it away to start the batch afresh"
            ) from None
        return cls(Path(out), entries)

    def save(self) -> None:
        data = {"format": _STATE_FORMAT, "entries": self.entries}
        atomic_write(self.out / STATE_FILE, json.dumps(data, indent=1) + "\n")

    def plan(
        self, paths: Sequence[Path], lab: str | None, root: Path, timeout: float
    ) -> list[Planned]:
        """The submissions to grade (duplicates removed), named over this run and earlier ones."""
        unique: dict[str, Path] = {}
        for p in paths:
            unique.setdefault(os.path.abspath(os.fsdecode(p)), Path(p))
        keys = list(unique)
        labs = assign_labs([unique[k] for k in keys], lab, root)
        everything = list(dict.fromkeys([*self.entries, *keys]))
        names = dict(zip(everything, submission_names(everything), strict=True))
        fingerprints: dict[str | None, str] = {}
        planned = []
        for k, (graded_as, flags) in zip(keys, labs, strict=True):
            if graded_as not in fingerprints:
                fingerprints[graded_as] = grader_fingerprint(graded_as, root, timeout)
            item = Planned(
                k,
                unique[k],
                names[k],
                graded_as,
                flags,
                file_digest(unique[k]),
                fingerprints[graded_as],
            )
            old = self.entries.get(k)
            if (
                old
                and item.digest is not None
                and (old["digest"], old["grader"]) == (item.digest, item.grader)
            ):
                item.previous = SubmissionResult.from_dict(old["result"])
                item.previous.name, item.previous.path = item.name, item.path
                item.previous.flags = list(flags)
            planned.append(item)
        # earlier entries keep their rows under their (possibly new) names
        for k in self.entries:
            self.entries[k]["result"]["name"] = names[k]
        return planned

    def record(self, item: Planned, result: SubmissionResult) -> None:
        """Remember a finished result; a grader failure is shown but regraded next time."""
        self.entries[item.key] = {
            "given": os.fsdecode(item.path),
            "digest": None if result.fatal else item.digest,
            "grader": item.grader,
            "result": result.to_dict(),
        }
        self.save()

    def results(self) -> list[SubmissionResult]:
        """Every remembered result, by name."""
        found = [SubmissionResult.from_dict(e["result"]) for e in self.entries.values()]
        return sorted(found, key=lambda r: r.name)
