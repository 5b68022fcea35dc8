"""The lab contract, for every lab present (see docs/architecture.md "Labs").

- the stub notebook's exercise functions have the solution's names and signatures;
- every hidden test carries a valid grades marker naming one of those exercises,
  every exercise is graded, and the points total 100;
- every hidden test fails on the unsolved (stub) notebook: one that passes is vacuous.
"""

from __future__ import annotations

import ast
import importlib
import inspect
import json
import os
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor

import nbformat
import pytest

from robolab.grading.labs import discover_labs, exercise_cells

LABS = discover_labs()
WITH_TESTS = [lab for lab in LABS if lab.hidden_tests.is_file()]
WITH_NOTEBOOK = [lab for lab in LABS if lab.notebook is not None]


def _ids(labs):
    return [lab.name for lab in labs]


def _stub_functions(lab) -> dict[str, ast.FunctionDef]:
    nb = nbformat.read(str(lab.notebook), as_version=4)
    funcs = {}
    for _, defs in exercise_cells(nb):
        for f in defs:
            assert f.name not in funcs, (
                f"{lab.notebook.name}: {f.name} is defined by two exercise cells"
            )
            funcs[f.name] = f
    assert funcs, f"{lab.notebook.name} has no exercise cell (a code cell tagged 'exercise')"
    return funcs


def _stub_parameters(func: ast.FunctionDef) -> list[tuple[str, str, str | None]]:
    """(name, kind, default source) per parameter, as inspect.Parameter would name the kind."""
    a = func.args
    positional = a.posonlyargs + a.args
    defaults = [None] * (len(positional) - len(a.defaults)) + [ast.unparse(d) for d in a.defaults]
    params = [
        (p.arg, "POSITIONAL_ONLY" if p in a.posonlyargs else "POSITIONAL_OR_KEYWORD", d)
        for p, d in zip(positional, defaults, strict=True)
    ]
    if a.vararg:
        params.append((a.vararg.arg, "VAR_POSITIONAL", None))
    params += [
        (p.arg, "KEYWORD_ONLY", None if d is None else ast.unparse(d))
        for p, d in zip(a.kwonlyargs, a.kw_defaults, strict=True)
    ]
    if a.kwarg:
        params.append((a.kwarg.arg, "VAR_KEYWORD", None))
    return params


def _solution_parameters(lab, name: str) -> list[tuple[str, str, str | None]]:
    module = importlib.import_module(f"solutions.{lab.name}")
    func = getattr(module, name, None)
    assert callable(func), (
        f"solutions/{lab.name}.py has no function {name} (the notebook has a stub for it)"
    )
    node = next(
        n for n in ast.parse(inspect.getsource(func)).body if isinstance(n, ast.FunctionDef)
    )
    by_ast = _stub_parameters(node)
    # the signature Python sees must be the one written in the source
    assert [(p.name, p.kind.name) for p in inspect.signature(func).parameters.values()] == [
        (n, k) for n, k, _ in by_ast
    ]
    return by_ast


@pytest.mark.parametrize("lab", WITH_NOTEBOOK, ids=_ids(WITH_NOTEBOOK))
def test_stubs_match_the_solution(lab):
    for name, stub in _stub_functions(lab).items():
        assert _stub_parameters(stub) == _solution_parameters(lab, name), (
            f"{lab.notebook.name}: the stub {name} and solutions/{lab.name}.py "
            "disagree on its signature"
        )


def _collect(root, paths, report) -> subprocess.CompletedProcess:
    """``pytest --collect-only`` of ``paths`` as the grader runs it, the report at ``report``."""
    return subprocess.run(
        [
            sys.executable,
            "-m",
            "pytest",
            *map(str, paths),
            "--collect-only",
            "-q",
            "-p",
            "robolab.grading.running.pytest_plugin",
            "-p",
            "no:cacheprovider",
            "--grading-report",
            str(report),
        ],
        cwd=root,
        capture_output=True,
        text=True,
        env={"PYTEST_DISABLE_PLUGIN_AUTOLOAD": "1", "PATH": "/usr/bin:/bin"},
    )


@pytest.fixture(scope="module")
def collected_together(tmp_path_factory) -> dict:
    """Every lab's hidden tests collected in one pytest run per project root (one start-up).

    ``{hidden test file: [test records]}``; the files of a root whose combined
    collection failed are left out: those labs are then collected one by one, so
    a broken lab fails alone and with its own message.
    """
    by_file: dict = {}
    roots = sorted({lab.root for lab in WITH_TESTS})
    for index, root in enumerate(roots):
        files = [lab.hidden_tests for lab in WITH_TESTS if lab.root == root]
        report = tmp_path_factory.mktemp("collected") / f"root{index}.json"
        proc = _collect(root, files, report)
        if proc.returncode != 0 or not report.is_file():
            continue
        for record in json.loads(report.read_text())["tests"]:
            path = (root / record["nodeid"].split("::", 1)[0]).resolve()
            by_file.setdefault(path, []).append(record)
    return by_file


def _collected(lab, tmp_path, together: dict) -> list[dict]:
    """The hidden tests of ``lab`` with exercise and points, as the grader collects them."""
    if lab.hidden_tests.resolve() in together:
        return together[lab.hidden_tests.resolve()]
    report = tmp_path / "collected.json"
    proc = _collect(lab.root, [lab.hidden_tests], report)
    assert proc.returncode == 0, (
        f"collecting {lab.hidden_tests.name} failed:\n{proc.stdout}{proc.stderr}"
    )
    return json.loads(report.read_text())["tests"]


@pytest.mark.parametrize("lab", WITH_TESTS, ids=_ids(WITH_TESTS))
def test_points_total_100_and_every_exercise_is_graded(lab, tmp_path, collected_together):
    tests = _collected(lab, tmp_path, collected_together)
    assert tests, f"{lab.hidden_tests.name} has no tests"
    total = sum(t["points"] for t in tests)
    assert total == pytest.approx(100), (
        f"lab {lab.name}: hidden tests total {total:g} points, not 100"
    )
    graded = {t["exercise"] for t in tests}
    if lab.notebook is not None:
        exercises = set(_stub_functions(lab))
        assert graded <= exercises, (
            f"grades markers name functions that are not exercises: {graded - exercises}"
        )
        assert exercises <= graded, f"exercises no hidden test grades: {sorted(exercises - graded)}"


@pytest.fixture(scope="module")
def stub_results() -> dict:
    """Every lab's stub notebook graded by its hidden tests, two at a time."""
    pytest.importorskip(
        "robolab.grading.running.proxy", reason="the isolation layer (running.proxy) has not landed"
    )
    from robolab.grading.running.runner import grade_submission

    graded = [lab for lab in WITH_NOTEBOOK if lab.hidden_tests.is_file()]
    with ThreadPoolExecutor(max_workers=2) as pool:
        results = pool.map(lambda lab: grade_submission(lab.notebook, lab=lab.name), graded)
        return {lab.name: r for lab, r in zip(graded, results, strict=True)}


@pytest.mark.parametrize("lab", WITH_NOTEBOOK, ids=_ids(WITH_NOTEBOOK))
def test_every_hidden_test_fails_on_the_stub_notebook(lab, stub_results):
    if lab.name not in stub_results:
        pytest.fail(f"lab {lab.name} has a notebook but no hidden tests ({lab.hidden_tests})")
    result = stub_results[lab.name]
    assert not result.errors, result.errors
    assert result.tests
    vacuous = [t.nodeid for t in result.tests if t.passed]
    assert not vacuous, (
        f"these hidden tests pass on the unsolved notebook, so they test nothing: {vacuous}"
    )


CHECKED = [lab for lab in WITH_NOTEBOOK if lab.name != "demo"]


@pytest.mark.parametrize("lab", CHECKED, ids=_ids(CHECKED))
def test_robolab_check_passes_solved_and_fails_stub(lab, tmp_path):
    # The student's command: on the solved notebook every visible check passes; on
    # the stub it says what is missing and exits non-zero, never claiming success.
    from robolab.grading.exports.solve import solve_paths

    (solved,) = solve_paths([lab.notebook], tmp_path)

    numba_cache = tmp_path / "numba-cache"
    env = dict(os.environ, NUMBA_CACHE_DIR=str(numba_cache))
    env.pop("ROBOLAB_RAYCAST", None)

    def check(path):
        return subprocess.run(
            [sys.executable, "-m", "robolab.cli", "check", str(path)],
            capture_output=True,
            text=True,
            timeout=300,
            env=env,
        )

    with ThreadPoolExecutor(max_workers=2) as pool:  # two processes: one per core
        good, bad = pool.map(check, [solved, lab.notebook])
    assert good.returncode == 0, good.stdout + good.stderr
    assert "visible checks passed" in good.stdout
    assert bad.returncode != 0
    assert "not implemented yet" in bad.stdout + bad.stderr
    assert "visible checks passed" not in bad.stdout
    # small work: a student's first check compiles no numba kernel (issue #28: it took minutes)
    assert not numba_cache.exists() or not any(numba_cache.rglob("*.nbi"))
