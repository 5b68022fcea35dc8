"""The mutation suite: every plausible mistake loses points on its own exercise.

Per lab, one batch is graded through the real grader (``robolab.grading.running.runner``,
two at a time): the solved notebook (must earn 100), the mutants packed into
notebooks (see ``build.py``: each must lose points on its own exercise), and two
"free points" notebooks, every exercise raising ValueError and every exercise
returning its first argument (both must earn 0, in every lab with a notebook).
"""

from __future__ import annotations

import functools
import importlib.util
import tempfile
from pathlib import Path

import nbformat
import pytest

from robolab.grading.labs import discover_labs, find_lab
from robolab.grading.loading.delegation import FORBIDDEN

from . import build

LABS = [lab for lab in discover_labs() if lab.notebook is not None and lab.hidden_tests.is_file()]
MUTANT_LABS = build.labs_with_mutants()
MUTANTS = [m for name in MUTANT_LABS for m in build.mutants_of(name)]
#: Every lab's mutation suite holds at least this many mistakes.
MIN_MUTANTS = 12
#: The classes of issue 15 each lab's suite must cover (those that apply to it).
APPLICABLE = {
    "frames": {"boundary", "refusal", "angle-wrap", "formula", "delegation"},
    "bayes": {
        "boundary",
        "refusal",
        "underflow",
        "degenerate-weights",
        "incoming-weights",
        "result-type",
        "formula",
    },
    "beam_model": {"boundary", "refusal", "underflow", "formula", "self-consistency"},
    "landmark_pf": {
        "refusal",
        "formula",
        "degenerate-weights",
        "incoming-weights",
        "angle-wrap",
        "reported-estimate",
        "delegation",
    },
    "demo": {"boundary", "refusal", "angle-wrap", "degenerate-weights", "delegation"},
    "odometry_mapping": {
        "boundary",
        "refusal",
        "underflow",
        "angle-wrap",
        "empty-map",
        "aliasing",
        "delegation",
    },
    "mcl": {
        "boundary",
        "refusal",
        "underflow",
        "degenerate-weights",
        "angle-wrap",
        "incoming-weights",
        "self-consistency",
        "empty-map",
        "delegation",
    },
    "ekf_mapping": {
        "boundary",
        "refusal",
        "angle-wrap",
        "empty-map",
        "jacobian-point",
        "aliasing",
        "delegation",
    },
    "graph_slam": {
        "refusal",
        "angle-wrap",
        "jacobian-point",
        "reported-estimate",
        "aliasing",
        "formula",
        "boundary",
        "delegation",
    },
    "fastslam": {
        "underflow",
        "degenerate-weights",
        "angle-wrap",
        "incoming-weights",
        "empty-map",
        "jacobian-point",
        "reported-estimate",
        "aliasing",
        "delegation",
    },
    "ekf_slam": {
        "refusal",
        "angle-wrap",
        "empty-map",
        "jacobian-point",
        "formula",
        "reported-estimate",
        "aliasing",
        "self-consistency",
        "delegation",
    },
}
#: Whether the worker observes argument changes and result aliasing (issue 14 item 5). Until
#: it does, arguments cross as copies and an in-place mistake cannot lose points.
OBSERVES_ARGUMENTS = importlib.util.find_spec("robolab.grading.wire.observe") is not None
#: Labs whose hidden tests do not yet refuse free points (their owner gates them next).
FREE_POINTS_PENDING: set[str] = set()


@functools.lru_cache(maxsize=None)
def graded(lab_name: str) -> dict:
    """Grade the lab's batch once: ``{"correct", "raises", "echo", "packs": [(group, result)]}``."""
    from robolab.grading.running.runner import grade_all

    lab = find_lab(lab_name)
    base = build.solved(lab)
    groups = build.packs(lab, build.mutants_of(lab_name))
    with tempfile.TemporaryDirectory(prefix=f"robolab-mutants-{lab_name}-") as tmp:
        folder = Path(tmp)
        notebooks = {
            "correct": base,
            "raises": build.free_points_variant(lab, "raises"),
            "echo": build.free_points_variant(lab, "echo"),
        }
        notebooks |= {
            f"pack{i:02d}": build.pack_notebook(lab, g, base) for i, g in enumerate(groups)
        }
        paths = []
        for key, nb in notebooks.items():
            path = folder / f"{key}.ipynb"
            nbformat.write(nb, str(path))
            paths.append(path)
        results = grade_all(paths, lab=lab_name, jobs=2, progress=False)
    by_key = dict(zip(notebooks, results, strict=True))
    return {
        "correct": by_key["correct"],
        "raises": by_key["raises"],
        "echo": by_key["echo"],
        "packs": [(g, by_key[f"pack{i:02d}"]) for i, g in enumerate(groups)],
    }


def _lost(result) -> list[str]:
    return [
        f"{t.description}: {t.outcome} {t.message[:300]!r}" for t in result.tests if not t.passed
    ]


@pytest.mark.parametrize("lab", MUTANT_LABS)
def test_the_catalogue_is_complete(lab):
    """Each lab's suite: enough mistakes on its exercises, its classes, and delegation."""
    mutants = build.mutants_of(lab)
    assert len(mutants) >= MIN_MUTANTS, (
        f"lab {lab}: expected at least {MIN_MUTANTS} mutants, got {len(mutants)}"
    )
    exercises = set(build.exercises(find_lab(lab)))
    strangers = [m.id for m in mutants if m.exercise not in exercises]
    assert not strangers, f"lab {lab}: mutants of functions that are not exercises: {strangers}"
    untouched = exercises - {m.exercise for m in mutants}
    assert not untouched, f"lab {lab}: exercises without any mutant: {sorted(untouched)}"
    missing = APPLICABLE.get(lab, set()) - {m.kind for m in mutants}
    assert not missing, f"lab {lab}: mistake classes with no mutant: {sorted(missing)}"
    delegated = {m.exercise for m in mutants if m.kind == "delegation"}
    undelegated = sorted(e for e, names in FORBIDDEN.get(lab, {}).items() if names)
    undelegated = [e for e in undelegated if e not in delegated]
    assert not undelegated, (
        f"lab {lab}: the library holds these exercises' answers (grading/loading/delegation.py) "
        f"but no delegating mutant shows that calling it loses the points: {undelegated}"
    )


@pytest.mark.parametrize("lab", MUTANT_LABS)
def test_mutants_differ_from_the_solution(lab):
    """A mutant's function is not the reference solution's function, statement for statement."""
    import ast

    from robolab.grading.exports.solve import SolutionSource

    source = SolutionSource.read(find_lab(lab).solution)
    for m in build.mutants_of(lab):
        _, ref = source.definitions[m.exercise]
        mine = next(n for n in ast.parse(m.source).body if isinstance(n, ast.FunctionDef))
        theirs = next(n for n in ast.parse(ref).body if isinstance(n, ast.FunctionDef))
        for node in (mine, theirs):  # docstrings differ by design
            if ast.get_docstring(node) is not None:
                node.body = node.body[1:]
        assert ast.dump(mine) != ast.dump(theirs), (
            f"mutant {m.id}: its {m.exercise} is the reference solution's code (no mistake)"
        )


@pytest.mark.parametrize("lab", MUTANT_LABS)
def test_the_solved_notebook_earns_full_marks(lab):
    """The notebook the mutants start from is correct: 100 of 100 through the grader."""
    result = graded(lab)["correct"]
    assert not result.errors, f"lab {lab}: grading the solved notebook failed: {result.errors}"
    assert result.total == result.max_points == pytest.approx(100), (
        f"lab {lab}: the solved notebook earned {result.total:g}/{result.max_points:g}; "
        f"lost: {_lost(result)}"
    )


@pytest.mark.parametrize("mutant", MUTANTS, ids=[m.id for m in MUTANTS])
def test_each_mutant_loses_points_on_its_own_exercise(mutant):
    """A notebook with this one mistake earns less than full marks on the exercise it breaks."""
    result = next(r for group, r in graded(mutant.lab)["packs"] if mutant in group)
    assert not result.errors, f"mutant {mutant.id}: grading failed: {result.errors}"
    earned, possible = result.exercise_scores()[mutant.exercise]
    if earned >= possible and mutant.kind == "aliasing" and not OBSERVES_ARGUMENTS:
        pytest.xfail("the worker does not observe argument changes yet (issue 14 item 5)")
    assert earned < possible, (
        f"mutant {mutant.id} ({build.CLASSES[mutant.kind]}: {mutant.mistake}) kept all "
        f"{possible:g} points of {mutant.exercise}: add the hidden test that catches its class"
    )


FREE_LABS = [lab.name for lab in LABS]


@pytest.mark.parametrize("kind", ["raises", "echo"])
@pytest.mark.parametrize("lab", FREE_LABS)
def test_free_points_notebooks_earn_nothing(lab, kind):
    """Exercises that only raise ValueError, or only return their first argument, earn 0."""
    if lab in FREE_POINTS_PENDING:
        pytest.xfail(f"lab {lab}: its hidden tests are not gated yet")
    result = graded(lab)[kind]
    assert not result.errors, f"lab {lab}, {kind}: grading failed: {result.errors}"
    kept = [f"{t.exercise}: {t.description} ({t.points:g})" for t in result.tests if t.passed]
    assert result.total == 0, (
        f"lab {lab}: a notebook whose every exercise {kind} earned {result.total:g} points, "
        f"expected 0; passing: {kept}"
    )


@pytest.mark.parametrize("lab", MUTANT_LABS)
def test_failures_caused_by_another_exercise_point_to_it(lab):
    """A correct exercise failing only because a function it uses is wrong says which one."""
    checked = 0
    for group, result in graded(lab)["packs"]:
        mutated = {m.exercise for m in group}
        for t in result.tests:
            if t.passed or t.exercise in mutated:
                continue
            # this exercise is the solution's own code: only a mutated one it calls can break it
            checked += 1
            named = [e for e in mutated if f"`{e}`" in t.message and "may be because" in t.message]
            assert named, (
                f"lab {lab}: {t.exercise} is correct but failed {t.description!r} because "
                f"{sorted(mutated)} are wrong; expected the feedback to point to them, got "
                f"{t.message[-400:]!r}"
            )
    if lab in ("beam_model", "landmark_pf"):
        assert checked, f"lab {lab}: expected some exercise to fail through a function it uses"
