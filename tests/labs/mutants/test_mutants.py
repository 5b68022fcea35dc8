"""The mutation suite: every plausible mistake loses points on its own exercise.

Per lab, one batch is graded through the real grader (``robolab.grading.running.runner``,
two at a time): the solved notebook (must earn 100), the mutants packed into
notebooks (see ``build.py``: each must lose points on its own exercise), and the
"free points" notebooks (``build.FREE_POINTS``: every exercise raising ValueError,
returning its first argument, returning zeros of the right shape, or zeroing its
inputs in place and returning the first; each must earn 0, in every lab).
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
#: Classes every lab's suite covers, whatever its topic: each lab's hidden tests give its
#: exercises the smallest valid input (one pose, particle, beam, landmark, state).
EVERY_LAB = {"minimum-size"}
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
    """Grade the lab's batch once: ``{"correct", <each free-points kind>, "packs": [...]}``."""
    from robolab.grading.running.runner import grade_all

    lab = find_lab(lab_name)
    base = build.solved(lab)
    groups = build.packs(lab, build.mutants_of(lab_name))
    with tempfile.TemporaryDirectory(prefix=f"robolab-mutants-{lab_name}-") as tmp:
        folder = Path(tmp)
        notebooks = {
            "correct": base,
        } | {kind: build.free_points_variant(lab, kind) for kind in build.FREE_POINTS}
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
        **{kind: by_key[kind] for kind in build.FREE_POINTS},
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
    missing = (APPLICABLE.get(lab, set()) | EVERY_LAB) - {m.kind for m in mutants}
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


@pytest.mark.parametrize("kind", sorted(build.FREE_POINTS))
@pytest.mark.parametrize("lab", FREE_LABS)
def test_free_points_notebooks_earn_nothing(lab, kind):
    """Exercises that only raise, echo their input, return zeros or zero their inputs earn 0."""
    if lab in FREE_POINTS_PENDING:
        pytest.xfail(f"lab {lab}: its hidden tests are not gated yet")
    result = graded(lab)[kind]
    assert not result.errors, f"lab {lab}, {kind}: grading failed: {result.errors}"
    kept = [f"{t.exercise}: {t.description} ({t.points:g})" for t in result.tests if t.passed]
    assert result.total == 0, (
        f"lab {lab}: a notebook whose every exercise {build.FREE_POINTS[kind]} earned "
        f"{result.total:g} points, "
        f"expected 0; passing: {kept}"
    )


def collateral(lab: str) -> list[tuple[build.Mutant, float, float]]:
    """Per mutant: points lost on its own exercise, and points lost on every other exercise.

    Mutants of independent exercises share a notebook (``build.packs``), so each mutant
    is charged with *all* the points its notebook loses outside the exercises mutated in
    it: an upper bound on what the mutant alone would cost elsewhere.
    """
    rows = []
    for group, result in graded(lab)["packs"]:
        scores = result.exercise_scores()
        mutated = {m.exercise for m in group}
        elsewhere = sum(p - e for x, (e, p) in scores.items() if x not in mutated)
        for m in group:
            earned, possible = scores.get(m.exercise, (0.0, 0.0))
            rows.append((m, possible - earned, elsewhere))
    return sorted(rows, key=lambda row: row[0].name)


#: Issue 24 item 1: of single-mistake notebooks, at most one in this many loses any point
#: outside its own exercise, and they lose at most this many points there on average.
COLLATERAL_SHARE = 1 / 20
COLLATERAL_MEAN = 0.5


@pytest.mark.parametrize("lab", MUTANT_LABS)
def test_a_mistake_costs_once(lab):
    """A mistake loses points on its own exercise and (nearly) nowhere else.

    The exercises a graded exercise builds on answer as the reference while it is
    graded (robolab/grading/running/answers.py), so a correct exercise keeps its points next to
    a wrong one it calls. Bounds of issue 24, per lab (so they hold over all labs).
    """
    rows = collateral(lab)
    hit = [(m.id, lost) for m, _, lost in rows if lost > 0]
    mean = sum(lost for _, _, lost in rows) / len(rows)
    table = "\n".join(
        f"  {m.id}: {own:g} on {m.exercise}, {lost:g} elsewhere" for m, own, lost in rows
    )
    assert len(hit) <= COLLATERAL_SHARE * len(rows) and mean <= COLLATERAL_MEAN, (
        f"lab {lab}: {len(hit)} of {len(rows)} mutants lose points outside their own exercise "
        f"(at most {COLLATERAL_SHARE * len(rows):.2f} allowed), {mean:.2f} points on average "
        f"(at most {COLLATERAL_MEAN}); every mutant:\n{table}"
    )


@pytest.mark.parametrize("lab", MUTANT_LABS)
def test_mutants_call_the_solutions_helpers_as_they_are_defined(lab):
    """A mutant's calls of the solution's private helpers bind to their current signatures.

    A mutant written against an older helper fails with a TypeError in the helper call:
    it loses its points for that, not for its mistake, and its feedback blames nothing
    a student would write.
    """
    import ast
    import importlib
    import inspect

    module = importlib.import_module(f"solutions.{lab}")
    stale = []
    for path in sorted((build.HERE / lab).glob("*.py")):
        tree = ast.parse(path.read_text())
        imported = [
            alias
            for node in tree.body
            if isinstance(node, ast.ImportFrom) and node.module == f"solutions.{lab}"
            for alias in node.names
        ]
        stale += [
            f"{path.name}: imports {a.name}, which solutions/{lab}.py no longer defines"
            for a in imported
            if not hasattr(module, a.name)
        ]
        helpers = {alias.asname or alias.name for alias in imported}
        for call in ast.walk(tree):
            if not (isinstance(call, ast.Call) and isinstance(call.func, ast.Name)):
                continue
            if call.func.id not in helpers or not callable(getattr(module, call.func.id, None)):
                continue
            if any(isinstance(a, ast.Starred) for a in call.args) or any(
                k.arg is None for k in call.keywords
            ):
                continue
            try:
                inspect.signature(getattr(module, call.func.id)).bind(
                    *call.args, **{k.arg: k.value for k in call.keywords}
                )
            except TypeError as exc:
                stale.append(f"{path.name}:{call.lineno}: {ast.unparse(call)[:80]}: {exc}")
    assert not stale, f"lab {lab}: mutants call helpers that changed:\n  " + "\n  ".join(stale)


#: Failures that say the mutant's code is out of date with the solution, not its mistake.
STALE_SIGNS = ("NameError", "ImportError", "required positional argument", "unexpected keyword")


@pytest.mark.parametrize("mutant", MUTANTS, ids=[m.id for m in MUTANTS])
def test_each_mutant_fails_for_its_own_mistake(mutant):
    """No failure of the mutated exercise comes from a helper that no longer exists or fits.

    A mutant that dies on a renamed helper loses its points whatever its mistake, and the
    feedback a student would read for that mistake is never seen.
    """
    result = next(r for group, r in graded(mutant.lab)["packs"] if mutant in group)
    stale = [
        f"{t.description}: {t.message[:200]!r}"
        for t in result.tests
        if t.exercise == mutant.exercise and not t.passed
        if any(sign in t.message for sign in STALE_SIGNS)
    ]
    assert not stale, f"mutant {mutant.id} fails for another reason than its mistake: {stale}"


def main(labs: list[str]) -> None:
    """Print every mutant's collateral: ``python -m tests.labs.mutants.test_mutants [LAB ...]``."""
    print("| mutant | class | lost on its exercise | lost elsewhere |")
    print("|---|---|---|---|")
    for lab in labs or MUTANT_LABS:
        for m, own, lost in collateral(lab):
            print(f"| {m.id} | {m.kind} | {own:g} ({m.exercise}) | {lost:g} |")


if __name__ == "__main__":
    import sys

    main(sys.argv[1:])
