"""docs/instructor.md, run as written: every `$` command, in order, in a fresh folder.

A ```csv file=NAME``` block is written to NAME before the commands that follow it; the
other lines of a ```console``` block are output the command before them must print
(compared with runs of spaces collapsed). Then the files the page promises are checked.
"""

from __future__ import annotations

import csv
import json
import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
DOC = REPO / "docs" / "instructor.md"
BLOCK = re.compile(r"^```(\w+)([^\n]*)\n(.*?)^```$", re.S | re.M)

pytestmark = pytest.mark.slow


def steps(text: str) -> list[tuple[str, str, list[str]]]:
    """``("file", name, lines)`` and ``("run", command, expected lines)`` in document order."""
    found = []
    for kind, info, body in BLOCK.findall(text):
        if kind == "csv":
            name = re.search(r"file=(\S+)", info)
            assert name, f"a csv block needs file=NAME: {info!r}"
            found.append(("file", name.group(1), body.splitlines()))
        elif kind == "console":
            for line in body.splitlines():
                if line.startswith("$ "):
                    found.append(("run", line[2:], []))
                elif line.strip():
                    assert found and found[-1][0] == "run", f"output before a command: {line}"
                    found[-1][2].append(line)
    return found


def _squash(text: str) -> str:
    return " ".join(text.split())


def test_the_page_has_every_step():
    text = DOC.read_text()
    for heading in (
        "Set up",
        "Release",
        "Collect",
        "Grade",
        "Late",
        "overrides",
        "Regrade",
        "Export",
        "Gradescope",
        "nbval",
    ):
        assert re.search(rf"^## \d+\. .*{heading}", text, re.M | re.I), heading
    commands = [s[1] for s in steps(text) if s[0] == "run"]
    assert {shlex.split(c)[1] for c in commands if c.startswith("robolab")} >= {
        "release",
        "check",
        "grade",
        "gradescope",
    }


def test_every_command_of_the_page_runs(tmp_path):
    (tmp_path / "examples").symlink_to(REPO / "examples")
    (tmp_path / "tests").symlink_to(REPO / "tests")  # section 10 runs the hidden tests
    env = dict(os.environ, PATH=f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}")
    env.pop("ROBOLAB_ROOT", None)
    for kind, what, lines in steps(DOC.read_text()):
        if kind == "file":
            (tmp_path / what).write_text("\n".join(lines) + "\n")
            continue
        proc = subprocess.run(
            ["bash", "-c", what],
            cwd=tmp_path,
            env=env,
            capture_output=True,
            text=True,
            timeout=600,
        )
        assert proc.returncode == 0, f"$ {what}\n{proc.stdout}\n{proc.stderr}"
        printed = _squash(proc.stdout + proc.stderr)
        for line in lines:
            assert _squash(line) in printed, f"$ {what}\nexpected: {line}\n---\n{proc.stdout}"

    grades = tmp_path / "grades"
    rows = {r["submission"]: r for r in json.loads((grades / "gradebook.json").read_text())}
    assert set(rows) == {"ada_bayes", "alan_bayes", "grace_bayes", "mallory_bayes"}
    assert rows["alan_bayes"]["overrides"] and rows["alan_bayes"]["days_late"] == 2
    assert rows["alan_bayes"]["final"] == pytest.approx(rows["alan_bayes"]["total"] * 0.8)
    assert rows["mallory_bayes"]["flags"] and rows["mallory_bayes"]["total"] < 100
    canvas = list(csv.DictReader((grades / "canvas.csv").open()))
    assert list(canvas[0])[:5] == ["Student", "ID", "SIS User ID", "SIS Login ID", "Section"]
    assert [r["SIS User ID"] for r in canvas] == ["s001", "s002", "s003", "s004"]
    assert canvas[0]["Lab 01 Bayes"] == "100" and canvas[3]["Lab 01 Bayes"] == ""
    assert (grades / "moodle.csv").is_file() and (grades / "overrides.csv").is_file()
    assert {p.stem for p in (grades / "feedback").glob("*.md")} == set(rows)
    assert (tmp_path / "autograder.zip").is_file()
    assert (tmp_path / "dist" / "student" / "notebooks").is_dir()
    assert not (tmp_path / "dist" / "student" / "solutions").exists()
    for name, failures in (("ada.xml", 0), ("alan.xml", None)):  # section 10's JUnit reports
        suite = (tmp_path / name).read_text()
        assert "<testcase" in suite and ('failures="0"' in suite) == (failures == 0), name
