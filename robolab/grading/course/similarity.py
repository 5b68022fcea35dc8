"""How alike the submissions' exercise code is, exercise by exercise (``robolab similarity``).

Nothing here runs student code: notebooks are read as JSON, their cells turned into
Python text the way IPython would (:func:`~robolab.grading.loading.notebook.to_python`) and parsed.

For each submission and exercise the compared *fragment* is the exercise function (its
last definition, as a kernel would hold it) with the notebook's own helper functions it
calls, directly or through each other. The fragments are tokenized and fingerprinted by
`copydetect <https://github.com/blingenf/copydetect>`_: its tokenizer (pygments) turns
every variable and function name into one letter and drops comments and whitespace, so
renamed variables, changed comments and reformatting change nothing; its fingerprints
are k-grams of that token text, a set, so reordered functions change only the few
k-grams across their boundaries. Every fingerprint of the code each student was given
(all code cells of the lab's stub notebook: stubs, imports, check cells) is removed as
copydetect's *boilerplate*, so two untouched stubs share nothing.

copydetect compares files pair by pair in Python; here its fingerprints are put in one
sparse incidence matrix and all pairs of an exercise are counted in one product, which
is what lets hundreds of submissions be compared in seconds. The score of a pair is the
mean of the share of each fragment's fingerprints found in the other (in [0, 1]; 1 when
the fragments are the same up to names, comments and layout). copydetect itself then
marks the matching regions of the closest pairs for the HTML page.
"""

from __future__ import annotations

import ast
import functools
import io
import json
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from robolab.grading.course.batch import atomic_write, display_path, submission_names
from robolab.grading.course.spreadsheet import csv_text
from robolab.grading.loading.notebook import _read, _text, lab_exercises, to_python

__all__ = ["Fragment", "Pair", "compare", "fragments", "similarity_report"]

#: k-gram length in characters of tokenized code (copydetect's "noise threshold"): a
#: match shorter than about one statement is not counted.
K = 25
_NAME = "fragment.py"  # shown by copydetect; the lexer is named (a look-up by name is slow)


@dataclass
class Fragment:
    """One submission's code for one exercise, with its copydetect fingerprint."""

    submission: str
    lab: str
    exercise: str
    code: str  # as written (comments and all), shown on the page
    canonical: str  # as scored (see _fragment_code)
    fingerprint: object = field(repr=False, default=None)  # copydetect's, of ``canonical``


@dataclass(frozen=True)
class Pair:
    """The similarity of two submissions' fragments of one exercise."""

    a: str
    b: str
    lab: str
    exercise: str
    score: float


def _functions(nb: dict) -> tuple[dict[str, ast.FunctionDef], dict[str, str]]:
    """Every top-level function a kernel running the notebook would end with (last wins),
    and the Python text of the cell each comes from (for its source)."""
    found: dict[str, ast.FunctionDef] = {}
    source: dict[str, str] = {}
    for cell in nb.get("cells", []):
        if not isinstance(cell, dict) or cell.get("cell_type") != "code":
            continue
        python = to_python(_text(cell.get("source", "")))
        if not python:
            continue
        try:
            tree = ast.parse(python)
        except (SyntaxError, ValueError):  # not Python: nothing to compare
            continue
        for node in tree.body:
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                found[node.name] = node
                source[node.name] = python
    return found, source


def _reached(name: str, functions: dict, exercises: set[str]) -> list[str]:
    """The exercise function and the notebook's helpers it calls (not other exercises)."""
    seen, todo = [], [name]
    while todo:
        current = todo.pop()
        if current in seen or current not in functions:
            continue
        seen.append(current)
        called = {n.id for n in ast.walk(functions[current]) if isinstance(n, ast.Name)}
        todo += sorted(c for c in called if c in functions and c not in exercises)
    return seen


def _canonical(node: ast.FunctionDef) -> str:
    """The function as ``ast.unparse`` writes it, without its docstring: one layout, one
    kind of quotes, no comments, no redundant parentheses."""
    import copy

    node = copy.deepcopy(node)
    body = node.body
    if (
        body
        and isinstance(body[0], ast.Expr)
        and isinstance(body[0].value, ast.Constant)
        and isinstance(body[0].value.value, str)
    ):
        node.body = body[1:] or [ast.Pass()]
    return ast.unparse(node)


def _fragment_code(
    name: str, functions: dict, source: dict, exercises: set[str]
) -> tuple[str, str]:
    """The fragment as the student wrote it (for the page) and in canonical form (for the
    score): the exercise function, then its helpers ordered by their tokens, not their
    names or places, so that renaming or reordering them changes nothing."""
    from copydetect.utils import filter_code

    reached = _reached(name, functions, exercises)
    canonical = [_canonical(functions[f]) for f in reached]
    helpers = sorted(canonical[1:], key=lambda c: filter_code(c, _NAME, "python")[0])
    written = "\n\n".join(ast.get_source_segment(source[f], functions[f]) or "" for f in reached)
    return written, "\n\n".join(canonical[:1] + helpers)


def _given_code(nb: dict) -> str:
    """All code of the lab's stub notebook, as written and in canonical form."""
    cells = [
        to_python(_text(c.get("source", "")))
        for c in nb.get("cells", [])
        if isinstance(c, dict) and c.get("cell_type") == "code"
    ]
    functions, _ = _functions(nb)
    return "\n\n".join([c for c in cells if c] + [_canonical(f) for f in functions.values()])


def _fingerprint(code: str, boilerplate=None):
    from copydetect import CodeFingerprint

    # win_size=1 keeps every k-gram: the selection does not depend on Python's
    # per-process string hashes, so the scores are the same on every run
    return CodeFingerprint(
        _NAME, K, 1, boilerplate=boilerplate, language="python", fp=io.StringIO(code)
    )


@functools.lru_cache(maxsize=None)
def _boilerplate(lab: str, root: Path | None) -> np.ndarray:
    """The fingerprints of the code every student of ``lab`` was given."""
    from robolab.grading.labs import LabError, find_lab

    try:
        stub = find_lab(lab, root).notebook
        given = _given_code(json.loads(stub.read_text(encoding="utf-8"))) if stub else ""
    except (LabError, OSError, ValueError):
        given = ""
    return np.array(sorted(_fingerprint(given).hashes), dtype=np.int64)


def fragments(paths: Sequence[Path], root: Path | None = None) -> list[Fragment]:
    """The fingerprinted fragments of every submission and exercise of its lab.

    A notebook that cannot be read, or names no lab, is skipped with a warning on
    stderr; a missing exercise is an empty fragment (similar to nothing).
    """
    import sys

    names = submission_names(paths)
    found = []
    for path, name in zip(paths, names, strict=True):
        try:
            nb = _read(Path(path))
        except Exception as exc:  # noqa: BLE001 - any unreadable file is reported, not fatal
            print(f"robolab similarity: skipped {display_path(path)}: {exc}", file=sys.stderr)
            continue
        lab = (nb.get("metadata", {}).get("robolab") or {}).get("lab")
        exercises = lab_exercises(lab) if isinstance(lab, str) else ()
        if not exercises:
            print(
                f"robolab similarity: skipped {display_path(path)}: it names no known lab",
                file=sys.stderr,
            )
            continue
        functions, source = _functions(nb)
        for exercise in exercises:
            code, canonical = _fragment_code(exercise, functions, source, set(exercises))
            found.append(
                Fragment(
                    name,
                    lab,
                    exercise,
                    code,
                    canonical,
                    _fingerprint(canonical, _boilerplate(lab, root)),
                )
            )
    return found


def compare(found: Sequence[Fragment]) -> list[Pair]:
    """Every pair of submissions of a lab, per exercise, best first.

    The shared fingerprints of all pairs are counted at once: a sparse (fragments x
    fingerprints) 0/1 matrix times its transpose.
    """
    from scipy import sparse

    groups: dict[tuple[str, str], list[Fragment]] = {}
    for f in found:
        groups.setdefault((f.lab, f.exercise), []).append(f)
    pairs = []
    for (lab, exercise), group in groups.items():
        if len(group) < 2:
            continue
        hashes = [np.fromiter(f.fingerprint.hashes, dtype=np.int64) for f in group]
        sizes = np.array([len(h) for h in hashes], dtype=float)
        vocabulary, columns = np.unique(np.concatenate(hashes), return_inverse=True)
        rows = np.repeat(np.arange(len(group)), sizes.astype(int))
        m = sparse.csr_matrix(
            (np.ones(len(rows)), (rows, columns)), shape=(len(group), len(vocabulary))
        )
        shared = (m @ m.T).toarray()
        with np.errstate(divide="ignore", invalid="ignore"):
            share = np.where(sizes[:, None] > 0, shared / sizes[:, None], 0.0)
        score = (share + share.T) / 2
        i, j = np.triu_indices(len(group), k=1)
        pairs += [
            Pair(group[a].submission, group[b].submission, lab, exercise, float(s))
            for a, b, s in zip(i, j, np.round(score[i, j], 4), strict=True)
        ]
    return sorted(pairs, key=lambda p: (-p.score, p.exercise, p.a, p.b))


def _highlighted(code: str, slices) -> str:
    import html

    from copydetect.utils import highlight_overlap

    if not code.strip():
        return '<span class="muted">(nothing beyond the given code)</span>'
    if len(slices) == 0 or slices.shape[-1] == 0:
        return html.escape(code)
    marked, _ = highlight_overlap(code, slices, "<mark>", "</mark>", escape_html=True)
    return marked


def _page(pairs: Sequence[Pair], by_key: dict, root: Path | None, shown: int) -> str:
    import html

    from copydetect import compare_files

    top = [p for p in pairs if p.score > 0][:shown]
    parts = [
        "<!DOCTYPE html>",
        '<html lang="en"><head><meta charset="utf-8"><title>robolab similarity</title>',
        "<style>body{font-family:system-ui,sans-serif;margin:2em}"
        "table{border-collapse:collapse;width:100%;table-layout:fixed}"
        "td{vertical-align:top;border:1px solid #ccc;padding:.4em;width:50%}"
        "pre{white-space:pre-wrap;margin:0;font-size:.85em}mark{background:#ffd54f}"
        "h2{font-size:1.1em;margin-top:2em}.muted{color:#777}</style></head><body>",
        "<h1>Similar exercise code</h1>",
        f"<p>The {len(top)} closest pairs of {len(pairs)} (all are in similarity.csv). "
        "Highlighted: code both share once names, comments and layout are set aside; the "
        "code every student was given is not counted. A high score is a reason to look, "
        "not a verdict: short exercises have few ways to be written.</p>",
    ]
    for p in top:
        fa, fb = by_key[(p.a, p.exercise)], by_key[(p.b, p.exercise)]
        given = _boilerplate(p.lab, root)
        _, _, (slices_a, slices_b) = compare_files(
            _fingerprint(fa.code, given), _fingerprint(fb.code, given)
        )
        parts += [
            f"<h2>{html.escape(p.exercise)} ({html.escape(p.lab)}): score {p.score:.2f}</h2>",
            f"<table><tr><th>{html.escape(p.a)}</th><th>{html.escape(p.b)}</th></tr><tr>"
            f"<td><pre>{_highlighted(fa.code, slices_a)}</pre></td>"
            f"<td><pre>{_highlighted(fb.code, slices_b)}</pre></td></tr></table>",
        ]
    parts.append("</body></html>")
    return "\n".join(parts) + "\n"


def similarity_report(
    paths: Sequence[Path], out: Path, *, shown: int = 25, root: Path | None = None
) -> list[Pair]:
    """Write ``out/similarity.csv`` (``a,b,exercise,score``, best first) and
    ``out/similarity.html`` (the ``shown`` closest pairs side by side); return the pairs."""
    found = fragments(paths, root)
    pairs = compare(found)
    rows = [["a", "b", "exercise", "score"]]
    rows += [[p.a, p.b, p.exercise, f"{p.score:.4f}"] for p in pairs]
    Path(out).mkdir(parents=True, exist_ok=True)
    atomic_write(Path(out) / "similarity.csv", csv_text(rows))  # file names are student-given
    by_key = {(f.submission, f.exercise): f for f in found}
    atomic_write(Path(out) / "similarity.html", _page(pairs, by_key, root, shown))
    return pairs
