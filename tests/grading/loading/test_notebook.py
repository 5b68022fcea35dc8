"""Loading a notebook: the cells a kernel needs for the graded functions, whole and in order."""

from __future__ import annotations

import ast

import pytest

from robolab.grading.loading.kernel import load_budget, new_namespace, run_cells
from robolab.grading.loading.notebook import (
    NotebookError,
    cell_label,
    lab_exercises,
    load_notebook,
    to_python,
)
from tests.grading import write_notebook

#: Cells as students write them; each parses as Python or is IPython syntax.
CELLS = [
    "import numpy as np\nx = np.zeros(3)\n",
    "def wrap(a):\n    return ((a + np.pi)\n            % (2 * np.pi)) - np.pi\n",
    "ok = (1\n      != 2)\n",
    "%matplotlib inline\nimport matplotlib.pyplot as plt\n",
    "!pip install filterpy\nimport filterpy\n",
    "files = !ls\nprint(files)\n",
    "%time y = sum(range(10))\n",
    "   indented = 1\n",
    "np.array?\n",
    "%load_ext autoreload\n%autoreload 2\n",
    "x = 5 \\\n    % 3\n",
]


BUDGET = load_budget(60.0, 30.0)


def run(nb) -> dict:
    """The namespace of the notebook's needed cells, run as the worker runs them."""
    namespace = new_namespace("submission")
    problems = run_cells(namespace, nb.cells, *BUDGET)
    assert problems == []
    return namespace


@pytest.mark.parametrize("source", CELLS)
def test_cells_become_the_python_ipython_makes_of_them(source):
    from IPython.core.inputtransformer2 import TransformerManager

    expected = TransformerManager().transform_cell(source)
    got = to_python(source)
    # Plain Python is kept as written: IPython turns it into the same program.
    assert ast.dump(ast.parse(got)) == ast.dump(ast.parse(expected))


def test_a_continuation_line_starting_with_percent_is_not_a_magic():
    source = "def wrap(a):\n    return ((a + 3.0)\n% 6.0) - 3.0\n"
    assert to_python(source) == source
    assert "get_ipython" not in to_python(source)


@pytest.mark.parametrize(
    "source, runs",
    [
        ("%%time\ndef f():\n    return 1\n", True),
        ("%%capture\ndef f():\n    return 1\n", True),
        ("\n%%time\n%matplotlib inline\ndef f():\n    return 1\n", True),
        ("%%timeit\ndef f():\n    return 1\n", False),
        ("%%bash\necho def f\n", False),
        ("%%html\n<b>def f()</b>\n", False),
    ],
)
def test_cell_magics_that_run_python_become_their_body(source, runs):
    python = to_python(source)
    if not runs:
        assert python is None
        return
    namespace = new_namespace("submission")
    assert run_cells(namespace, [(0, python)], *BUDGET) == []
    assert namespace["f"]() == 1


def test_cells_are_named_as_a_student_finds_them():
    assert cell_label(11, "\n  def p_hit(z, z_star, z_max, sigma_hit, extra):\n") == (
        "cell 12, `def p_hit(z, z_star, z_max, sigma_hit, ...`"
    )
    assert cell_label(5, "from __future__ import annotations\nimport numpy") == (
        "cell 6, `from __future__ import annotations`"
    )
    assert cell_label(0, "x = 1") == "cell 1, `x = 1`"
    assert cell_label(3, "\n\n") == "cell 4 (empty)"


def test_only_the_cells_the_graded_functions_need_are_kept(tmp_path):
    path = write_notebook(
        tmp_path / "sub.ipynb",
        "# md the story",
        "import numpy as np\nfrom scipy.stats import norm",  # 1: needed (np, norm)
        "import time\ntime.sleep(45)",  # 2: a slow demo
        "HALF = norm(0, 1).cdf(0)\nsq = lambda v: v * v",  # 3: needed
        "raise RuntimeError('scratch')",  # 4
        "def broken(:\n",  # 5: scratch syntax error, defines nothing graded
        "N = 1",  # 6: needed, N += 1 reads it
        "N += 1\nfor _ in range(20000):\n    print(_)",  # 7: needed
        "def normalize(w):\n    return np.asarray(w) / np.sum(w) * HALF * 2",  # 8: replaced
        "def normalize(w):\n    return sq(np.asarray(w)) / np.sum(sq(np.asarray(w))) * N / 2",
        "print(normalize([1, 1]))",  # 10: a check
    )
    nb = load_notebook(path, graded=["normalize"])
    assert [index for index, _ in nb.cells] == [1, 3, 6, 7, 9]
    assert nb.problems == []
    ns = run(nb)
    assert ns["normalize"]([1.0, 3.0]).tolist() == [0.1, 0.9]


def test_a_top_level_read_needs_the_binding_before_the_cell(tmp_path):
    path = write_notebook(
        tmp_path / "sub.ipynb",
        "SCALE = 2",
        "TABLE = {k: SCALE * k for k in range(3)}",
        "SCALE = 100",  # later: TABLE was already computed with 2, f reads SCALE when called
        "def f(k):\n    return TABLE[k] + SCALE",
        lab=None,
    )
    nb = load_notebook(path)
    assert [index for index, _ in nb.cells] == [0, 1, 2, 3]
    assert run(nb)["f"](2) == 104


def test_a_value_changed_in_place_keeps_its_cell(tmp_path):
    path = write_notebook(
        tmp_path / "sub.ipynb",
        "PARAMS = {'a': 1}",
        "PARAMS['a'] = 5",
        "class Box:\n    pass\nBOX = Box()",
        "BOX.value = 7",
        "def f():\n    return PARAMS['a'] + BOX.value",
        lab=None,
    )
    nb = load_notebook(path)
    assert len(nb.cells) == 5
    assert run(nb)["f"]() == 12


def test_decorators_defaults_classes_and_globals(tmp_path):
    path = write_notebook(
        tmp_path / "sub.ipynb",
        "import functools\nDEFAULT = 3",
        "def twice(fn):\n    return lambda *a: 2 * fn(*a)",
        "def setup():\n    global OFFSET\n    OFFSET = 10",
        "setup()",
        "class Model:\n    BASE = DEFAULT\n    def value(self):\n        return self.BASE + OFFSET",
        "@twice\ndef f(x=DEFAULT):\n    return x + Model().value() + add1(0)",
        "add1 = functools.partial(lambda a, b: a + b, 1)",
        "plot = 1",  # a demo
        lab=None,
    )
    nb = load_notebook(path, graded=["f"])
    assert [index for index, _ in nb.cells] == [0, 1, 2, 3, 4, 5, 6]
    assert run(nb)["f"]() == 2 * (3 + 13 + 1)


def test_star_imports_are_always_kept(tmp_path):
    path = write_notebook(
        tmp_path / "sub.ipynb", "from math import *", "def f():\n    return floor(pi)", lab=None
    )
    nb = load_notebook(path)
    assert [index for index, _ in nb.cells] == [0, 1]
    assert run(nb)["f"]() == 3


def test_a_needed_cell_that_does_not_parse_is_named(tmp_path):
    path = write_notebook(
        tmp_path / "sub.ipynb",
        "x = (",  # scratch: nothing graded in it
        "def normalize(w:\n    return w",
        "def wrap(a):\n    return a",
    )
    nb = load_notebook(path)  # lab demo: normalize, wrap, mean_pose are graded
    assert [(p.cell_index, p.kind, p.where) for p in nb.problems] == [
        (1, "syntax", "cell 2, `def normalize(w:`")
    ]
    assert "nothing in it is defined" in nb.problems[0].message
    assert str(nb.problems[0]).startswith("cell 2, `def normalize(w:`: ")
    assert [index for index, _ in nb.cells] == [2]


def test_the_lab_exercises_are_graded():
    assert set(lab_exercises("demo")) == {"normalize", "wrap", "mean_pose"}
    assert {"bayes_posterior", "door_open_posterior", "bayes_filter_step"} <= set(
        lab_exercises("bayes")
    )
    assert lab_exercises(None) == ()
    assert lab_exercises("no_such_lab") == ()


def test_failing_needed_cells_stop_where_jupyter_stops(tmp_path):
    path = write_notebook(
        tmp_path / "sub.ipynb",
        "def f():\n    return 1\nraise ValueError('boom')\ndef g():\n    return 2",
        "def k():\n    return 4",
        "import time\ndef h():\n    return 3\ntry:\n    time.sleep(30)\nexcept Exception:\n"
        "    pass\ndef late():\n    return 5",
        "def m():\n    return 6",
        lab=None,
    )
    nb = load_notebook(path)
    namespace = new_namespace("submission")
    problems = run_cells(namespace, nb.cells, wall_seconds=0.5, cpu_seconds=10.0)
    assert [(i, kind) for i, kind, _ in problems] == [(0, "error"), (2, "timeout"), (3, "timeout")]
    assert "ValueError: boom (line 3)" in problems[0][2]
    assert "time allowed to load your notebook (0.5 s)" in problems[1][2]
    assert problems[2][2].startswith("not run: cell 3 used up")
    assert namespace["f"]() == 1 and namespace["k"]() == 4 and namespace["h"]() == 3
    assert not {"g", "late", "m"} & namespace.keys()
    # The shim builtins are no definitions of the notebook.
    assert "get_ipython" not in namespace and "display" not in namespace


def test_cpu_time_is_limited_too():
    namespace = new_namespace("submission")
    source = "def f():\n    return 1\nwhile True:\n    pass"
    problems = run_cells(namespace, [(4, source)], wall_seconds=30.0, cpu_seconds=0.3)
    assert problems == [(4, "timeout", problems[0][2])]
    assert "(0.3 s of CPU time)" in problems[0][2] and namespace["f"]() == 1


def test_future_imports_carry_over_to_later_cells(tmp_path):
    path = write_notebook(
        tmp_path / "sub.ipynb",
        "from __future__ import annotations\nimport math",
        "def f(x: Later) -> float:\n    return math.pi",
        lab=None,
    )
    nb = load_notebook(path)
    assert run(nb)["f"](0) == pytest.approx(3.141592653589793)
    # The joined source (for reading) still compiles as one module.
    assert nb.source.startswith("from __future__ import annotations\n")
    compile(nb.source, "sub", "exec")


def test_notebook_without_lab_metadata(tmp_path):
    nb = load_notebook(write_notebook(tmp_path / "n.ipynb", "def f():\n    return 1", lab=None))
    assert nb.lab is None
    assert nb.functions == ["f"] and nb.graded == ["f"]


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
    nb.cells[1].metadata["tags"] = ["exercise"]
    path = tmp_path / "nbf.ipynb"
    nbformat.write(nb, path)
    loaded = load_notebook(path)
    assert (
        loaded.lab == "demo"
        and loaded.functions == ["f"]
        and loaded.cells == [(1, "def f():\n    return 1\nf()")]
    )


def test_old_notebook_format_is_refused(tmp_path):
    path = tmp_path / "v3.ipynb"
    path.write_text('{"nbformat": 3, "worksheets": [], "cells": []}')
    with pytest.raises(NotebookError, match="v3.ipynb.*format 4"):
        load_notebook(path)


@pytest.mark.parametrize(
    "imports",
    [
        "import numpy as np\nfrom math import (pi\n",  # an unclosed parenthesis
        "import numpy as np\nimport math as m,\n",  # a trailing comma
        "import numpy as np\n  x = 1\n",  # an indentation error
    ],
)
def test_an_imports_cell_that_does_not_parse_is_named_with_its_error(tmp_path, imports):
    # Issue 25: every check failed with NameError and no word of the syntax error.
    path = write_notebook(
        tmp_path / "n.ipynb",
        "x = (\n",  # scratch that does not parse and that nothing needs: not reported
        imports,
        "def wrap(a):\n    return np.arctan2(np.sin(a), np.cos(a)) + 0 * len(names)\n",
        "names = ['np', 'pi']\n",
    )
    loaded = load_notebook(path, graded=["wrap"])
    (problem,) = loaded.problems
    assert problem.kind == "syntax" and problem.cell_index == 1
    assert problem.where.startswith("cell 2, `import numpy as np`")
    assert "does not parse" in problem.message and "line 2" in problem.message
    assert "your graded functions use np," in problem.message  # names bound elsewhere: not


def test_the_syntax_error_reaches_grading_and_checking_alike(tmp_path, capsys):
    from robolab.cli import main
    from robolab.grading.running.proxy import open_submission
    from tests.grading import TEST_LIMITS

    path = write_notebook(
        tmp_path / "n.ipynb",
        "import numpy as np\nfrom math import (pi\n",
        "def wrap(a):\n    return np.arctan2(np.sin(a), np.cos(a))\n",
    )
    with open_submission(path, limits=TEST_LIMITS) as sub:  # what grading reports
        assert any("was never closed" in str(p) and "use np" in str(p) for p in sub.problems)
    main(["check", str(path)])  # what a student checking sees
    out = capsys.readouterr().out
    assert "cell 1, `import numpy as np`" in out and "was never closed" in out
