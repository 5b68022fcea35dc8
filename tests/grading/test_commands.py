"""`robolab grade` and `robolab check` end to end, through the isolated worker.

The demo lab's correct, partial and wrong submissions are graded together with
every hostile submission in examples/submissions/hostile/ (they attack
``normalize`` of the demo lab and implement the rest correctly).
"""

from __future__ import annotations

import ast
import csv
import json
import os
from pathlib import Path

import pytest

from robolab.cli import main
from robolab.grading.course.spreadsheet import safe_cell

pytest.importorskip(
    "robolab.grading.running.proxy", reason="the isolation layer (running.proxy) has not landed"
)

REPO = Path(__file__).resolve().parents[2]
DEMO = REPO / "examples" / "submissions" / "demo"
HOSTILE = sorted((REPO / "examples" / "submissions" / "hostile").glob("*.ipynb"))
FAIR = [DEMO / "correct.ipynb", DEMO / "partial.ipynb", DEMO / "wrong.ipynb"]
EXPECTED = {DEMO / "correct.ipynb": 100, DEMO / "partial.ipynb": 60, DEMO / "wrong.ipynb": 0}
#: The exercise a hostile notebook attacks when it is not ``normalize``.
ATTACKED = {"delegation_alias": "wrap"}
#: Hostile notebooks no step before grading can read: their row's reason.
UNREADABLE = {"deep_metadata": "nested too deeply"}


def _rows(out: Path) -> dict[Path, dict]:
    """Gradebook rows by submission path."""
    return {Path(r["path"]): r for r in json.loads((out / "gradebook.json").read_text())}


def _grade(tmp: Path, paths: list[Path], capsys) -> tuple[int, dict, str]:
    code = main(["grade", *map(str, paths), "--out", str(tmp), "-j", "2"])
    return code, _rows(tmp), capsys.readouterr().out


@pytest.fixture(scope="module")
def mixed(tmp_path_factory):
    """The fair submissions graded in one batch with every hostile one."""
    out = tmp_path_factory.mktemp("grades")
    code = main(["grade", *map(str, FAIR + HOSTILE), "--out", str(out), "-j", "2"])
    return code, out, _rows(out)


def _hidden_test_lines() -> set[str]:
    """Source lines of the demo lab's hidden tests (not docstrings: they name the checks)."""
    text = (REPO / "tests" / "labs" / "test_demo.py").read_text()
    tree = ast.parse(text)
    doc_lines = {
        n.lineno
        for n in ast.walk(tree)
        if isinstance(n, ast.Expr) and isinstance(n.value, ast.Constant)
    }
    lines = text.splitlines()
    return {
        lines[i].strip()
        for i in range(len(lines))
        if i + 1 not in doc_lines
        and len(lines[i].strip()) >= 12
        and not lines[i].strip().startswith("#")
    }


def test_batch_completes_with_exit_0(mixed):
    code, out, rows = mixed
    assert code == 0
    assert len(rows) == len(FAIR) + len(HOSTILE)
    assert (out / "gradebook.csv").is_file()
    assert len(list(csv.DictReader((out / "gradebook.csv").open()))) == len(rows)
    assert {p.stem for p in (out / "feedback").glob("*.md")} == {
        r["submission"] for r in rows.values()
    }


def test_fair_scores_unchanged_by_hostile_neighbours(mixed, tmp_path, capsys):
    _, _, rows = mixed
    assert {k: rows[k]["total"] for k in EXPECTED} == EXPECTED
    alone_code, alone, printed = _grade(tmp_path, FAIR, capsys)
    assert alone_code == 0
    for name in EXPECTED:
        assert alone[name]["exercises"] == rows[name]["exercises"]
    assert "partial" in printed and "60/100" in printed and "wrap 20/30, mean_pose 0/30" in printed


@pytest.mark.skipif(
    not HOSTILE, reason="no hostile submissions in examples/submissions/hostile yet"
)
@pytest.mark.parametrize("path", HOSTILE, ids=[p.stem for p in HOSTILE])
def test_hostile_submission_earns_nothing_on_what_it_attacks(mixed, path):
    _, _, rows = mixed
    row = rows[path]
    if path.stem in UNREADABLE:  # refused whole, in its own row: the batch went on
        assert row["total"] == 0 and UNREADABLE[path.stem] in "; ".join(row["errors"])
        return
    assert row["lab"] == "demo"
    attacked = ATTACKED.get(path.stem, "normalize")
    assert row["exercises"][attacked]["earned"] == 0
    for exercise in {"normalize", "wrap", "mean_pose"} - {attacked}:
        got = row["exercises"][exercise]
        assert got["earned"] == got["possible"] > 0, f"{path.stem}: {exercise} {got}"


def test_no_csv_cell_of_the_batch_is_a_spreadsheet_formula(mixed):
    _, out, _ = mixed
    for path in out.rglob("*.csv"):
        for row in csv.reader(path.open(encoding="utf-8", newline="")):
            assert all(safe_cell(c) == c for c in row), (path.name, row)  # none to neutralise


def test_feedback_never_quotes_hidden_tests(mixed):
    _, out, _ = mixed
    secret = _hidden_test_lines()
    assert any("pytest.mark.grades" in s for s in secret) and len(secret) > 30
    for md in (out / "feedback").glob("*.md"):
        text = md.read_text()
        leaked = [s for s in secret if s in text]
        assert not leaked, f"{md.name} quotes the hidden tests: {leaked[:3]}"


def test_feedback_explains_in_words(mixed):
    _, out, _ = mixed
    name = mixed[2][DEMO / "partial.ipynb"]["submission"]
    partial = (out / "feedback" / f"{name}.md").read_text()
    assert "both pi and -pi wrap to -pi" in partial and "expected -pi, got 3.14159" in partial
    assert "Not implemented yet: `mean_pose`" in partial


def test_unknown_lab_is_an_error(tmp_path, capsys):
    assert main(["grade", str(FAIR[0]), "--lab", "no_such_lab", "--out", str(tmp_path)]) == 2
    assert "no hidden tests" in capsys.readouterr().err


@pytest.mark.parametrize(
    "name, code, expected",
    [
        ("correct", 0, "visible checks passed"),
        ("partial", 1, "mean_pose is not implemented yet"),
        ("wrong", 1, "normalize([1, 3]): expected [0.25 0.75]"),
    ],
)
def test_check_reports_visible_checks_only(name, code, expected, capsys):
    assert main(["check", str(DEMO / f"{name}.ipynb")]) == code
    out = capsys.readouterr().out
    assert expected in out
    assert "all tests passed" not in out.lower()


def test_check_runs_the_numpy_kernels_and_leaves_the_backend_choice_as_it_was(monkeypatch):
    # The visible checks are small work: while checking, robolab.raycast's backend is numpy
    # (no numba import, no compilation into the student's cache); afterwards the process
    # chooses as before, and a backend the user chose is kept.
    from robolab import raycast
    from robolab.grading.commands import _numpy_kernels

    monkeypatch.delenv("ROBOLAB_RAYCAST", raising=False)
    before = raycast.default_backend()
    monkeypatch.setattr(raycast, "_JIT", False)  # not chosen yet, as in a fresh process
    with _numpy_kernels():
        assert raycast.default_backend() == "numpy"
    assert "ROBOLAB_RAYCAST" not in os.environ
    assert raycast.default_backend() == before
    monkeypatch.setenv("ROBOLAB_RAYCAST", "numba")
    with _numpy_kernels():
        assert os.environ["ROBOLAB_RAYCAST"] == "numba"
    assert os.environ["ROBOLAB_RAYCAST"] == "numba"
