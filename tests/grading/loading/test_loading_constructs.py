"""Bindings only running reveals: branches that may not run, `globals()`/`exec`/`setattr` on the
module, `%%writefile`/`%run`, `__main__` -- chosen and run as Jupyter would (docs/grading.md 1).

The quick tests load small notebooks and run their needed cells through
:class:`robolab.grading.loading.kernel.Notebook` (what the worker and ``robolab check`` both
use); each notebook's expected value is what a kernel running it top to bottom
holds. The sandbox tests go through the grading worker (:func:`open_submission`).
"""

from __future__ import annotations

import ast
import os
import sys

import pytest

from robolab.grading.labs import project_root
from robolab.grading.loading.bindings import surely_binds
from robolab.grading.loading.kernel import Notebook, load_budget
from robolab.grading.loading.notebook import load_notebook
from robolab.grading.running.proxy import open_submission
from tests.grading import TEST_LIMITS, write_notebook

BUDGET = load_budget(60.0, 30.0)

#: (name, cells, what f() returns in a kernel that ran every cell top to bottom).
NOTEBOOKS = [
    ("if-false", ["def f():\n    return 1", "if False:\n    def f():\n        return 2"], 1),
    ("if-true", ["def f():\n    return 1", "if True:\n    def f():\n        return 2"], 2),
    (
        "try-import-after",
        [
            "def f():\n    return 1",
            "try:\n    from old_answers import f\nexcept ImportError:\n    pass",
        ],
        1,
    ),
    ("for-nothing", ["def f():\n    return 1", "for f in []:\n    pass"], 1),
    ("for-something", ["def f():\n    return 1", "for f in [lambda: 3]:\n    pass"], 3),
    ("while-false", ["def f():\n    return 1", "while False:\n    f = None"], 1),
    (
        "with-suppress",
        [
            "def f():\n    return 1",
            "import contextlib\nwith contextlib.suppress(ImportError):\n"
            "    from old_answers import f",
        ],
        1,
    ),
    ("match", ["def f():\n    return 1", 'match "a":\n    case "b":\n        f = None'], 1),
    (
        "define-if-missing",
        ["def f():\n    return 1", "try:\n    f\nexcept NameError:\n    f = None"],
        1,
    ),
    ("guarded-by-globals", ["def f():\n    return 1", "if 'f' not in globals():\n    f = None"], 1),
    ("main-guard", ["if __name__ == '__main__':\n    def f():\n        return 1"], 1),
    ("not-main-guard", ["def f():\n    return 1", "if __name__ != '__main__':\n    f = None"], 1),
    ("globals-item", ["def _g():\n    return 1", "globals()['f'] = _g"], 1),
    (
        "globals-by-value",
        [
            "def _f_impl():\n    return 1",
            "x = 1",
            "for n in ['f']:\n    globals()[n] = globals()['_' + n + '_impl']",
        ],
        1,
    ),
    ("exec-then-value", ["exec('def f():\\n    return K')", "K = 5"], 5),
    (
        "setattr-module-by-name",
        [
            "def _g():\n    return 2",
            "import sys\nme = sys.modules[__name__]",
            "x = 1",
            "setattr(me, 'f', _g)",
        ],
        2,
    ),
    (
        "setattr-module",
        ["def _g():\n    return 1", "import sys\nsetattr(sys.modules[__name__], 'f', _g)"],
        1,
    ),
    ("import-main", ["def _g():\n    return 4", "import __main__\n__main__.f = _g"], 4),
    (
        "exporting-decorator",
        [
            "def export(fn):\n    globals()[fn.__name__[1:]] = fn\n    return fn",
            "@export\ndef _f():\n    return 3",
        ],
        3,
    ),
    (
        "writefile-import",
        ["%%writefile helper_a.py\ndef f():\n    return 7\n", "from helper_a import f"],
        7,
    ),
    (
        "writefile-star",
        ["%%writefile helper_b.py\ndef f():\n    return 8\n", "from helper_b import *"],
        8,
    ),
    ("writefile-run", ["%%writefile s.py\nK = 3\ndef f():\n    return K\n", "%run s.py"], 3),
    ("run-interactive", ["K = 4", "%%writefile s.py\ndef f():\n    return K\n", "%run -i s.py"], 4),
    (
        "writefile-append",
        [
            "%%writefile helper_c.py\nK = 2\n",
            "%%writefile -a helper_c.py\ndef f():\n    return K\n",
            "import helper_c\nf = helper_c.f",
        ],
        2,
    ),
    (
        "pickle-by-reference",
        ["import pickle\ndef _g():\n    return 9\nf = pickle.loads(pickle.dumps(_g))"],
        9,
    ),
    ("store-restore", ["%store -r\nK = 6", "def f():\n    return K"], 6),
    (
        "data-file",
        [
            '%%writefile table.json\n{"k": 11}\n',
            "import json\nT = json.load(open('table.json'))",
            "def f():\n    return T['k']",
        ],
        11,
    ),
    (
        "raise-in-other-branch",
        ["def f():\n    return 1", "if 1 > 2:\n    raise ValueError\nelse:\n    f = lambda: 2"],
        2,
    ),
]


def _load(tmp_path, cells):
    path = write_notebook(tmp_path / "nb.ipynb", *cells, lab=None)
    return load_notebook(path, graded=["f"])


@pytest.mark.parametrize("name, cells, expected", NOTEBOOKS, ids=[n[0] for n in NOTEBOOKS])
def test_the_needed_cells_hold_what_a_kernel_holds(tmp_path, name, cells, expected):
    loaded = _load(tmp_path, cells)
    folder = tmp_path / "scratch"
    folder.mkdir()
    with Notebook(folder) as notebook:
        problems = notebook.run(loaded.cells, *BUDGET)
        assert problems == []
        assert notebook.namespace["f"]() == expected


def test_scratch_cells_that_bind_nothing_needed_are_still_skipped(tmp_path):
    cells = [
        "def f():\n    return 1",
        "import time\ntime.sleep(60)",  # a demo
        "if False:\n    def f():\n        return 2",
        "print(1 / 0)",
        "exec('g = 1', {})",  # a namespace of its own: binds nothing of the notebook's
        "class C:\n    def __init__(self):\n        setattr(self, 'x', 1)\n\n\nC()",
    ]
    assert [i for i, _ in _load(tmp_path, cells).cells] == [0, 2]


@pytest.mark.parametrize(
    "statement, sure",
    [
        ("x = 1", {"x"}),
        ("if c:\n    x = 1\nelse:\n    x = 2\n    y = 3", {"x"}),
        ("if c:\n    x = 1", set()),
        ("if c:\n    raise ValueError\nx = 1", {"x"}),
        ("if c:\n    raise ValueError\nelse:\n    x = 1", {"x"}),
        ("try:\n    import a as x\nexcept ImportError:\n    x = None", {"x"}),
        ("try:\n    import a as x\nexcept ImportError:\n    pass", set()),
        ("try:\n    pass\nfinally:\n    x = 1", {"x"}),
        ("for x in y:\n    z = 1", set()),
        ("while (n := 3) > 4:\n    z = 1", {"n"}),
        ("with open(p) as fh:\n    x = fh.read()", {"fh", "x"}),
        ("with suppress(E):\n    x = 1", set()),
        ("if __name__ == '__main__':\n    def f(): pass", {"f"}),
        ("x: int", set()),
    ],
)
def test_a_binding_is_sure_only_when_every_way_through_binds_it(statement, sure):
    assert surely_binds(ast.parse(statement).body) == sure


def test_the_notebook_module_is_main_and_is_put_back(tmp_path):
    main, cwd, path = sys.modules["__main__"], os.getcwd(), list(sys.path)
    folder = tmp_path / "scratch"
    folder.mkdir()
    cells = [
        (0, "%%writefile mine.py\nX = 1\n"),
        (1, "import mine, sys\nME = sys.modules[__name__]"),
    ]
    from robolab.grading.loading.notebook import to_python

    with Notebook(folder) as notebook:
        assert notebook.run([(i, to_python(s)) for i, s in cells], *BUDGET) == []
        assert notebook.namespace["__name__"] == "__main__"
        assert notebook.namespace["ME"] is notebook.module is sys.modules["__main__"]
        assert os.getcwd() == str(folder.resolve()) and sys.path[0] == str(folder.resolve())
        assert "mine" in sys.modules
    assert sys.modules["__main__"] is main and os.getcwd() == cwd and sys.path == path
    assert "mine" not in sys.modules  # the next notebook's `import mine` finds its own


# --- through the grading worker: the sandbox stays as strict ---------------------------------


def _graded(tmp_path, *cells):
    path = write_notebook(tmp_path / "sub.ipynb", *cells, lab=None)
    return open_submission(path, limits=TEST_LIMITS)


def test_writefile_and_run_work_in_the_workers_scratch_folder(tmp_path):
    with _graded(
        tmp_path,
        "%%writefile helper.py\nimport os\ndef where():\n    return os.getcwd()\n",
        "from helper import where as _where\n\n\ndef where():\n    return _where()",
        "%%writefile script.py\nimport sys\nARGS = sys.argv[1:]\nNAME = __name__\n",
        "%run script.py a b\ndef args():\n    return ARGS, NAME, __name__",
    ) as sub:
        assert sub.problems == []
        folder = sub.where()
        assert sub.args() == (["a", "b"], "__main__", "__main__")
    assert not (tmp_path / "helper.py").exists()  # the scratch folder, not the notebook's
    assert folder != str(tmp_path)


def test_run_outside_the_scratch_folder_is_not_found_and_reads_nothing(tmp_path):
    answers = project_root() / "solutions" / "demo.py"
    assert answers.is_file()
    relative = os.path.relpath(answers, "/")
    with _graded(
        tmp_path,
        f"%run {answers}\n",
        f"%run ../../../../../../../../{relative}\n",
        f"import os\nos.symlink({str(answers)!r}, 'link.py')\n%run link.py\n",
        "%run -m solutions.demo\n",
        "def normalize_seen():\n    return 'normalize' in globals()",
    ) as sub:
        messages = [p.message for p in sub.problems]
        assert sub.normalize_seen() is False
    assert len(messages) == 4, messages
    for message in messages[:3]:
        assert "not found" in message and "Exception" in message, message
    assert "not a valid modulename" in messages[3]


def test_writefile_outside_the_scratch_folder_is_refused(tmp_path):
    target = tmp_path / "escaped.py"
    with _graded(
        tmp_path,
        f"%%writefile {target}\nX = 1\n",
        "%%writefile ../escaped.py\nX = 1\n",
        "def f():\n    return 1",
    ) as sub:
        assert sub.f() == 1
        messages = [p.message for p in sub.problems]
    assert not target.exists()
    assert len(messages) == 2 and all("FolderError" in m for m in messages), messages


def test_robolab_check_loads_like_the_grader_cells_that_set_the_module_attribute(tmp_path, capsys):
    """Was: `robolab check` failed with KeyError: '__notebook__', `robolab grade` passed."""
    import nbformat

    from robolab.grading.commands import check
    from tests.grading.loading.fidelity_constructs import CONSTRUCTS, DYNAMIC
    from tests.grading.loading.fidelity_variants import Variant, solved_cells

    cells, exercises = solved_cells("demo")
    style = CONSTRUCTS[DYNAMIC]["setattr-on-module"].style
    for at in sorted(exercises, reverse=True):
        for f in exercises[at]:
            cells = style(cells, at, f, f"answers_{f}")
    path = tmp_path / "demo.ipynb"
    nbformat.write(Variant("setattr", "demo", cells).notebook(), str(path))
    assert check(path) == 0, capsys.readouterr().out
    assert "note:" not in capsys.readouterr().out
    with open_submission(path, lab="demo", limits=TEST_LIMITS) as sub:
        assert sub.problems == []
        assert list(sub.normalize([1.0, 3.0])) == [0.25, 0.75]
