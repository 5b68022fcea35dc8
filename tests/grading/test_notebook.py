"""Loading a notebook: definitions kept, everything else dropped, broken cells recorded."""

from __future__ import annotations

import textwrap

import pytest

from robolab.grading.notebook import NotebookError, extract_definitions, load_notebook
from tests.grading import write_notebook


def kept_lines(source: str) -> list[str]:
    return [
        line for line in extract_definitions(textwrap.dedent(source)).splitlines() if line.strip()
    ]


def test_keeps_definitions_and_drops_everything_else():
    kept = kept_lines("""
        import numpy as np
        from math import pi as PI
        N = 10
        print("hello")
        plt.plot([1, 2])
        for i in range(3):
            x = i
        check_normalize(normalize)
        def normalize(w):
            # a comment inside stays
            return w / w.sum()
        class Filter:
            pass
        normalize([1, 2])
    """)
    assert kept == [
        "import numpy as np",
        "from math import pi as PI",
        "N = 10",
        "def normalize(w):",
        "    # a comment inside stays",
        "    return w / w.sum()",
        "class Filter:",
        "    pass",
    ]


@pytest.mark.parametrize(
    "statement",
    [
        "A = 1.5",
        "B = -2",
        "C = (1, 2.0, 'x')",
        "D = [1, [2, 3]]",
        "E = {'a': 1, 2: None}",
        "F = np.pi / 2",
        "G = 2 ** 10 + 1",
        "H: float = 0.5",
        "a, b = 1, 2",
        "S = {1, 2}",
        "T = True",
    ],
)
def test_constant_assignments_are_kept(statement):
    assert kept_lines(statement) == [statement]


@pytest.mark.parametrize(
    "statement",
    [
        "x = f()",
        "x = plt.plot(3)",
        "x = np.zeros(f())",
        "x = np.random.default_rng(0).random()",
        "x = [i for i in range(3)]",
        "obj.attr = 3",
        "d['k'] = 1",
        "x = lambda: 1",
        "x += 1",
        "x = {**other}",
        "x = (yield)",
        "if True:\n    def f(): pass",
        "with open('f') as fh:\n    y = 1",
        "assert False",
        "del x",
        "x = 'a'.upper()",
    ],
)
def test_non_constant_statements_are_dropped(statement):
    # Calls are dropped unless they are numpy/math functions of constants (see below).
    assert kept_lines(statement) == []


@pytest.mark.parametrize(
    "statement",
    ["SQRT_2PI = np.sqrt(2 * np.pi)", "ANGLES = np.deg2rad(np.arange(0, 360, 10))",
     "A = np.array([[1.0, 0.0], [0.0, 1.0]], dtype=float)", "L = math.log(2)"],
)
def test_numpy_and_math_functions_of_constants_are_kept(statement):
    assert kept_lines(statement) == [statement]


def test_decorators_are_kept_with_their_function():
    assert kept_lines("""
        @functools.lru_cache(maxsize=None)
        def f(x):
            return x
    """) == ["@functools.lru_cache(maxsize=None)", "def f(x):", "    return x"]


def test_magics_and_shell_lines_are_dropped_before_parsing():
    source = (
        "%matplotlib inline\n!pip install foo\nfiles = !ls\nt = %timeit f()\n"
        "def f():\n    return 1\n"
    )
    assert kept_lines(source) == ["def f():", "    return 1"]


def test_a_cell_magic_drops_the_whole_cell():
    assert extract_definitions("%%bash\necho hi\n") == ""
    assert extract_definitions("%%time\ndef f():\n    return 1\n") == ""


def test_a_syntax_error_raises():
    with pytest.raises(SyntaxError):
        extract_definitions("def f(:\n    pass\n")


def test_load_notebook(tmp_path):
    path = write_notebook(
        tmp_path / "sub.ipynb",
        "# md the story",
        "import numpy as np\nprint('setup')",
        "def normalize(w):\n    raise NotImplementedError",
        "check(normalize)",
        "def broken(:\n",
        "def normalize(w):\n    return np.asarray(w) / np.sum(w)\n",
        "def mean_pose(p):\n    return p\nX = 3",
        tags={2: ["exercise"], 6: ["exercise", "other"]},
    )
    nb = load_notebook(path)
    assert nb.path == path
    assert nb.lab == "demo"
    assert nb.functions == ["normalize", "mean_pose"]
    assert nb.exercise_cells == [2, 6]
    assert [(p.cell_index, p.kind) for p in nb.problems] == [(4, "syntax")]
    assert "invalid syntax" in nb.problems[0].message
    assert "print" not in nb.source and "check(" not in nb.source
    # The later definition of normalize wins, as when the notebook runs top to bottom.
    ns: dict = {}
    exec(nb.source, ns)
    assert ns["normalize"]([1.0, 3.0]).tolist() == [0.25, 0.75]
    assert ns["X"] == 3
    assert [index for index, _ in nb.cells] == [1, 2, 5, 6]


def test_assignments_reading_dropped_names_are_dropped_across_cells(tmp_path):
    # `belief = run(...)` is a call, so it is dropped; keeping `history = [belief]`
    # would only raise NameError while defining the notebook.
    path = write_notebook(
        tmp_path / "sub.ipynb",
        "import numpy as np\ndef run(b):\n    return b\nbelief = run(np.array([0.5, 0.5]))",
        "history = [belief]\nTAU = 2 * np.pi\nHALF = TAU / 2\nN = len",
        "def f():\n    return HALF",
    )
    nb = load_notebook(path)
    assert "history" not in nb.source and "belief" not in nb.source
    ns: dict = {}
    exec(nb.source, ns)
    assert ns["f"]() == pytest.approx(3.141592653589793)
    assert ns["N"] is len


def test_future_imports_head_the_joined_source(tmp_path):
    # Solved cells start with `from __future__ import annotations`; joined, they must
    # still compile as one module (robolab check executes the source in one piece).
    cell = (
        "from __future__ import annotations\nimport math\n"
        "def f{}(x: Later) -> float:\n    return math.pi\n"
    )
    path = write_notebook(tmp_path / "sub.ipynb", cell.format(1), cell.format(2))
    nb = load_notebook(path)
    assert nb.source.startswith("from __future__ import annotations\n")
    assert nb.source.count("__future__") == 1
    ns: dict = {}
    exec(compile(nb.source, "sub", "exec"), ns)
    assert ns["f2"](0) == pytest.approx(3.141592653589793)


def test_notebook_without_lab_metadata(tmp_path):
    nb = load_notebook(write_notebook(tmp_path / "n.ipynb", "def f():\n    return 1", lab=None))
    assert nb.lab is None
    assert nb.functions == ["f"]


def test_invalid_json_names_the_file(tmp_path):
    path = tmp_path / "broken.ipynb"
    path.write_text("{ not json")
    with pytest.raises(NotebookError, match="broken.ipynb.*not valid JSON"):
        load_notebook(path)


def test_json_that_is_not_a_notebook(tmp_path):
    path = tmp_path / "list.ipynb"
    path.write_text("[1, 2, 3]")
    with pytest.raises(NotebookError, match="list.ipynb.*is not a notebook"):
        load_notebook(path)


def test_missing_file(tmp_path):
    with pytest.raises(NotebookError, match="nope.ipynb.*cannot read"):
        load_notebook(tmp_path / "nope.ipynb")


def test_notebooks_written_by_nbformat_load(tmp_path):
    nbformat = pytest.importorskip("nbformat")
    nb = nbformat.v4.new_notebook()
    nb.metadata["robolab"] = {"lab": "demo"}
    nb.cells = [
        nbformat.v4.new_markdown_cell("# title"),
        nbformat.v4.new_code_cell("def f():\n    return 1\nf()"),
    ]
    path = tmp_path / "nbf.ipynb"
    nbformat.write(nb, path)
    loaded = load_notebook(path)
    assert (
        loaded.lab == "demo"
        and loaded.functions == ["f"]
        and loaded.cells == [(1, "def f():\n    return 1\n")]
    )


def test_old_notebook_format_is_refused(tmp_path):
    path = tmp_path / "v3.ipynb"
    path.write_text('{"nbformat": 3, "worksheets": [], "cells": []}')
    with pytest.raises(NotebookError, match="v3.ipynb.*format 4"):
        load_notebook(path)
