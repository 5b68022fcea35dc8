"""The similarity report: disguised copies rank above independent solutions, given code
counts for nothing, and nothing a notebook holds is run or injected into the page."""

from __future__ import annotations

import ast
import builtins
import csv
import json
from html.parser import HTMLParser
from pathlib import Path

import nbformat
import numpy as np
import pytest

from robolab.cli import main
from robolab.grading.course.similarity import compare, fragments
from robolab.grading.labs import EXERCISE_TAG
from tests.grading.running.test_runner import REPO

STUB = REPO / "notebooks" / "01_bayes.ipynb"
EXERCISES = ("bayes_posterior", "door_open_posterior", "bayes_filter_step")

# Two genuinely different correct implementations of the Bayes lab.
VECTORIZED = '''
import numpy as np


def _as_distribution(values, name):
    """Check a probability vector."""
    arr = np.asarray(values, dtype=float)
    if arr.ndim != 1 or np.any(arr < 0) or not np.isclose(arr.sum(), 1.0):
        raise ValueError(f"{name} must be a probability vector")
    return arr


def _normalized(weights):
    total = weights.sum()
    if total <= 0:
        raise ValueError("p(z) = 0: nothing to normalize")
    return weights / total


def bayes_posterior(likelihood, prior):
    prior = _as_distribution(prior, "prior")
    likelihood = np.asarray(likelihood, dtype=float)
    if likelihood.shape != prior.shape or np.any(likelihood < 0):
        raise ValueError("likelihood must be non-negative, shaped like prior")
    # Bayes' rule, then normalize by the evidence
    return _normalized(likelihood * prior)


def door_open_posterior(p_z_given_open, p_z_given_closed, p_open):
    for name, p in [("p_z_given_open", p_z_given_open), ("p_z_given_closed", p_z_given_closed),
                    ("p_open", p_open)]:
        if not 0 <= p <= 1:
            raise ValueError(f"{name} must be in [0, 1]")
    joint_open = p_z_given_open * p_open
    evidence = joint_open + p_z_given_closed * (1 - p_open)
    if evidence == 0:
        raise ValueError("p(z) = 0")
    return joint_open / evidence


def bayes_filter_step(belief, action_model, measurement_likelihood):
    belief = _as_distribution(belief, "belief")
    action_model = np.asarray(action_model, dtype=float)
    if action_model.shape != (belief.size, belief.size):
        raise ValueError("action_model must be n x n")
    if not np.allclose(action_model.sum(axis=0), 1.0):
        raise ValueError("every column of action_model must sum to 1")
    predicted = action_model @ belief  # prediction: sum over the previous state
    return bayes_posterior(measurement_likelihood, predicted)
'''

LOOPS = """
from fractions import Fraction


def bayes_posterior(likelihood, prior):
    if len(likelihood) != len(prior):
        raise ValueError("shapes differ")
    if any(p < 0 for p in prior) or abs(sum(prior) - 1) > 1e-9:
        raise ValueError("prior is not a distribution")
    if any(l < 0 for l in likelihood):
        raise ValueError("negative likelihood")
    unnormalized = []
    for l, p in zip(likelihood, prior):
        unnormalized.append(l * p)
    eta = sum(unnormalized)
    if eta == 0:
        raise ValueError("impossible measurement")
    import numpy
    return numpy.array([u / eta for u in unnormalized])


def door_open_posterior(p_z_given_open, p_z_given_closed, p_open):
    values = (p_z_given_open, p_z_given_closed, p_open)
    if min(values) < 0 or max(values) > 1:
        raise ValueError("probabilities must lie in [0, 1]")
    closed = 1 - p_open
    numerator = p_open * p_z_given_open
    denominator = numerator + closed * p_z_given_closed
    if not denominator:
        raise ValueError("the measurement cannot happen")
    return numerator / denominator


def bayes_filter_step(belief, action_model, measurement_likelihood):
    n = len(belief)
    rows = [list(r) for r in action_model]
    if len(rows) != n or any(len(r) != n for r in rows):
        raise ValueError("action model has the wrong shape")
    for j in range(n):
        if abs(sum(rows[i][j] for i in range(n)) - 1) > 1e-9:
            raise ValueError("columns must sum to one")
    bel_bar = [0.0] * n
    for i in range(n):
        for j in range(n):
            bel_bar[i] += rows[i][j] * belief[j]
    return bayes_posterior(measurement_likelihood, bel_bar)
"""


class _Rename(ast.NodeTransformer):
    """Every name the code binds (functions, arguments, locals) gets a new name."""

    def __init__(self, names):
        self.names = names

    def _new(self, name):
        return self.names.get(name, name)

    def visit_Name(self, node):
        node.id = self._new(node.id)
        return node

    def visit_arg(self, node):
        node.arg = self._new(node.arg)
        return node

    def visit_FunctionDef(self, node):
        node.name = self._new(node.name)
        self.generic_visit(node)
        return node


def disguise(code: str) -> str:
    """Renamed variables and helpers, functions in reverse order, other comments and
    docstrings, another layout; the exercise functions keep their names (the contract)."""
    tree = ast.parse(code)
    bound = {
        n.id for n in ast.walk(tree) if isinstance(n, ast.Name) and isinstance(n.ctx, ast.Store)
    }
    bound |= {a.arg for a in ast.walk(tree) if isinstance(a, ast.arg)}
    bound |= {f.name for f in ast.walk(tree) if isinstance(f, ast.FunctionDef)}
    bound -= set(EXERCISES) | set(dir(builtins))
    tree = _Rename({n: f"q{i}" for i, n in enumerate(sorted(bound))}).visit(tree)
    imports = [n for n in tree.body if not isinstance(n, ast.FunctionDef)]
    functions = [n for n in tree.body if isinstance(n, ast.FunctionDef)][::-1]
    for f in functions:  # drop docstrings
        if f.body and isinstance(f.body[0], ast.Expr) and isinstance(f.body[0].value, ast.Constant):
            f.body = f.body[1:] or [ast.Pass()]
    parts = [ast.unparse(n) for n in imports]
    for f in functions:
        parts.append(f"# my own version of {f.name}\n" + ast.unparse(f).replace("\n", "\n\n", 2))
    return "\n\n\n".join(parts)


def notebook(path: Path, code: str | None) -> Path:
    """The lab's stub notebook with ``code`` in place of its exercise cells (None: untouched)."""
    nb = nbformat.read(str(STUB), as_version=4)
    cells = [c for c in nb.cells if EXERCISE_TAG in c.get("metadata", {}).get("tags", [])]
    if code is not None:
        for c in cells:
            c.source = ""
        cells[-1].source = code
    nbformat.write(nb, str(path))
    return path


@pytest.fixture(scope="module")
def batch(tmp_path_factory):
    folder = tmp_path_factory.mktemp("subs")
    paths = [
        notebook(folder / "ann.ipynb", VECTORIZED),
        notebook(folder / "bob.ipynb", disguise(VECTORIZED)),
        notebook(folder / "cyd.ipynb", LOOPS),
        notebook(folder / "dee.ipynb", disguise(LOOPS)),
        notebook(folder / "eve.ipynb", None),
        notebook(folder / "fay.ipynb", None),
    ]
    for kind in ("correct", "wrong"):
        target = folder / f"example_{kind}.ipynb"
        target.write_bytes((REPO / "examples/submissions/bayes" / f"{kind}.ipynb").read_bytes())
        paths.append(target)
    return paths


def test_the_disguise_changes_the_text_but_not_the_logic():
    ns_a, ns_b = {}, {}
    exec(VECTORIZED, ns_a)  # our own test code, not a submission
    exec(disguise(VECTORIZED), ns_b)
    assert disguise(VECTORIZED) != VECTORIZED and "_normalized" not in disguise(VECTORIZED)
    assert "predicted" not in disguise(VECTORIZED) and "def q" in disguise(VECTORIZED)
    assert np.allclose(
        ns_a["bayes_posterior"]([0.6, 0.2], [0.5, 0.5]),
        ns_b["bayes_posterior"]([0.6, 0.2], [0.5, 0.5]),
    )
    assert ns_a["door_open_posterior"](2 / 3, 1 / 3, 3 / 5) == pytest.approx(0.75)
    assert ns_b["door_open_posterior"](2 / 3, 1 / 3, 3 / 5) == pytest.approx(0.75)
    push = [[1, 0.8], [0, 0.2]]
    assert np.allclose(
        ns_a["bayes_filter_step"]([0.5, 0.5], push, [0.6, 0.2]),
        ns_b["bayes_filter_step"]([0.5, 0.5], push, [0.6, 0.2]),
    )


def test_disguised_copies_rank_above_independent_solutions(batch):
    pairs = compare(fragments(batch))
    score = {(p.a, p.b, p.exercise): p.score for p in pairs}

    def s(a, b, exercise):
        return score.get((a, b, exercise), score.get((b, a, exercise)))

    copies = {("ann", "bob"), ("cyd", "dee")}
    for exercise in EXERCISES:
        ranked = [(p.a, p.b) for p in pairs if p.exercise == exercise]
        # the two disguised copies are the two closest pairs of every exercise
        assert set(ranked[:2]) == copies, (exercise, ranked[:4])
        for a, b in copies:
            assert s(a, b, exercise) >= 0.9, (a, b, exercise, s(a, b, exercise))
        independent = [s(x, y, exercise) for x in ("ann", "bob") for y in ("cyd", "dee")]
        assert max(independent) < 0.3
    assert all(0.0 <= p.score <= 1.0 for p in pairs)


def test_untouched_stubs_are_not_similar(batch):
    pairs = compare(fragments(batch))
    for p in pairs:
        if "eve" in (p.a, p.b) or "fay" in (p.a, p.b):
            assert p.score == 0.0, p


def test_command_writes_ranked_csv_and_a_safe_page(batch, tmp_path, capsys):
    evil = batch[0].with_name("x<script>alert(1)<-script>.ipynb")
    code = VECTORIZED.replace("# Bayes' rule", "# </pre><script>alert('pwned')</script>")
    notebook(evil, code)
    assert main(["similarity", *map(str, batch), str(evil), "--out", str(tmp_path / "sim")]) == 0
    with (tmp_path / "sim" / "similarity.csv").open(newline="") as f:
        rows = list(csv.DictReader(f))
    assert list(rows[0]) == ["a", "b", "exercise", "score"]
    scores = [float(r["score"]) for r in rows]
    assert scores == sorted(scores, reverse=True)
    n = len(batch) + 1
    assert len(rows) == len(EXERCISES) * n * (n - 1) // 2  # one row per pair and exercise
    page = (tmp_path / "sim" / "similarity.html").read_text()

    class Tags(HTMLParser):
        tags: list = []

        def handle_starttag(self, tag, attrs):
            self.tags.append(tag)

    parser = Tags()
    parser.feed(page)
    assert "script" not in parser.tags and "<mark>" in page
    assert "&lt;script&gt;alert(&#x27;pwned&#x27;)" in page
    assert "score 1.00" in page
    assert "similar" in capsys.readouterr().out


def test_no_student_code_runs(tmp_path):
    marker = tmp_path / "ran"
    code = VECTORIZED + f"\nopen({str(marker)!r}, 'w').write('x')\n"
    nb = notebook(tmp_path / "a.ipynb", code)
    nb2 = notebook(tmp_path / "b.ipynb", code.replace("if total", "if  total"))
    assert compare(fragments([nb, nb2]))
    assert not marker.exists()


def test_unreadable_and_labless_notebooks_are_skipped_with_a_word(tmp_path, capsys):
    (tmp_path / "bad.ipynb").write_text("{not json")
    plain = nbformat.v4.new_notebook()
    (tmp_path / "plain.ipynb").write_text(json.dumps(plain))
    ok = notebook(tmp_path / "ok.ipynb", VECTORIZED)
    found = fragments([tmp_path / "bad.ipynb", tmp_path / "plain.ipynb", ok])
    err = capsys.readouterr().err
    assert "skipped" in err and "bad.ipynb" in err and "names no known lab" in err
    assert {f.submission for f in found} == {"ok"}
