"""`robolab` as a user runs it (a subprocess): every user error is one line and exit 2.

Each case is a mistake an instructor or a student makes: impossible limits, paths that
cannot be written, a notebook without checks, solving onto the stubs.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import nbformat
import pytest

REPO = Path(__file__).resolve().parents[2]
DEMO = REPO / "examples" / "submissions" / "demo"
STUB = REPO / "examples" / "demo_lab" / "demo.ipynb"


def robolab(*args, cwd: Path | None = None) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "robolab.cli", *map(str, args)],
        capture_output=True,
        text=True,
        timeout=900,
        cwd=cwd,
    )


def assert_user_error(proc: subprocess.CompletedProcess, *words: str) -> None:
    assert proc.returncode == 2, (proc.returncode, proc.stdout, proc.stderr)
    assert "Traceback" not in proc.stderr + proc.stdout
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("robolab: error: "), proc.stderr
    for word in words:
        assert word in lines[0], (word, lines[0])


@pytest.fixture
def blocker(tmp_path) -> Path:
    """A regular file, so that anything 'under' it cannot be created."""
    path = tmp_path / "a-file"
    path.write_text("x")
    return path


@pytest.mark.parametrize(
    "args, words",
    [
        (["--timeout", "-5"], ["--timeout", "positive"]),
        (["--timeout", "0"], ["--timeout", "positive"]),
        (["--timeout", "nan"], ["--timeout"]),
        (["--timeout", "soon"], ["--timeout"]),
        (["-j", "0"], ["--jobs", "at least 1"]),
        (["--lab", "no_such_lab"], ["no hidden tests"]),
        (["--export", "canvas"], ["--roster"]),
        (["--export", "blackboard"], ["--export"]),
        (["--late-penalty", "150", "--due", "2026-01-01"], ["--late-penalty"]),
        (["--late-penalty", "10"], ["--due"]),
        (["--due", "next friday"], ["ISO 8601"]),
    ],
)
def test_grade_refuses_impossible_options(tmp_path, args, words):
    proc = robolab("grade", DEMO / "correct.ipynb", "--out", tmp_path / "g", *args)
    assert_user_error(proc, *words)
    assert not (tmp_path / "g" / "gradebook.csv").exists()


def test_grade_refuses_bad_paths_before_grading(tmp_path, blocker):
    assert_user_error(robolab("grade", tmp_path / "missing.ipynb"), "no such notebook")
    assert_user_error(robolab("grade", DEMO / "correct.ipynb", "--out", blocker), "--out")
    assert_user_error(
        robolab("grade", DEMO / "correct.ipynb", "--out", blocker / "g"), "--out", "cannot"
    )
    assert_user_error(
        robolab("grade", DEMO / "correct.ipynb", "--roster", tmp_path / "none.csv"), "cannot read"
    )
    bad = tmp_path / "roster.csv"
    bad.write_text("id,name\ns1,Ada\n")
    assert_user_error(
        robolab("grade", DEMO / "correct.ipynb", "--roster", bad, "--out", tmp_path / "g"),
        "missing column",
    )


def _notebook(path: Path, lab: str | None) -> Path:
    nb = nbformat.v4.new_notebook()
    if lab is not None:
        nb.metadata["robolab"] = {"lab": lab}
    nb.cells = [nbformat.v4.new_code_cell("def f(x):\n    return x\n")]
    nbformat.write(nb, str(path))
    return path


@pytest.mark.parametrize("lab", ["base", "no_such_lab", "..", None])
def test_check_refuses_a_notebook_it_has_no_checks_for(tmp_path, lab):
    proc = robolab("check", _notebook(tmp_path / "nb.ipynb", lab))
    assert_user_error(proc)
    assert "passed" not in proc.stdout


def test_check_on_a_missing_file(tmp_path):
    assert_user_error(robolab("check", tmp_path / "nope.ipynb"), "cannot read")


def test_solve_to_a_file_writes_that_file(tmp_path):
    target = tmp_path / "solved.ipynb"
    proc = robolab("solve", STUB, "-o", target)
    assert proc.returncode == 0, proc.stderr
    assert target.is_file()
    nb = nbformat.read(str(target), as_version=4)
    assert nb.metadata["robolab"]["lab"] == "demo"
    assert "NotImplementedError" not in "".join(c.source for c in nb.cells if c.cell_type == "code")


def test_solve_never_writes_over_its_input_or_a_stub(tmp_path):
    stubs = tmp_path / "nbs"
    stubs.mkdir()
    shutil.copy(STUB, stubs / "demo.ipynb")
    before = (stubs / "demo.ipynb").read_bytes()
    assert_user_error(robolab("solve", stubs, "-o", stubs), "refusing")
    assert_user_error(
        robolab("solve", stubs / "demo.ipynb", "-o", stubs / "demo.ipynb"), "refusing"
    )
    other = tmp_path / "other.ipynb"
    shutil.copy(STUB, other)  # a stub notebook elsewhere is not overwritten either
    assert_user_error(robolab("solve", stubs / "demo.ipynb", "-o", other), "stub")
    assert (stubs / "demo.ipynb").read_bytes() == before
    assert_user_error(robolab("solve", STUB, "-o", REPO / "notebooks"), "refusing")


def test_outputs_that_cannot_be_written_are_one_line_errors(tmp_path, blocker):
    assert_user_error(robolab("solve", STUB, "-o", blocker / "out"), "-o")
    assert_user_error(robolab("solve", STUB, "-o", blocker / "x.ipynb"), "-o")
    assert_user_error(robolab("solve", STUB, "DEMO", "-o", tmp_path / "x.ipynb"))
    assert_user_error(robolab("release", blocker), "release")
    assert_user_error(robolab("release", blocker / "dist"), "release")
    assert_user_error(robolab("gradescope", "--lab", "demo", "-o", tmp_path), "folder")
    assert_user_error(robolab("gradescope", "--lab", "demo", "-o", blocker / "a.zip"), "-o")
    assert_user_error(
        robolab("gradescope", "--lab", "demo", "--visibility", "wrap=sometimes"), "--visibility"
    )
    assert_user_error(
        robolab(
            "gradescope", "--lab", "demo", "-o", tmp_path / "a.zip", "--visibility", "no=hidden"
        ),
        "does not grade",
    )
    assert not (tmp_path / "a.zip").exists()
    assert_user_error(robolab("data", "--out", blocker), "--out")
    assert_user_error(robolab("data", "--out", tmp_path / "d", "--only", "nonsense"), "unknown")


def test_argparse_errors_are_one_line_too(tmp_path):
    assert_user_error(robolab("grade"), "grade")
    assert_user_error(robolab("frobnicate"), "invalid choice")
    assert_user_error(robolab("solve", STUB), "-o")


def test_grade_refuses_a_broken_batch_state(tmp_path):
    out = tmp_path / "g"
    out.mkdir()
    (out / ".robolab-state.json").write_text(json.dumps({"format": 99}))
    assert_user_error(robolab("grade", DEMO / "correct.ipynb", "--out", out), "batch state")


@pytest.mark.skipif(os.geteuid() == 0, reason="root can write anywhere")
def test_unwritable_out_folder(tmp_path):
    locked = tmp_path / "locked"
    locked.mkdir(mode=0o500)
    assert_user_error(robolab("grade", DEMO / "correct.ipynb", "--out", locked), "--out")


def test_the_student_edition_offers_student_commands_and_names_what_the_others_need(tmp_path):
    """Without the answer key beside robolab, grade/solve/release/gradescope are not offered,
    and calling one says it needs the instructor's copy (not that pytest is missing)."""
    env = {**os.environ, "ROBOLAB_ROOT": str(tmp_path)}  # a root without solutions/ or tests/
    run = lambda *a: subprocess.run(  # noqa: E731
        [sys.executable, "-m", "robolab.cli", *a], capture_output=True, text=True, env=env,
        timeout=120,
    )
    listed = run("--help").stdout
    assert "check" in listed and "student edition" in listed
    for command in ("grade", "solve", "release", "gradescope"):
        assert f"    {command}" not in listed
        proc = run(command, "x.ipynb")
        assert_user_error(proc, command, "instructor's copy", "robolab check")
    assert "grade" in robolab("--help").stdout  # the instructor's copy offers everything
