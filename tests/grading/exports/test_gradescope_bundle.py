"""The Gradescope bundle as Gradescope runs it: setup.sh into a fresh venv, then run_autograder.

Nothing of the development venv is used: setup.sh creates ``/autograder/venv`` (here a
temporary tree of the same shape, per https://gradescope-autograders.readthedocs.io/en/latest/specs/:
``source/`` holds the unpacked zip, ``run_autograder`` is copied next to it, the harness puts
the student's files in ``submission/`` and ``submission_metadata.json`` beside them, and
``results/results.json`` is the output) with the base interpreter and installs robolab and
pytest from the bundle and PyPI. The venv is built once per session (about a minute and a
half with a warm pip cache), so the test is marked ``slow``.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

import pytest

from robolab.grading.exports.gradescope import VISIBILITIES, BundleOptions, build_bundle
from robolab.grading.isolation.sandbox import UID_BASE

pytestmark = pytest.mark.slow

REPO = Path(__file__).resolve().parents[3]
DEMO = REPO / "examples" / "submissions" / "demo"
HOSTILE = REPO / "examples" / "submissions" / "hostile"
OPTIONS = BundleOptions(
    visibility={"wrap": "after_due_date", "mean_pose": "hidden"}, late_penalty=10, late_cap=30
)
DUE = "2099-03-01T23:59:00-08:00"  # not yet passed: after_due_date stays hidden

#: The documented keys of results.json and of one test in it.
RESULT_KEYS = {
    "score",
    "execution_time",
    "output",
    "output_format",
    "test_output_format",
    "test_name_format",
    "visibility",
    "stdout_visibility",
    "extra_data",
    "tests",
    "leaderboard",
}
TEST_KEYS = {
    "score",
    "max_score",
    "status",
    "name",
    "name_format",
    "number",
    "output",
    "output_format",
    "tags",
    "visibility",
    "extra_data",
}
FORMATS = {"text", "html", "simple_format", "md", "ansi"}


def _clean_env(**extra) -> dict:
    env = {
        k: v for k, v in os.environ.items() if k not in ("VIRTUAL_ENV", "PYTHONPATH", "PYTHONHOME")
    }
    env["PATH"] = os.pathsep.join(
        p for p in env.get("PATH", "").split(os.pathsep) if not p.startswith(sys.prefix)
    )
    return env | extra


@pytest.fixture(scope="session")
def home():
    """An /autograder-shaped tree after Gradescope ran setup.sh in it."""
    if shutil.which("bash") is None:
        pytest.skip("needs bash")
    base = Path(tempfile.mkdtemp(prefix="robolab-gradescope-", dir="/tmp"))
    base.chmod(0o755)  # the worker's uid must be able to reach the venv, as in the container
    try:
        bundle = build_bundle("demo", base / "autograder.zip", options=OPTIONS)
        home = base / "autograder"
        with zipfile.ZipFile(bundle) as zf:
            zf.extractall(home / "source")
        for script in ("setup.sh", "run_autograder"):
            (home / "source" / script).chmod(0o755)
        shutil.copy(home / "source" / "run_autograder", home / "run_autograder")
        env = _clean_env(
            ROBOLAB_AUTOGRADER_DIR=str(home), ROBOLAB_SETUP_PYTHON=sys._base_executable
        )
        proc = subprocess.run(
            ["bash", str(home / "source" / "setup.sh")],
            env=env,
            capture_output=True,
            text=True,
            timeout=900,
            cwd=home,
        )
        assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
        assert "the autograder is ready" in proc.stdout
        yield home
    finally:
        shutil.rmtree(base, ignore_errors=True)


def grade(home: Path, notebook: Path, created_at: str) -> tuple[subprocess.CompletedProcess, dict]:
    for folder in ("submission", "results"):
        shutil.rmtree(home / folder, ignore_errors=True)
    (home / "submission").mkdir()
    shutil.copy(notebook, home / "submission" / notebook.name)
    metadata = {
        "id": 987654,
        "created_at": created_at,
        "assignment": {"due_date": DUE, "title": "Demo lab", "total_points": "100.0"},
        "users": [{"email": "ada@example.edu", "id": 4321, "name": "Ada Lovelace"}],
        "previous_submissions": [],
    }
    (home / "submission_metadata.json").write_text(json.dumps(metadata))
    proc = subprocess.run(
        ["bash", str(home / "run_autograder")],
        env=_clean_env(ROBOLAB_AUTOGRADER_DIR=str(home)),
        capture_output=True,
        text=True,
        timeout=900,
        cwd=home,
    )
    results = json.loads((home / "results" / "results.json").read_text())
    return proc, results


def validate(results: dict) -> None:
    """results.json as Gradescope documents it."""
    assert set(results) <= RESULT_KEYS, set(results) - RESULT_KEYS
    assert isinstance(results["score"], (int, float))
    assert results["output_format"] in FORMATS and results["visibility"] in VISIBILITIES
    assert results["stdout_visibility"] in VISIBILITIES
    assert isinstance(results["execution_time"], int)
    for t in results["tests"]:
        assert set(t) <= TEST_KEYS, set(t) - TEST_KEYS
        assert isinstance(t["name"], str) and t["name"]
        assert 0 <= t["score"] <= t["max_score"]
        assert t["status"] in ("passed", "failed") and t["visibility"] in VISIBILITIES
        assert t["output_format"] in FORMATS and isinstance(t["output"], str)
    assert sum(t["max_score"] for t in results["tests"]) == 100


def test_correct_submission_on_time_scores_100(home):
    proc, results = grade(home, DEMO / "correct.ipynb", "2099-03-01T20:00:00-08:00")
    assert proc.returncode == 0, proc.stderr
    validate(results)
    assert results["score"] == 100 and all(t["status"] == "passed" for t in results["tests"])
    assert results["extra_data"]["students"] == [
        {"id": 4321, "name": "Ada Lovelace", "email": "ada@example.edu"}
    ]
    assert results["extra_data"]["late"]["days_late"] == 0


def test_wrong_late_submission_hides_what_is_not_visible(home):
    proc, results = grade(home, DEMO / "partial.ipynb", "2099-03-03T08:00:00-08:00")
    assert proc.returncode == 0, proc.stderr
    validate(results)
    earned = sum(t["score"] for t in results["tests"])
    assert earned == 60
    # two started days late at 10% a day
    assert (
        results["score"] == pytest.approx(48)
        and "2 day(s) after the due date" in (results["output"])
    )
    by_visibility = {v: [t for t in results["tests"] if t["visibility"] == v] for v in VISIBILITIES}
    assert by_visibility["after_due_date"] and by_visibility["hidden"]
    for t in by_visibility["after_due_date"] + by_visibility["hidden"]:
        assert "expected" not in t["output"] and "got" not in t["output"]
    # the overall feedback only discusses visible checks
    assert "`wrap`" not in results["output"] and "`mean_pose`" not in results["output"]
    assert "points are graded by checks that are not shown here" in results["output"]


@pytest.mark.parametrize("attack", ["exec_solution", "read_tests", "import_solutions"])
def test_hostile_submission_wins_nothing(home, attack):
    proc, results = grade(home, HOSTILE / f"{attack}.ipynb", "2099-03-01T20:00:00-08:00")
    assert proc.returncode == 0, proc.stderr
    validate(results)
    normalize = [t for t in results["tests"] if t["name"].startswith("normalize")]
    assert normalize and all(t["score"] == 0 for t in normalize)
    solution = (REPO / "solutions" / "demo.py").read_text().splitlines()
    leaked = [s for s in solution if len(s.strip()) > 20 and s.strip() in json.dumps(results)]
    assert not leaked


@pytest.mark.skipif(os.geteuid() != 0, reason="only a root grader drops the worker's uid")
def test_answers_are_unreadable_by_a_worker_uid_without_any_sandbox(home):
    """Plain file modes, no namespace and no Landlock: what the worker's uid can read."""
    uid = UID_BASE + 4242
    source = home / "source"

    def readable(path: Path) -> bool:
        # /usr/bin/test, not Python: the base interpreter may live where other uids cannot go
        proc = subprocess.run(
            ["test", "-r", str(path)], user=uid, group=uid, extra_groups=[], timeout=30
        )
        return proc.returncode == 0

    assert not readable(source / "solutions" / "demo.py")
    assert not readable(source / "tests" / "labs" / "test_demo.py")
    assert readable(source / "robolab" / "__init__.py") and readable(source / "data")
    assert readable(home / "venv" / "bin" / "activate")
