"""The runner and the hidden-test plugin, on a throw-away project root.

The root is a copy of robolab plus the demo lab, with ``robolab/grading/running/proxy.py``
replaced by an in-process test double: these tests exercise the pytest runs,
the report and the scoring, not the isolation (tests/grading/test_commands.py
grades through the real worker).
"""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import nbformat
import pytest

from robolab.grading.course.batch import submission_names
from robolab.grading.running.pytest_plugin import failure_message
from robolab.grading.running.runner import grade_all, grade_submission

REPO = Path(__file__).resolve().parents[3]
SUBMISSIONS = REPO / "examples" / "submissions" / "demo"

FAKE_PROXY = '''\
"""Test double of the isolated proxy: runs the notebook's definitions in this process."""
import types
from robolab.grading.loading.notebook import load_notebook

def Limits(**limits):
    return limits

def reference_limits(limits, reference_cpu_seconds):
    return limits

def open_submission(path, lab=None, *, limits=None, answers=None):
    loaded = load_notebook(path)
    namespace = {"__name__": "submission"}
    exec(compile(loaded.source, str(path), "exec"), namespace)
    proxy = types.SimpleNamespace(**{n: namespace[n] for n in loaded.functions if n in namespace})
    proxy.problems = loaded.problems
    proxy.close = lambda: None
    return proxy
'''


def make_root(path: Path) -> Path:
    """A project root with the demo lab whose ``lab`` fixture runs notebooks in-process."""
    ignore = shutil.ignore_patterns("__pycache__")
    shutil.copytree(REPO / "robolab", path / "robolab", ignore=ignore)
    (path / "robolab" / "grading" / "running" / "proxy.py").write_text(FAKE_PROXY)
    for rel in (
        "solutions/__init__.py",
        "solutions/demo.py",
        "tests/__init__.py",
        "tests/labs/__init__.py",
        "tests/labs/test_demo.py",
    ):
        (path / rel).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(REPO / rel, path / rel)
    return path


@pytest.fixture(scope="module")
def root(tmp_path_factory) -> Path:
    return make_root(tmp_path_factory.mktemp("root"))


def write_notebook(path: Path, lab: str | None, code: str) -> Path:
    nb = nbformat.v4.new_notebook()
    if lab:
        nb.metadata["robolab"] = {"lab": lab}
    nb.cells = [nbformat.v4.new_code_cell(textwrap.dedent(code))]
    nbformat.write(nb, str(path))
    return path


@pytest.fixture(scope="module")
def batch(root, tmp_path_factory):
    tmp = tmp_path_factory.mktemp("subs")
    paths = [
        SUBMISSIONS / "correct.ipynb",
        SUBMISSIONS / "partial.ipynb",
        SUBMISSIONS / "wrong.ipynb",
        write_notebook(tmp / "nolab.ipynb", None, "def wrap(a):\n    return a\n"),
        write_notebook(tmp / "otherlab.ipynb", "no_such_lab", "def wrap(a):\n    return a\n"),
    ]
    return grade_all(paths, root=root, jobs=2, progress=False)


def test_scores_follow_the_examples(batch):
    correct, partial, wrong = batch[:3]
    assert [r.name for r in batch[:3]] == [
        "correct",
        "partial",
        "wrong",
    ]  # input order kept under -j 2
    assert (correct.total, correct.max_points) == (100, 100)
    assert partial.exercise_scores() == {
        "normalize": (40, 40),
        "wrap": (20, 30),
        "mean_pose": (0, 30),
    }
    assert wrong.total == 0 and wrong.max_points == 100
    assert not any(r.errors for r in batch[:3])


def test_failure_messages_say_expected_and_got(batch):
    partial = batch[1]
    seam = next(t for t in partial.tests if t.nodeid.endswith("test_wrap_half_turn_is_minus_pi"))
    assert seam.outcome == "failed"
    assert "expected -pi, got 3.14159" in seam.message
    stub = next(t for t in partial.tests if t.exercise == "mean_pose")
    assert stub.message.startswith("NotImplementedError")
    assert all("def test_" not in t.message and "lab." not in t.message for t in partial.tests)


def test_notebook_without_lab_is_recorded_not_fatal(batch, root, tmp_path):
    nolab = batch[3]
    assert nolab.lab is None and not nolab.fatal and not nolab.tests
    assert "no robolab.lab" in nolab.errors[0]
    # --lab supplies what the metadata lacks
    named = grade_submission(SUBMISSIONS / "correct.ipynb", lab="demo", root=root)
    assert named.total == 100


def test_lab_without_hidden_tests_is_fatal(batch):
    other = batch[4]
    assert other.fatal and "no hidden tests" in other.errors[0]


def test_timeout_keeps_what_finished(root, tmp_path):
    code = (SUBMISSIONS / "correct.ipynb").read_text()
    nb = nbformat.reads(code, as_version=4)
    for cell in nb.cells:  # wrap() now hangs; the normalize tests run before it
        if cell.source.startswith("def wrap"):
            cell.source = "def wrap(angle):\n    while True:\n        pass\n"
    path = tmp_path / "hangs.ipynb"
    nbformat.write(nb, str(path))
    result = grade_submission(path, root=root, timeout=4)
    assert "timed out" in result.errors[-1] and not result.fatal
    assert result.exercise_scores()["normalize"] == (40, 40)
    assert result.total == 40
    assert result.limits == ["grading stopped at the batch's timeout of 4 s"]


def test_unmarked_hidden_test_stops_collection(root, tmp_path):
    bad_root = make_root(tmp_path / "bad")
    with (bad_root / "tests" / "labs" / "test_demo.py").open("a") as f:
        f.write("\n\ndef test_forgot_the_marker(lab):\n    assert lab.wrap(0.0) == 0.0\n")
    result = grade_submission(SUBMISSIONS / "correct.ipynb", root=bad_root)
    assert result.fatal and not result.tests


def _pytest(root: Path, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [
            sys.executable,
            "-m",
            "pytest",
            "-p",
            "robolab.grading.running.pytest_plugin",
            "-p",
            "no:cacheprovider",
            *args,
        ],
        cwd=root,
        capture_output=True,
        text=True,
        env={"PYTEST_DISABLE_PLUGIN_AUTOLOAD": "1", "PATH": "/usr/bin:/bin"},
    )


@pytest.mark.parametrize(
    "marker, complaint",
    [
        ("", "must be marked"),
        ('@pytest.mark.grades("wrap", points=0)', "points=N with N > 0"),
        ("@pytest.mark.grades(points=3)", "exercise's function name"),
        ('@pytest.mark.grades("wrap")', "points=N with N > 0"),
    ],
)
def test_grades_marker_is_validated(tmp_path, marker, complaint):
    (tmp_path / "tests" / "labs").mkdir(parents=True)
    (tmp_path / "tests" / "labs" / "test_x.py").write_text(
        f"import pytest\n\n{marker}\ndef test_a():\n    pass\n"
    )
    proc = _pytest(tmp_path, "tests/labs/test_x.py")
    assert proc.returncode == 4, proc.stdout + proc.stderr
    assert complaint in proc.stderr


def test_report_records_exercise_points_and_outcome(tmp_path):
    (tmp_path / "tests" / "labs").mkdir(parents=True)
    (tmp_path / "tests" / "labs" / "test_x.py").write_text(
        textwrap.dedent('''\
        import pytest

        @pytest.mark.grades("f", points=2.5)
        def test_ok():
            """f: works"""

        @pytest.mark.grades("f", points=1)
        def test_bad():
            secret_expected = 42
            assert 41 == secret_expected, "expected 42, got 41"
        ''')
    )
    proc = _pytest(tmp_path, "tests/labs/test_x.py", "--grading-report", "r.json")
    assert proc.returncode == 1
    report = json.loads((tmp_path / "r.json").read_text())
    ok, bad = report["tests"]
    assert (ok["exercise"], ok["points"], ok["outcome"], ok["description"]) == (
        "f",
        2.5,
        "passed",
        "f: works",
    )
    assert (bad["outcome"], bad["message"]) == ("failed", "AssertionError: expected 42, got 41")
    assert report["exitstatus"] == 1


def test_failure_message_prefers_the_student_traceback():
    class FakeStudentError(ValueError):
        kind, message = "ValueError", "weights must be positive"
        student_traceback = 'File "cell 3", line 4, in normalize'

    text = failure_message(FakeStudentError(), "ValueError: weights must be positive")
    assert text.startswith("ValueError: weights must be positive\n") and "cell 3" in text
    assert (
        failure_message(None, "AssertionError: expected 1\nassert 0 == 1\n +  where 0 = f()")
        == "AssertionError: expected 1"
    )
    assert len(failure_message(None, "x" * 10_000)) < 2100


def test_submission_names_come_from_the_relative_path():
    paths = [
        Path("a/correct.ipynb"),
        Path("b/correct.ipynb"),
        Path("b/wrong.ipynb"),
        Path("a/correct.ipynb"),
    ]
    assert submission_names(paths) == ["a-correct", "b-correct", "b-wrong", "a-correct"]
    # the collision: x/s, y/x/s and x-s-2 used to give two rows named x-s-2
    assert submission_names(["x/s.ipynb", "y/x/s.ipynb", "x-s-2.ipynb"]) == [
        "x-s",
        "y-x-s",
        "x-s-2",
    ]


@pytest.mark.parametrize(
    "paths",
    [
        ["x/s.ipynb", "x-s.ipynb", "x_s.ipynb", "x s.ipynb"],
        ["a/b/c.ipynb", "a-b/c.ipynb", "a/b-c.ipynb", "a-b-c.ipynb", "A-b-c.ipynb"],
        [b"caf\xe9.ipynb", "caf\u00e9.ipynb", "caf_.ipynb", "caf?.ipynb", "caf*.ipynb"],
        ["# Feedback.ipynb", "../up/one.ipynb", "-rf.ipynb", ".hidden.ipynb", "a\nb.ipynb"],
    ],
)
def test_submission_names_are_unique_safe_and_order_free(paths):
    names = submission_names(paths)
    assert len(set(names)) == len(paths)
    assert all(re.fullmatch(r"[\w][\w.-]*", n) and n.isprintable() for n in names), names
    assert all(len(n.encode()) <= 100 for n in names)
    # the same files in another order get the same names: a name depends on its path only
    shuffled = list(reversed(paths))
    assert dict(zip(map(str, shuffled), submission_names(shuffled), strict=True)) == dict(
        zip(map(str, paths), names, strict=True)
    )
