"""Grade fidelity: a correct notebook earns full marks whatever ordinary style it is written in.

Every variant of tests/grading/loading/fidelity_variants.py is first run by Jupyter
itself (nbclient; one kernel per lab, ``%reset -f`` between variants), which
proves that Jupyter accepts it and that its functions return the reference
solution's values; then it is graded through the real grading path
(:func:`robolab.grading.running.runner.grade_all`, as ``robolab grade -j 2``) and must
earn every point, with no load problem reported.

The sleeping scratch cell sleeps 45 s when graded (the grader must skip it:
the whole variant is graded well within that) and 0.2 s in Jupyter.

tests/grading/loading/fidelity_constructs.py adds one notebook per lab (every lab) whose
exercises are each bound in a style only running the notebook reveals; the test
classes below, one per construct, check each style on the exercise it was given.
"""

from __future__ import annotations

import time

import nbformat
import pytest

from robolab.grading.running.runner import grade_all
from tests.grading.loading.fidelity_constructs import (
    BRANCHES,
    CONSTRUCTS,
    DYNAMIC,
    FILES,
    LABS,
    MAIN,
    combinations,
)
from tests.grading.loading.fidelity_variants import LONG_SLEEP, PLAN, variants, wrong_variants

pytestmark = pytest.mark.slow

VARIANTS = variants()
#: One notebook per lab, each exercise bound in one of the constructs' styles.
COMBINATIONS = combinations()
BY_NAME = {v.name: v for v in VARIANTS + COMBINATIONS}
#: Run by Jupyter too: their visible checks fail there, and in `robolab check`.
WRONG = wrong_variants()

#: Calls whose values the Jupyter run compares with the reference solution, per lab.
CASES = {
    "demo": """[
    ("normalize", ([1.0, 3.0, 0.0],)),
    ("wrap", (np.array([4.0, -4.0, np.pi, 0.5, 7.0]),)),
    ("wrap", (3 * np.pi,)),
    ("mean_pose", (np.array([[0.0, 0.0, 3.0], [2.0, 1.0, -3.0]]),)),
]""",
    "bayes": """[
    ("bayes_posterior", (np.array([0.6, 0.2, 0.1]), np.array([0.2, 0.3, 0.5]))),
    ("door_open_posterior", (0.6, 0.3, 0.5)),
    ("bayes_filter_step", (np.array([0.5, 0.5]), np.array([[1.0, 0.8], [0.0, 0.2]]),
                           np.array([0.6, 0.2]))),
]""",
    "frames": """[
    ("scan_to_cartesian", (np.array([1.0, 2.0, 0.05, 9.0]), np.array([0.0, np.pi / 2, 1.0, 2.0]),
                           0.1, 5.0)),
    ("transform_points", (np.array([[1.0, 0.0], [0.0, 2.0]]), np.array([1.0, 2.0, np.pi / 2]))),
    ("pose_at", (np.array([0.0, 1.0, 2.0]),
                 np.array([[0.0, 0.0, 3.0], [1.0, 0.0, -3.0], [1.0, 1.0, 0.0]]),
                 np.array([0.25, 1.5]))),
]""",
}

ORACLE = """\
import numpy as _np
import importlib as _importlib
_ref = _importlib.import_module("solutions.{lab}")


def _same(got, want, where):
    if isinstance(want, (tuple, list)):
        assert len(got) == len(want), where
        for i, (g, w) in enumerate(zip(got, want)):
            _same(g, w, f"{{where}}[{{i}}]")
    elif isinstance(want, dict):
        assert got.keys() == want.keys(), where
        for k in want:
            _same(got[k], want[k], f"{{where}}[{{k!r}}]")
    else:
        _np.testing.assert_allclose(_np.asarray(got, dtype=float), _np.asarray(want, dtype=float),
                                    rtol=1e-12, atol=1e-12, err_msg=where)


np = _np
for _name in {names}:
    assert callable(globals().get(_name)), f"{{_name}} is not defined"
for _name, _args in {cases}:
    _same(globals()[_name](*_args), getattr(_ref, _name)(*_args), _name)
print("FIDELITY OK {name}")
"""


def test_the_suite_covers_enough_styles_and_labs():
    styles = {v.style for v in VARIANTS}
    assert len(styles) >= 25 and styles == set(PLAN)
    assert {v.lab for v in VARIANTS} >= {"demo", "bayes", "frames"}


def test_every_construct_style_is_given_to_an_exercise_in_every_lab():
    given = {style for combo in COMBINATIONS for style in combo.assignment.values()}
    every = {(group, name) for group, styles in CONSTRUCTS.items() for name in styles}
    assert given == every and len(every) >= 30
    assert {c.lab for c in COMBINATIONS} == set(LABS)
    for combo in COMBINATIONS:  # each lab's exercises all carry a style, constructs mixed
        assert len({group for group, _ in combo.assignment.values()}) >= min(
            3, len(combo.assignment)
        )


@pytest.fixture(scope="module")
def jupyter(tmp_path_factory) -> dict[str, tuple[bool, str]]:
    """Run every variant in Jupyter: ``{variant name: (accepted and correct, details)}``."""
    nbclient = pytest.importorskip("nbclient")
    verdicts: dict[str, tuple[bool, str]] = {}
    for lab in dict.fromkeys(v.lab for v in VARIANTS + COMBINATIONS):
        runs = [v for v in VARIANTS if v.lab == lab]
        runs = runs[:-1] + [v for v in WRONG if v.lab == lab] + runs[-1:]  # future last
        runs = [v for v in COMBINATIONS if v.lab == lab] + runs
        combined = nbformat.v4.new_notebook()
        combined.metadata["kernelspec"] = {"name": "python3", "display_name": "Python 3"}
        spans: dict[str, tuple[int, int]] = {}
        for variant in runs:
            start = len(combined.cells)
            combined.cells += variant.notebook(for_jupyter=True).cells
            combined.cells.append(
                nbformat.v4.new_code_cell(
                    ORACLE.format(
                        lab=lab,
                        cases=CASES.get(lab, "[]"),
                        names=sorted(getattr(variant, "assignment", None) or ()),
                        name=variant.name,
                    )
                )
            )
            spans[variant.name] = (start, len(combined.cells))
            combined.cells.append(
                nbformat.v4.new_code_cell(
                    "%reset -f\nimport matplotlib.pyplot\nmatplotlib.pyplot.close('all')"
                )
            )
        client = nbclient.NotebookClient(
            combined,
            timeout=900,
            kernel_name="python3",
            allow_errors=True,
            resources={"metadata": {"path": str(tmp_path_factory.mktemp(f"jupyter-{lab}"))}},
        )
        client.execute()
        for name, (start, end) in spans.items():
            verdicts[name] = _verdict(combined.cells[start:end], name)
    return verdicts


def _verdict(cells: list, name: str) -> tuple[bool, str]:
    problems = []
    for position, cell in enumerate(cells):
        if cell.cell_type != "code":
            continue
        errors = [o for o in cell.get("outputs", []) if o.get("output_type") == "error"]
        expected = "raises-exception" in cell.metadata.get("tags", [])
        if errors and not expected:
            problems.append(
                f"cell {position}: {errors[0].get('ename')}: {errors[0].get('evalue')}\n"
                f"{cell.source[:300]}"
            )
        if expected and not errors:
            problems.append(f"cell {position} was meant to raise and did not")
    text = "".join(
        o.get("text", "") for o in cells[-1].get("outputs", []) if o.get("output_type") == "stream"
    )
    if f"FIDELITY OK {name}" not in text:
        problems.append("the reference comparison did not pass")
    return not problems, "\n".join(problems)


@pytest.fixture(scope="module")
def graded(tmp_path_factory) -> dict[str, object]:
    """Grade every variant through the real grading path, two at a time."""
    folder = tmp_path_factory.mktemp("fidelity")
    paths = []
    for variant in BY_NAME.values():
        path = folder / f"{variant.name}.ipynb"
        nbformat.write(variant.notebook(), str(path))
        paths.append(path)
    broken = folder / "demo-broken-needed-cell.ipynb"
    nbformat.write(_broken_needed_cell(), str(broken))
    start = time.monotonic()
    results = grade_all([*paths, broken], jobs=2, progress=False)
    elapsed = time.monotonic() - start
    return {
        "elapsed": elapsed,
        "broken": results[-1],
        **{name: r for name, r in zip(BY_NAME, results[:-1], strict=True)},
    }


def _broken_needed_cell() -> nbformat.NotebookNode:
    """The plain demo notebook whose wrap cell starts with an import that fails."""
    nb = BY_NAME["demo-plain"].notebook()
    for cell in nb.cells:
        if cell.source.lstrip().startswith("from __future__") and "def wrap(" in cell.source:
            cell.source = "import no_such_module\n" + cell.source
    return nb


@pytest.mark.parametrize("name", list(BY_NAME))
def test_jupyter_accepts_the_variant_and_its_values_are_the_references(jupyter, name):
    ok, details = jupyter[name]
    assert ok, f"{name} in Jupyter:\n{details}"


@pytest.mark.parametrize("name", list(BY_NAME))
def test_the_variant_earns_full_marks(graded, name):
    result = graded[name]
    failing = [f"{t.nodeid}: {t.message[:300]}" for t in result.tests if not t.passed]
    assert not result.errors and not result.fatal, result.errors
    assert result.tests and result.total == result.max_points, (
        f"{name}: {result.total}/{result.max_points}\n" + "\n".join(failing)
    )
    assert result.problems == [], result.problems


def test_the_sleeping_scratch_cell_is_skipped(graded):
    sleepers = [v for v in VARIANTS if v.style == "scratch-sleep"]
    assert sleepers
    for variant in sleepers:
        # Its worker was awake (running or sleeping, not waiting for a CPU) for less than
        # the cell's sleep: the cell did not run, however loaded the machine.
        assert graded[variant.name].awake_seconds < LONG_SLEEP, (
            f"{variant.name}'s worker was awake {graded[variant.name].awake_seconds:.0f} s"
        )


@pytest.mark.parametrize("name", list(BY_NAME))
def test_robolab_check_passes_where_the_visible_checks_pass_in_jupyter(
    jupyter, tmp_path, capsys, name
):
    from robolab.grading.commands import check

    ok, details = jupyter[name]
    assert ok, details  # the visible-check cells ran in Jupyter without an error
    path = tmp_path / f"{name}.ipynb"
    nbformat.write(BY_NAME[name].notebook(), str(path))
    code = check(path)
    out = capsys.readouterr().out
    assert code == 0, out[-2000:]
    assert "note:" not in out, out[-2000:]


@pytest.mark.parametrize("variant", WRONG, ids=[v.name for v in WRONG])
def test_robolab_check_fails_where_the_visible_checks_fail_in_jupyter(
    jupyter, tmp_path, capsys, variant
):
    from robolab.grading.commands import check

    ok, details = jupyter[variant.name]
    assert not ok and "CheckFailed" in details, details
    path = tmp_path / f"{variant.name}.ipynb"
    nbformat.write(variant.notebook(), str(path))
    assert check(path) == 1
    assert "normalize" in capsys.readouterr().out


def test_feedback_names_a_failing_needed_cell_as_the_student_finds_it(graded):
    from robolab.grading.course.report import render_feedback

    result = graded["broken"]
    scores = result.exercise_scores()
    assert scores["wrap"][0] == 0 and scores["normalize"] == (scores["normalize"][1],) * 2
    position = 1 + next(
        i for i, c in enumerate(_broken_needed_cell().cells) if "no_such_module" in c.source
    )
    text = render_feedback(result)
    assert f"cell {position}, `import no_such_module`" in text, text
    assert "ModuleNotFoundError" in text


def _slots(group: str) -> list:
    """``(style, variant, exercise)`` of every exercise given a style of ``group``."""
    return [
        pytest.param(style, combo.name, f, id=f"{style}-{combo.lab}-{f}")
        for combo in COMBINATIONS
        for f, (g, style) in combo.assignment.items()
        if g == group
    ]


def pytest_generate_tests(metafunc):
    """Each construct's class is run for every exercise given one of its styles."""
    group = getattr(metafunc.cls, "CONSTRUCT", None)
    if group is not None:
        metafunc.parametrize("style, variant, exercise", _slots(group))


class _ConstructChecks:
    """For each exercise given a style of the construct: Jupyter holds a working function
    (its visible check passed there), and grading gives the exercise every point."""

    CONSTRUCT: str

    def test_the_exercise_earns_full_marks(self, jupyter, graded, style, variant, exercise):
        ok, details = jupyter[variant]
        assert ok, f"{variant} in Jupyter:\n{details}"
        result = graded[variant]
        earned, worth = result.exercise_scores()[exercise]
        failing = [f"{t.nodeid}: {t.message[:300]}" for t in result.tests if not t.passed]
        assert earned == worth, (
            f"{exercise}, bound with style {style!r}, earned {earned}/{worth}:\n"
            + "\n".join(f for f in failing if exercise in f)
            + f"\nload problems: {result.problems}"
        )


class TestBindingsInBranchesThatMayNotRun(_ConstructChecks):
    CONSTRUCT = BRANCHES


class TestTheNotebookRunsAsMain(_ConstructChecks):
    CONSTRUCT = MAIN


class TestBindingsNoAnalysisSees(_ConstructChecks):
    CONSTRUCT = DYNAMIC


class TestFilesTheNotebookWritesAndRuns(_ConstructChecks):
    CONSTRUCT = FILES
