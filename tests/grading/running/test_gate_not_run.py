"""A gated test whose required tests already failed is not run (pytest_plugin's fail-fast gate).

An end-to-end hidden test (lab 05's global localization) can cost a minute on a
broken filter; when its required tests have failed it cannot pay, so the plugin
fails it at once instead of running it. Checked on a throwaway hidden-test module
run by a real pytest process.
"""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap


def test_a_gated_test_is_not_run_once_its_requirement_failed(tmp_path):
    """The gated test's body never runs, it fails naming what it waits for; others run.

    A requirement that failed with NotImplementedError (a stub) does not skip: the gated
    test runs and its feedback says "not implemented yet".
    """
    labs = tmp_path / "tests" / "labs"
    labs.mkdir(parents=True)
    ran = tmp_path / "ran"
    plugin = "robolab.grading.running.pytest_plugin"
    (tmp_path / "conftest.py").write_text(f'pytest_plugins = ["{plugin}"]\n')
    (labs / "test_x.py").write_text(
        textwrap.dedent(
            f"""
            import pathlib
            import pytest

            @pytest.mark.grades("f", points=1)
            def test_core():
                '''The core formula.'''
                assert False, "the core formula is wrong"

            @pytest.mark.grades("f", points=1)
            def test_other():
                '''Another part that works.'''
                pathlib.Path({str(ran)!r}).joinpath("other").write_text("ran")

            @pytest.mark.grades("f", points=3)
            @pytest.mark.requires("test_core")
            def test_end_to_end():
                '''The expensive run.'''
                pathlib.Path({str(ran)!r}).joinpath("e2e").write_text("ran")

            @pytest.mark.grades("f", points=1)
            def test_stub():
                '''Not written yet.'''
                raise NotImplementedError

            @pytest.mark.grades("f", points=1)
            @pytest.mark.requires("test_stub")
            def test_after_stub():
                '''Gated on a stub: runs (and meets the stub's NotImplementedError again).'''
                pathlib.Path({str(ran)!r}).joinpath("after_stub").write_text("ran")

            @pytest.mark.grades("f", points=1)
            @pytest.mark.requires("test_other")
            def test_refusal():
                '''Gated on a passing test: runs.'''
                pathlib.Path({str(ran)!r}).joinpath("refusal").write_text("ran")
            """
        )
    )
    ran.mkdir()
    report = tmp_path / "report.json"
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "pytest",
            "-q",
            "-p",
            "no:cacheprovider",
            "--rootdir",
            str(tmp_path),
            "-o",
            "addopts=",
            str(labs),
            "--grading-report",
            str(report),
        ],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=900,
    )
    records = {r["name"]: r for r in json.loads(report.read_text())["tests"]}
    assert not (ran / "e2e").exists(), (
        f"test_end_to_end requires the failed test_core, so its body must not run; pytest said "
        f"{proc.stdout[-800:]}"
    )
    assert (ran / "after_stub").exists(), (
        "a requirement that failed with NotImplementedError (a stub) must not skip the gated "
        f"test (its feedback says 'not implemented yet'); pytest said {proc.stdout[-800:]}"
    )
    assert (ran / "other").exists() and (ran / "refusal").exists(), (
        "tests whose requirements passed (or that have none) must run; "
        f"pytest said {proc.stdout[-800:]}"
    )
    e2e = records["test_end_to_end"]
    assert e2e["outcome"] == "failed" and "Not run" in e2e["message"], (
        f"the skipped gated test must fail with a 'Not run' message, got {e2e}"
    )
    assert '"The core formula."' in e2e["message"], (
        f"the message must name the failed requirement by its title, got {e2e['message']!r}"
    )
    assert records["test_refusal"]["outcome"] == "passed", (
        f"a gate whose requirement passed must not fail, got {records['test_refusal']}"
    )
