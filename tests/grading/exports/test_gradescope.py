"""The Gradescope bundle: its layout, and its run_autograder on a sample submission."""

from __future__ import annotations

import json
import os
import shutil
import stat
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

import pytest

from robolab.cli import main
from robolab.grading.course.late import parse_time
from robolab.grading.exports.gradescope import (
    BundleOptions,
    build_bundle,
    find_submission,
    results_json,
)
from robolab.grading.running.runner import SubmissionResult, TestOutcome

REPO = Path(__file__).resolve().parents[3]
CORRECT = REPO / "examples" / "submissions" / "demo" / "correct.ipynb"


@pytest.fixture(scope="module")
def bundle(tmp_path_factory) -> Path:
    return build_bundle("demo", tmp_path_factory.mktemp("gs") / "autograder.zip")


@pytest.fixture
def autograder(bundle, tmp_path) -> Path:
    """The bundle laid out as Gradescope does: unpacked into source/, run_autograder copied up."""
    home = tmp_path / "autograder"
    with zipfile.ZipFile(bundle) as zf:
        zf.extractall(home / "source")
    shutil.copy(home / "source" / "run_autograder", home / "run_autograder")
    (home / "submission").mkdir()
    # In Gradescope, setup.sh installs robolab editable from source/, so the isolated worker
    # (`python -I -m robolab.grading.isolation.worker`) imports that same copy. Here the installed
    # robolab is the repository's, so point source/robolab at it: grader and worker must
    # agree on one robolab, whose folder is the only code the sandbox lets the worker read.
    assert (home / "source" / "robolab" / "grading" / "running" / "runner.py").is_file()
    shutil.rmtree(home / "source" / "robolab")
    (home / "source" / "robolab").symlink_to(REPO / "robolab")
    protect(home / "source")
    return home


def protect(source: Path) -> None:
    """What setup.sh does to the answers: readable by their owner only."""
    for top in (source / "solutions", source / "tests"):
        for path in [top, *top.rglob("*")]:
            path.chmod(0o700 if path.is_dir() else 0o600)


def run_autograder(home: Path) -> subprocess.CompletedProcess:
    env = dict(os.environ, ROBOLAB_AUTOGRADER_DIR=str(home), ROBOLAB_PYTHON=sys.executable)
    return subprocess.run(
        ["bash", str(home / "run_autograder")], env=env, capture_output=True, text=True, timeout=900
    )


def test_layout(bundle):
    with zipfile.ZipFile(bundle) as zf:
        names = set(zf.namelist())
        modes = {i.filename: i.external_attr >> 16 for i in zf.infolist()}
    for required in (
        "setup.sh",
        "run_autograder",
        "pyproject.toml",
        "README.md",
        "robolab/__init__.py",
        "robolab/grading/running/runner.py",
        "robolab/grading/running/proxy.py",
        "solutions/__init__.py",
        "solutions/demo.py",
        "tests/__init__.py",
        "tests/labs/__init__.py",
        "tests/labs/test_demo.py",
    ):
        assert required in names, required
    assert modes["run_autograder"] & stat.S_IXUSR and modes["setup.sh"] & stat.S_IXUSR
    # only this lab's answers and hidden tests travel
    assert {n for n in names if n.startswith(("solutions/", "tests/"))} == {
        "solutions/__init__.py",
        "solutions/demo.py",
        "tests/__init__.py",
        "tests/labs/__init__.py",
        "tests/labs/test_demo.py",
    }
    assert not any("__pycache__" in n or n.endswith(".pyc") for n in names)


def test_scripts_are_valid_bash(autograder):
    for script in ("setup.sh", "run_autograder"):
        proc = subprocess.run(
            ["bash", "-n", str(autograder / "source" / script)], capture_output=True, text=True
        )
        assert proc.returncode == 0, proc.stderr
    setup = (autograder / "source" / "setup.sh").read_text()
    assert "pip install" in setup and '-e "$SOURCE" "pytest' in setup


def test_run_autograder_grades_the_submission(autograder):
    shutil.copy(CORRECT, autograder / "submission" / "my_work.ipynb")
    # prove the bundle's own hidden tests run: make one test worth one point more inside the bundle
    tests = autograder / "source" / "tests" / "labs" / "test_demo.py"
    text = tests.read_text()
    tests.write_text(
        text.replace(
            '@pytest.mark.grades("wrap", points=10)', '@pytest.mark.grades("wrap", points=11)', 1
        )
    )
    proc = run_autograder(autograder)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    results = json.loads((autograder / "results" / "results.json").read_text())
    assert results["score"] == 101
    assert len(results["tests"]) == 11
    assert sum(t["max_score"] for t in results["tests"]) == 101
    assert all(t["score"] == t["max_score"] and t["status"] == "passed" for t in results["tests"])
    first = results["tests"][0]
    assert set(first) >= {"name", "score", "max_score", "output"}
    assert first["name"].startswith("normalize: ")
    assert "Score: **101 / 101**" in results["output"]


@pytest.mark.skipif(
    os.geteuid() != 0, reason="file modes protect the answers only from a root grader"
)
def test_run_autograder_refuses_when_the_answers_are_readable(autograder):
    # somewhere every uid can reach (pytest's tmp_path is under a 0700 folder)
    base = Path(tempfile.mkdtemp(dir="/tmp"))
    base.chmod(0o755)
    autograder = Path(shutil.copytree(autograder, base / "autograder", symlinks=True))
    shutil.copy(CORRECT, autograder / "submission" / "my_work.ipynb")
    (autograder / "source" / "solutions" / "demo.py").chmod(0o644)
    (autograder / "source" / "solutions").chmod(0o755)
    proc = run_autograder(autograder)
    assert proc.returncode != 0 and "refusing to grade" in proc.stderr
    results = json.loads((autograder / "results" / "results.json").read_text())
    assert results["score"] == 0 and results["tests"] == []
    assert "not set up safely" in results["output"]
    shutil.rmtree(base)


def test_run_autograder_without_a_notebook_scores_zero(autograder):
    proc = run_autograder(autograder)
    assert proc.returncode == 0, proc.stderr
    results = json.loads((autograder / "results" / "results.json").read_text())
    assert results["score"] == 0 and results["tests"] == []
    assert "no .ipynb notebook was submitted" in results["output"]


def test_find_submission_picks_the_lab_notebook(tmp_path):
    shutil.copy(CORRECT, tmp_path / "demo.ipynb")
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "scratch.ipynb").write_text(
        '{"cells": [], "metadata": {}, "nbformat": 4, "nbformat_minor": 5}'
    )
    assert find_submission(tmp_path, "demo") == tmp_path / "demo.ipynb"
    with pytest.raises(FileNotFoundError, match="several notebooks"):
        find_submission(tmp_path, "bayes")


def test_cli_refuses_an_unknown_lab(tmp_path, capsys):
    assert main(["gradescope", "--lab", "no_such_lab", "-o", str(tmp_path / "a.zip")]) == 2
    assert "no hidden tests" in capsys.readouterr().err
    assert not (tmp_path / "a.zip").exists()


def _result(message: str) -> SubmissionResult:
    def t(exercise, points, passed):
        return TestOutcome(
            f"tests/labs/test_demo.py::test_{exercise}_{points}",
            f"{exercise}: check {points}",
            exercise,
            points,
            "passed" if passed else "failed",
            "" if passed else message,
        )

    return SubmissionResult(
        path=Path("s.ipynb"),
        name="s",
        lab="demo",
        tests=[t("normalize", 40, True), t("wrap", 30, False), t("mean_pose", 30, False)],
    )


@pytest.mark.parametrize(
    "now, shows_wrap", [("2026-02-01T00:00:00Z", False), ("2026-04-01T00:00:00Z", True)]
)
def test_visibility_holds_back_details_until_the_due_date(now, shows_wrap):
    options = BundleOptions(visibility={"wrap": "after_due_date", "mean_pose": "hidden"})
    metadata = {"assignment": {"due_date": "2026-03-01T23:59:00+00:00"}}
    secret = "expected 0.123456, got 0.5"
    data = results_json(_result(secret), options, metadata, parse_time(now))
    by_name = {t["name"].split(":")[0]: t for t in data["tests"]}
    assert [by_name[e]["visibility"] for e in ("normalize", "wrap", "mean_pose")] == [
        "visible",
        "after_due_date",
        "hidden",
    ]
    assert (secret in by_name["wrap"]["output"]) is shows_wrap
    assert secret not in by_name["mean_pose"]["output"]  # hidden: never
    assert secret not in data["output"]  # the overall feedback shows visible checks only
    assert data["score"] == 40 and "60 more points" in data["output"]


def test_gradescope_output_cannot_be_formatted_by_the_submission():
    evil = "# Feedback\nScore: **100 / 100**\n```\n<script>alert(1)</script>"
    data = results_json(_result(evil), BundleOptions())
    assert all(t["output_format"] == "text" and t["name_format"] == "text" for t in data["tests"])
    assert data["output_format"] == "md"
    # in the Markdown feedback every copy of the message is inside a longer fence
    lines = data["output"].splitlines()
    assert not any(line.startswith("# Feedback") and line != lines[0] for line in lines)
    assert data["output"].count("Score: **") == 1 + data["output"].count("  Score: **100 / 100**")


def test_late_policy_from_submission_metadata():
    options = BundleOptions(late_penalty=25, late_cap=40)
    metadata = {
        "created_at": "2026-03-04T00:00:00+00:00",
        "assignment": {"due_date": "2026-03-01T23:59:00+00:00"},
        "users": [{"id": 7, "name": "Ada", "email": "ada@x.edu"}],
    }
    data = results_json(_result("x"), options, metadata)
    assert data["score"] == pytest.approx(40 * 0.6)  # 3 started days, capped at 40%
    assert data["extra_data"]["late"]["days_late"] == 3
    assert data["extra_data"]["students"] == [{"id": 7, "name": "Ada", "email": "ada@x.edu"}]
    # a user's own due date (an extension) wins over the assignment's
    metadata["users"][0]["assignment"] = {"due_date": "2026-03-05T00:00:00+00:00"}
    assert results_json(_result("x"), options, metadata)["score"] == 40


def test_gradescope_refuses_to_replace_a_file_that_is_not_a_bundle(tmp_path, capsys):
    # Issue 25: `-o keep.csv` silently replaced the instructor's file.
    keep = tmp_path / "keep.csv"
    keep.write_text("id,name\n")
    other_zip = tmp_path / "other.zip"
    with zipfile.ZipFile(other_zip, "w") as zf:
        zf.writestr("notes.txt", "mine")
    for path in (keep, other_zip):
        before = path.read_bytes()
        assert main(["gradescope", "--lab", "demo", "-o", str(path)]) == 2
        assert "not a Gradescope autograder bundle" in capsys.readouterr().err
        assert path.read_bytes() == before
    bundle = tmp_path / "autograder.zip"
    assert main(["gradescope", "--lab", "demo", "-o", str(bundle)]) == 0
    assert main(["gradescope", "--lab", "demo", "-o", str(bundle)]) == 0  # a bundle: rebuilt
