"""Durable batches through `robolab grade`: validation first, rows as they finish, resume,
unique names, any file name, stale feedback, interruption, and lab spoofing.

Graded on a throw-away project root (ROBOLAB_ROOT) whose proxy runs notebooks in-process
(see test_runner.py), with the demo and bayes labs: these tests are about the batch, not
the isolation.
"""

from __future__ import annotations

import csv
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from robolab.cli import main
from robolab.grading.course.batch import STATE_FILE
from tests.grading.running.test_runner import REPO, SUBMISSIONS, make_root, write_notebook
from tests.grading.sigint import sigint_default

BAYES = REPO / "examples" / "submissions" / "bayes"


@pytest.fixture(scope="module")
def root(tmp_path_factory) -> Path:
    root = make_root(tmp_path_factory.mktemp("root"))
    for rel in ("solutions/bayes.py", "tests/labs/test_bayes.py"):
        shutil.copy(REPO / rel, root / rel)
    return root


@pytest.fixture(autouse=True)
def project(root, monkeypatch):
    monkeypatch.setenv("ROBOLAB_ROOT", str(root))
    return root


def grade(*args) -> int:
    return main(["grade", *map(os.fsdecode, args)])


def rows(out: Path) -> dict[str, dict]:
    return {r["submission"]: r for r in json.loads((out / "gradebook.json").read_text())}


def csv_rows(out: Path) -> list[dict]:
    with (out / "gradebook.csv").open(encoding="utf-8", newline="") as f:
        return list(csv.DictReader(f))


def copy(src: Path, dst: Path) -> Path:
    dst.parent.mkdir(parents=True, exist_ok=True)
    shutil.copy(src, dst)
    return dst


def test_unwritable_out_is_refused_before_grading(tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    code = grade(SUBMISSIONS / "correct.ipynb", "--out", blocker / "grades")
    printed = capsys.readouterr()
    assert code == 2 and printed.err.startswith("robolab: error: --out")
    assert printed.err.count("\n") == 1 and printed.out == ""  # nothing was graded
    assert grade(SUBMISSIONS / "correct.ipynb", "--out", blocker) == 2


def test_colliding_names_get_distinct_rows_and_feedback(tmp_path):
    subs = tmp_path / "subs"
    paths = [
        copy(SUBMISSIONS / "correct.ipynb", subs / "x" / "s.ipynb"),
        copy(SUBMISSIONS / "partial.ipynb", subs / "y" / "x" / "s.ipynb"),
        copy(SUBMISSIONS / "wrong.ipynb", subs / "x-s-2.ipynb"),
        copy(SUBMISSIONS / "partial.ipynb", subs / "x-s.ipynb"),
    ]
    out = tmp_path / "grades"
    assert grade(*paths, "--out", out, "-j", "2") == 0
    got = rows(out)
    assert len(got) == 4
    by_path = {r["path"]: r for r in got.values()}
    assert {os.fsdecode(p) for p in paths} == set(by_path)
    assert [r["path"] for r in csv_rows(out)] == [r["path"] for r in got.values()]
    assert by_path[str(paths[0])]["total"] == 100 and by_path[str(paths[1])]["total"] == 60
    assert {p.stem for p in (out / "feedback").glob("*.md")} == set(got)


def test_a_file_name_that_is_not_utf8_is_graded(tmp_path):
    folder = os.fsencode(tmp_path)
    weird = folder + b"/caf\xe9 # Feedback `x`.ipynb"
    with open(weird, "wb") as f:
        f.write((SUBMISSIONS / "correct.ipynb").read_bytes())
    broken = folder + b"/\xff\xfe broken.ipynb"
    with open(broken, "wb") as f:
        f.write(b"{not json")
    out = tmp_path / "grades"
    assert (
        grade(os.fsdecode(weird), os.fsdecode(broken), SUBMISSIONS / "wrong.ipynb", "--out", out)
        == 0
    )
    table = csv_rows(out)  # valid UTF-8
    assert len(table) == 3
    bad = next(r for r in table if "broken" in r["path"])
    assert "is not a notebook: not valid JSON" in bad["errors"] and "\\xff" in bad["errors"]
    json.loads((out / "gradebook.json").read_bytes().decode("utf-8"))
    row = next(r for r in table if "caf" in r["path"])
    assert row["total"] == "100" and "\\xe9" in row["path"]
    name = row["submission"]
    assert name.isascii() and "#" not in name and "`" not in name
    feedback = (out / "feedback" / f"{name}.md").read_text()
    assert feedback.count("\n# ") == 0 and feedback.startswith("# Feedback on `")


def test_repeated_run_regrades_only_what_changed(tmp_path, capsys, project):
    subs = tmp_path / "subs"
    a = copy(SUBMISSIONS / "correct.ipynb", subs / "a.ipynb")
    b = copy(SUBMISSIONS / "partial.ipynb", subs / "b.ipynb")
    out = tmp_path / "grades"
    assert grade(a, b, "--out", out) == 0
    first = json.loads((out / STATE_FILE).read_text())["entries"]
    capsys.readouterr()
    assert grade(a, b, "--out", out) == 0
    assert "2 unchanged submission(s) kept" in capsys.readouterr().out
    assert json.loads((out / STATE_FILE).read_text())["entries"] == first

    copy(SUBMISSIONS / "wrong.ipynb", b)  # b's content changes: only b is regraded
    assert grade(a, b, "--out", out) == 0
    assert "1 unchanged submission(s) kept" in capsys.readouterr().out
    assert rows(out)["b"]["total"] == 0 and rows(out)["a"]["total"] == 100
    assert "0 / 100" in (out / "feedback" / "b.md").read_text()

    # grading only a keeps b's row (rows are updated by submission, never dropped)
    assert grade(a, "--out", out) == 0
    assert set(rows(out)) == {"a", "b"}
    capsys.readouterr()

    # a new grader version (the hidden tests changed) regrades everything
    tests = project / "tests" / "labs" / "test_demo.py"
    saved = tests.read_text()
    try:
        tests.write_text(saved + "\n# a new version of the hidden tests\n")
        assert grade(a, b, "--out", out) == 0
        assert "unchanged" not in capsys.readouterr().out
    finally:
        tests.write_text(saved)


def test_no_stale_feedback_when_names_change(tmp_path):
    one = copy(SUBMISSIONS / "correct.ipynb", tmp_path / "d1" / "s.ipynb")
    two = copy(SUBMISSIONS / "wrong.ipynb", tmp_path / "d2" / "s.ipynb")
    out = tmp_path / "grades"
    assert grade(one, "--out", out) == 0
    assert [p.name for p in (out / "feedback").iterdir()] == ["s.md"]
    assert grade(one, two, "--out", out) == 0
    assert sorted(p.name for p in (out / "feedback").iterdir()) == ["d1-s.md", "d2-s.md"]
    assert set(rows(out)) == {"d1-s", "d2-s"}
    assert "100 / 100" in (out / "feedback" / "d1-s.md").read_text()
    assert "0 / 100" in (out / "feedback" / "d2-s.md").read_text()


def _hanging(path: Path) -> Path:
    return write_notebook(
        path,
        "demo",
        "import numpy as np\n"
        "def normalize(w):\n    while True:\n        pass\n"
        "def wrap(a):\n    while True:\n        pass\n",
    )




# Both signals take the same path (a stop request, robolab.grading.running.stopping), so
# the moments are spread over them rather than crossed with them.
@pytest.mark.parametrize(
    ("signals", "rows_before"),
    [
        # the batch is read; its workers start, the first submission is graded
        ((signal.SIGINT,), 0),
        ((signal.SIGTERM,), 1),  # between submissions
        # the hanging one runs (or is about to): it never ends by itself
        ((signal.SIGINT,), 2),
        ((signal.SIGTERM,), 2),
        ((signal.SIGINT, signal.SIGTERM), 2),  # a second signal: stop now
    ],
    ids=["int-started", "term-one-row", "int-hanging", "term-hanging", "int-term-hanging"],
)
def test_interrupt_leaves_a_valid_partial_gradebook_and_resumes(
    tmp_path, project, signals, rows_before
):
    subs = tmp_path / "subs"
    fast = [copy(SUBMISSIONS / n, subs / n) for n in ("correct.ipynb", "partial.ipynb")]
    hang = _hanging(subs / "zz_hangs.ipynb")
    out = tmp_path / "grades"
    cmd = [
        sys.executable,
        "-m",
        "robolab.cli",
        "grade",
        *map(str, [*fast, hang]),
        "--out",
        str(out),
    ]
    env = dict(os.environ, ROBOLAB_ROOT=str(project))
    with sigint_default():
        proc = subprocess.Popen(
            cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
        )
    # An event, not a sleep: the gradebook holds `rows_before` rows (it is written, with
    # none, once the batch is read). The bounds only catch a hang, at any load.
    deadline = time.monotonic() + 600
    while time.monotonic() < deadline and proc.poll() is None:
        if (out / "gradebook.json").is_file() and len(rows(out)) >= rows_before:
            break
        time.sleep(0.05)
    seen = set(rows(out))
    for sig in signals:
        proc.send_signal(sig)
        time.sleep(0.05)
    stdout, stderr = proc.communicate(timeout=600)
    assert proc.returncode == 130, stderr
    assert "Run the same command again" in stderr and "Traceback" not in stderr
    table = {r["submission"]: r["total"] for r in csv_rows(out)}
    assert seen <= set(table) == set(rows(out))  # what was written stays; csv and json agree
    assert table.items() <= {"correct": "100", "partial": "60"}.items()
    leftover = subprocess.run(
        ["pgrep", "-f", f"--notebook {subs}"], capture_output=True, text=True
    ).stdout
    assert not leftover.strip(), "a pytest run outlived the interrupted batch"
    # resume: the finished ones are kept, the rest is graded
    copy(SUBMISSIONS / "correct.ipynb", hang)
    done = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, done.stderr
    if table:
        assert f"{len(table)} unchanged submission(s) kept" in done.stdout
    else:
        assert "unchanged" not in done.stdout
    assert {n: r["total"] for n, r in rows(out).items()} == {
        "correct": 100,
        "partial": 60,
        "zz_hangs": 100,
    }


def test_a_notebook_of_another_lab_is_flagged_not_graded_as_its_claim(tmp_path, capsys):
    """A demo notebook renamed alice_bayes.ipynb in a bayes batch earns bayes points only."""
    subs = tmp_path / "subs"
    batch = [copy(BAYES / n, subs / n) for n in ("correct.ipynb", "partial.ipynb", "wrong.ipynb")]
    spoof = copy(SUBMISSIONS / "correct.ipynb", subs / "alice_bayes.ipynb")  # lab: demo
    quiet = copy(SUBMISSIONS / "correct.ipynb", subs / "bob.ipynb")  # no hint but the majority
    out = tmp_path / "grades"
    assert grade(*batch, spoof, quiet, "--out", out) == 0
    printed = capsys.readouterr().out
    got = rows(out)
    for name in ("alice_bayes", "bob"):
        assert got[name]["lab"] == "bayes" and got[name]["total"] < 100
        assert any("lab mismatch" in f and "'demo'" in f for f in got[name]["flags"])
    assert got["correct"]["total"] == 100 and not got["correct"]["flags"]
    assert "FLAGGED: 2 submission(s)" in printed and "alice_bayes" in printed.split("FLAGGED")[1]
    table = {r["submission"]: r for r in csv_rows(out)}
    assert "lab mismatch" in table["alice_bayes"]["flags"]


def test_lab_option_disagreeing_with_the_notebook_is_flagged(tmp_path, capsys):
    out = tmp_path / "grades"
    assert grade(SUBMISSIONS / "correct.ipynb", "--lab", "bayes", "--out", out) == 0
    row = rows(out)["correct"]
    assert row["lab"] == "bayes" and row["total"] == 0
    assert row["flags"] == [
        "lab mismatch: the notebook says lab 'demo' but --lab bayes was given; graded as 'bayes'"
    ]
    assert "FLAGGED: 1 submission(s)" in capsys.readouterr().out


def test_mixed_labs_named_by_their_folders_are_not_flagged(tmp_path):
    out = tmp_path / "grades"
    paths = [SUBMISSIONS / "correct.ipynb", BAYES / "correct.ipynb", BAYES / "wrong.ipynb"]
    assert grade(*paths, "--out", out) == 0
    got = rows(out)
    assert {n: (r["lab"], r["flags"]) for n, r in got.items()} == {
        "demo-correct": ("demo", []),
        "bayes-correct": ("bayes", []),
        "bayes-wrong": ("bayes", []),
    }
