"""What a student reads of a refusal test and of a check's title (pytest_plugin).

A refusal test goes through the ``refuses`` fixture, so that a function that accepts
the bad input is told which input it was; a check's title is its docstring's whole
first paragraph, never a first line cut mid-sentence.
"""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap

import pytest

from robolab.grading.running.pytest_plugin import _refusing, title_of


def test_refusing_passes_on_the_error_and_names_the_input_otherwise():
    """The error (or a subclass) passes; returning normally fails naming the bad input."""
    with _refusing(ValueError, "sigma = -1"):
        raise ValueError("refused")
    with pytest.raises(pytest.fail.Exception, match=r"expected ValueError for sigma = -1, but"):
        with _refusing(ValueError, "sigma = -1"):
            pass
    with pytest.raises(KeyError):  # another error is not a refusal: it propagates
        with _refusing(ValueError, "sigma = -1"):
            raise KeyError("sigma")
    with pytest.raises(TypeError, match="names the input"):
        with _refusing(ValueError, " "):
            pass


def test_a_title_is_the_whole_first_paragraph():
    """Lines of the first paragraph join into one sentence; later paragraphs are not in it."""
    doc = """The path is the mean of the particles; the map their weighted
    mixture.

    Details the student does not need in the title.
    """
    assert title_of(doc) == "The path is the mean of the particles; the map their weighted mixture."
    assert title_of(None) == "" and title_of("  One line.  ") == "One line."


def test_the_report_names_the_input_and_the_whole_title(tmp_path):
    """Through pytest and the plugin: the failure names the input, the title is whole."""
    (tmp_path / "test_probe.py").write_text(
        textwrap.dedent(
            '''
            def test_refusal(refuses):
                """f refuses a negative sigma, the only bad input here; the title goes on
                over two lines.

                More words.
                """
                with refuses(ValueError, "sigma = -1 (a standard deviation must be > 0)"):
                    pass  # the function under test returned normally
            '''
        )
    )
    report = tmp_path / "report.json"
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "pytest",
            "-q",
            "-p",
            "robolab.grading.running.pytest_plugin",
            "-p",
            "no:cacheprovider",
            f"--grading-report={report}",
            str(tmp_path / "test_probe.py"),
        ],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 1, f"the probe must fail: {done.stdout[-2000:]}{done.stderr[-2000:]}"
    (test,) = json.loads(report.read_text())["tests"]
    assert test["description"] == (
        "f refuses a negative sigma, the only bad input here; the title goes on over two lines."
    ), test["description"]
    assert test["message"].startswith(
        "expected ValueError for sigma = -1 (a standard deviation must be > 0), but the "
        "function returned normally"
    ), test["message"]
