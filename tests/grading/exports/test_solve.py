"""`robolab solve`: exercise cells get the reference code, everything else stays."""

from __future__ import annotations

import textwrap
from pathlib import Path

import nbformat
import numpy as np
import pytest

from robolab.cli import main
from robolab.grading.exports.solve import SolveError, solve_notebook, solve_paths
from robolab.grading.labs import Lab, exercise_cells
from solutions import demo

REPO = Path(__file__).resolve().parents[3]
DEMO_STUB = REPO / "examples" / "demo_lab" / "demo.ipynb"


def notebook(lab: str | None, *cells: tuple[str, bool]) -> nbformat.NotebookNode:
    nb = nbformat.v4.new_notebook()
    if lab:
        nb.metadata["robolab"] = {"lab": lab}
    for source, is_exercise in cells:
        cell = nbformat.v4.new_code_cell(textwrap.dedent(source))
        if is_exercise:
            cell.metadata["tags"] = ["exercise"]
        nb.cells.append(cell)
    return nb


@pytest.fixture(scope="module")
def solved_demo(tmp_path_factory) -> nbformat.NotebookNode:
    out = tmp_path_factory.mktemp("solved")
    (path,) = solve_paths([DEMO_STUB.parent], out)
    assert path == out / "demo.ipynb"
    return nbformat.read(str(path), as_version=4)


def test_exercise_cells_hold_the_solution_and_its_helpers(solved_demo):
    stub = nbformat.read(str(DEMO_STUB), as_version=4)
    cells = {funcs[0].name: solved_demo.cells[i].source for i, funcs in exercise_cells(stub)}
    assert list(cells) == ["normalize", "wrap", "mean_pose"]
    assert "raise NotImplementedError" not in "".join(cells.values())
    assert "from robolab.geometry import wrap_angle" in cells["wrap"]
    assert "def _circular_mean" in cells["mean_pose"] and "POSE_WIDTH = 3" in cells["mean_pose"]
    assert "#: Number of columns" in cells["mean_pose"]  # a constant keeps its comment
    assert "_circular_mean" not in cells["normalize"] and "POSE_WIDTH" not in cells["normalize"]
    # every other cell is untouched
    exercise_index = {i for i, _ in exercise_cells(stub)}
    for i, (a, b) in enumerate(zip(stub.cells, solved_demo.cells, strict=True)):
        if i not in exercise_index:
            assert a.source == b.source


def test_solved_functions_behave_like_the_solution(solved_demo):
    namespace: dict = {}
    for i, _ in exercise_cells(solved_demo):
        exec(compile(solved_demo.cells[i].source, f"cell{i}", "exec"), namespace)
    poses = np.array([[0.0, 1.0, 3.0], [2.0, 3.0, -3.0]])
    np.testing.assert_array_equal(namespace["mean_pose"](poses), demo.mean_pose(poses))
    np.testing.assert_array_equal(namespace["normalize"]([1.0, 3.0]), [0.25, 0.75])
    with pytest.raises(ValueError, match="weights"):
        namespace["normalize"]([-1.0, 2.0])


def test_outputs_are_cleared(tmp_path):
    nb = notebook(
        "demo", ("def wrap(angle):\n    raise NotImplementedError\n", True), ("print(1)", False)
    )
    nb.cells[1].outputs = [nbformat.v4.new_output("stream", text="1\n")]
    nb.cells[1].execution_count = 3
    solved = solve_notebook(nb, Lab("demo", REPO))
    assert all(c.outputs == [] and c.execution_count is None for c in solved.cells)
    assert nb.cells[1].outputs  # the input notebook is not modified


def test_transitive_helpers_and_constants(tmp_path):
    (tmp_path / "solutions").mkdir()
    (tmp_path / "solutions" / "toy.py").write_text(
        textwrap.dedent('''\
        """Toy lab."""
        import math

        SCALE = 2.0
        OFFSET = SCALE * 3
        _UNUSED = 1


        def _inner(x):
            return x * OFFSET


        def _outer(x):
            return _inner(x) + math.pi


        def f(x):
            return _outer(x) * SCALE


        def g(x):
            return f(x) + 1
        ''')
    )
    nb = notebook(
        "toy",
        ("def f(x):\n    raise NotImplementedError\n", True),
        ("def g(x):\n    raise NotImplementedError\n", True),
    )
    solved = solve_notebook(nb, Lab("toy", tmp_path))
    f_cell, g_cell = solved.cells[0].source, solved.cells[1].source
    assert (
        f_cell.index("import math")
        < f_cell.index("SCALE = 2.0")
        < f_cell.index("OFFSET = SCALE * 3")
        < f_cell.index("def _inner")
        < f_cell.index("def _outer")
        < f_cell.index("def f(x)")
    )
    assert "_UNUSED" not in f_cell
    assert "def f(" not in g_cell and "def g(x)" in g_cell  # f is defined by its own cell
    namespace: dict = {}
    exec(f_cell + "\n" + g_cell, namespace)
    assert namespace["g"](1.0) == pytest.approx((6.0 + np.pi) * 2.0 + 1)


def test_a_stub_without_solution_is_named(tmp_path):
    nb = notebook(
        "demo",
        (
            "def wrap(angle):\n    raise NotImplementedError\n\n"
            "def unwrap(angle):\n    raise NotImplementedError\n",
            True,
        ),
    )
    with pytest.raises(
        SolveError, match=r"exercise cell 0: unwrap: no such function in .*solutions/demo.py"
    ):
        solve_notebook(nb, Lab("demo", REPO))


def test_cli_reports_errors_and_writes_notebooks(tmp_path, capsys):
    bad = tmp_path / "in" / "nolab.ipynb"
    bad.parent.mkdir()
    nbformat.write(notebook(None, ("def f(x):\n    pass\n", True)), str(bad))
    assert main(["solve", str(bad), "-o", str(tmp_path / "out")]) == 2
    assert "no robolab.lab" in capsys.readouterr().err
    assert main(["solve", str(DEMO_STUB), "-o", str(tmp_path / "out")]) == 0
    assert (tmp_path / "out" / "demo.ipynb").is_file()
    assert main(["solve", str(tmp_path / "missing"), "-o", str(tmp_path / "out")]) == 2
