"""Correct notebooks written in the styles students use, built from the reference solutions.

Each :class:`Variant` starts from the solved notebook of a lab
(:func:`robolab.grading.exports.solve.solve_notebook`), reduced to its set-up cell, its
exercise cells and its visible-check cells, and rewrites it in one style:
magics, shell lines, module-level values computed by calls, helpers in cells
the student inserted, redefinitions, scratch cells that raise, do not parse,
sleep or flood the output, and so on. Every variant stays correct: its
functions return the reference solution's values (test_fidelity.py proves it
with Jupyter itself, then grades it).

Styles that need a module-level value wrap each exercise function ``f`` as::

    def f(*args, **kwargs):
        <lines that fail unless the value is bound as the kernel binds it>
        return _f_impl(*args, **kwargs)

so a loader that drops or mis-binds the value costs every test of ``f``.
"""

from __future__ import annotations

import ast
import re
from collections.abc import Callable
from dataclasses import dataclass, field

import nbformat

from robolab.grading.exports.solve import solve_notebook
from robolab.grading.labs import exercise_cells, find_lab

#: Seconds the sleeping scratch cell sleeps when graded (Jupyter runs it with SHORT_SLEEP).
LONG_SLEEP = 45
SHORT_SLEEP = 0.2


@dataclass
class Cell:
    source: str
    tags: list[str] = field(default_factory=list)
    #: The source Jupyter runs instead, when running the graded source would only waste time.
    jupyter_source: str | None = None


@dataclass
class Variant:
    """One correct notebook of ``lab`` written in style ``style``."""

    style: str
    lab: str
    cells: list[Cell]

    @property
    def name(self) -> str:
        return f"{self.lab}-{self.style}"

    def notebook(self, *, for_jupyter: bool = False) -> nbformat.NotebookNode:
        nb = nbformat.v4.new_notebook()
        nb.metadata["robolab"] = {"lab": self.lab}
        nb.metadata["kernelspec"] = {"name": "python3", "display_name": "Python 3"}
        nb.cells = [nbformat.v4.new_markdown_cell(f"# {self.name}")]
        for cell in self.cells:
            source = cell.source
            if for_jupyter and cell.jupyter_source is not None:
                source = cell.jupyter_source
            code = nbformat.v4.new_code_cell(source)
            if cell.tags:
                code.metadata["tags"] = list(cell.tags)
            nb.cells.append(code)
        return nb


# --- the solved notebook, reduced --------------------------------------------------------------


def solved_cells(lab: str) -> tuple[list[Cell], dict[int, list[str]]]:
    """The set-up cell, exercise cells and visible checks of ``lab``'s solved notebook.

    Returns the cells and, for each exercise cell (by position in the list), its functions.
    """
    found = find_lab(lab)
    stub = nbformat.read(str(found.notebook), as_version=4)
    solved = solve_notebook(stub, found)
    # The exercises are the stub's functions (the solved cells add the helpers they use).
    functions = {index: [f.name for f in funcs] for index, funcs in exercise_cells(stub)}
    cells: list[Cell] = []
    exercises: dict[int, list[str]] = {}
    first = True
    for index, cell in enumerate(solved.cells):
        if cell.cell_type != "code":
            continue
        if index in functions:
            exercises[len(cells)] = functions[index]
            cells.append(Cell(cell.source, ["exercise"]))
        elif first or "checks.check_" in cell.source:
            cells.append(Cell(cell.source))
        first = False
    return cells, exercises


# --- rewriting helpers -------------------------------------------------------------------------


def _rename(source: str, name: str, new: str) -> str:
    return re.sub(rf"^def {name}\(", f"def {new}(", source, flags=re.MULTILINE)


def wrap_exercises(
    cells: list[Cell],
    exercises: dict[int, list[str]],
    body: str,
    *,
    header: str = "def {name}(*args, **kwargs):",
) -> list[Cell]:
    """Each exercise ``f`` renamed ``_f_impl`` and called by a wrapper running ``body`` first."""
    out = []
    for position, cell in enumerate(cells):
        if position not in exercises:
            out.append(cell)
            continue
        source = cell.source
        for name in exercises[position]:
            source = _rename(source, name, f"_{name}_impl")
            wrapper = header.format(name=name) + "\n"
            wrapper += "".join(f"    {line}\n" if line else "\n" for line in body.splitlines())
            wrapper += f"    return _{name}_impl(*args, **kwargs)\n"
            source = source.rstrip() + "\n\n\n" + wrapper
        out.append(Cell(source, cell.tags))
    return out


def prefix_exercises(cells: list[Cell], exercises: dict[int, list[str]], prefix: str) -> list[Cell]:
    return [Cell(prefix + c.source, c.tags) if p in exercises else c for p, c in enumerate(cells)]


def insert_after_first_exercise(
    cells: list[Cell], exercises: dict[int, list[str]], *new: Cell
) -> list[Cell]:
    at = min(exercises) + 1
    return cells[:at] + list(new) + cells[at:]


def insert_before_exercises(
    cells: list[Cell], exercises: dict[int, list[str]], *new: Cell
) -> list[Cell]:
    at = min(exercises)
    return cells[:at] + list(new) + cells[at:]


def _split_helpers(source: str, names: list[str]) -> tuple[str, str]:
    """(the cell with only imports and the exercise functions, the rest of it)."""
    tree = ast.parse(source)
    lines = source.splitlines()
    keep, move = [], []
    for node in tree.body:
        start = min([node.lineno] + [d.lineno for d in getattr(node, "decorator_list", [])]) - 1
        while start > 0 and lines[start - 1].lstrip().startswith("#"):
            start -= 1
        text = "\n".join(lines[start : node.end_lineno])
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            keep.append(text)
            move.append(text)
        elif isinstance(node, ast.FunctionDef) and node.name in names:
            keep.append(text)
        else:
            move.append(text)
    return "\n\n\n".join(keep) + "\n", "\n\n\n".join(move) + "\n"


def checks_last(cells: list[Cell]) -> list[Cell]:
    """The visible-check cells moved to the end (for styles that complete the code later)."""
    checks = [c for c in cells if "checks.check_" in c.source]
    return [c for c in cells if c not in checks] + checks


# --- the styles ----------------------------------------------------------------------------------

Style = Callable[[list[Cell], dict[int, list[str]]], list[Cell]]
STYLES: dict[str, Style] = {}


def style(name: str) -> Callable[[Style], Style]:
    def register(fn: Style) -> Style:
        STYLES[name] = fn
        return fn

    return register


@style("plain")
def _plain(cells, ex):
    return cells


@style("line-magics")
def _line_magics(cells, ex):
    magics = "%matplotlib inline\n%config InlineBackend.figure_format = 'png'\n"
    return [Cell(magics + cells[0].source)] + prefix_exercises(cells, ex, "%load_ext autoreload\n")[
        1:
    ]


#: Styles that prefix every exercise cell.
PREFIXES = {
    "shell-lines": "!pip --version\nfiles = !ls\n",
    "time-cell-magic": "%%time\n",
    "capture-cell-magic": "%%capture\n",
}

#: Styles whose wrappers check a line of their own (``body``), or a module-level value bound
#: by code put at the top of each exercise cell (``prefix``) or in cells inserted before the
#: first exercise cell (``cells``).
WRAPPED: dict[str, dict] = {
    "percent-continuation": {"body": "k = (7\n% 4)\nassert k == 3"},
    "neq-continuation": {"body": "if (len(args)\n!= len(args)):\n    raise AssertionError"},
    "lambda-value": {"prefix": "sq = lambda v: v * v\n", "body": "assert sq(3) == 9"},
    "dict-comprehension": {
        "prefix": "TABLE = {k: k * k for k in range(4)}\n",
        "body": "assert TABLE[3] == 9",
    },
    "tuple-unpacking": {
        "prefix": "LO, (MID, HI) = sorted((3, 1))[0], (2, 3)\n",
        "body": "assert (LO, MID, HI) == (1, 2, 3)",
    },
    "time-line-magic": {"cells": ["%time SEED = sum(range(4))"], "body": "assert SEED == 6"},
    "scipy-value": {
        "cells": ["from scipy.stats import norm\nHALF = norm(0, 1).cdf(0)"],
        "body": "assert HALF == 0.5",
    },
    "needed-cell-floods": {
        "cells": ["for i in range(20000):\n    print('line', i)\nFLOODED = True"],
        "body": "assert FLOODED",
    },
    "global-setup": {
        "cells": ["def setup():\n    global CONFIG\n    CONFIG = {'ok': True}", "setup()"],
        "body": "assert CONFIG['ok']",
    },
    "walrus": {"cells": ["print(W := 7)"], "body": "assert W == 7"},
    "display-and-plot": {
        "cells": [
            "import matplotlib.pyplot as plt\nTHRESH = 0.25\ndisplay(THRESH)\n"
            "plt.plot([0, 1], [THRESH, THRESH])\nplt.close('all')"
        ],
        "body": "assert THRESH == 0.25",
    },
}

#: Scratch cells inserted after the first exercise cell (they define nothing graded).
SCRATCH = {
    "scratch-raises": Cell("x = 1 / 0  # trying something", ["raises-exception"]),
    "scratch-syntax-error": Cell("def oops(:\n    pass", ["raises-exception"]),
    "scratch-flood": Cell("for i in range(20000):\n    print(i)"),
}


def _prefixed(prefix: str) -> Style:
    return lambda cells, ex: prefix_exercises(cells, ex, prefix)


def _wrapped(prefix: str = "", cells: tuple = (), body: str = "") -> Style:
    def build(notebook: list[Cell], ex: dict[int, list[str]]) -> list[Cell]:
        if prefix:
            notebook = prefix_exercises(notebook, ex, prefix)
        notebook = insert_before_exercises(notebook, ex, *(Cell(c) for c in cells))
        return wrap_exercises(notebook, {p + len(cells): n for p, n in ex.items()}, body)

    return build


def _scratch(cell: Cell) -> Style:
    return lambda cells, ex: insert_after_first_exercise(cells, ex, cell)


STYLES.update({name: _prefixed(prefix) for name, prefix in PREFIXES.items()})
STYLES.update({name: _wrapped(**spec) for name, spec in WRAPPED.items()})
STYLES.update({name: _scratch(cell) for name, cell in SCRATCH.items()})


def rebind_exercises(
    cells: list[Cell], exercises: dict[int, list[str]], template: str, header: str = ""
) -> list[Cell]:
    """Each exercise ``f`` renamed ``_f_impl``; ``template`` (naming ``{name}``) rebinds ``f``."""
    out = []
    for p, c in enumerate(cells):
        if p in exercises:
            source = c.source
            for name in exercises[p]:
                source = _rename(source, name, f"_{name}_impl") + template.format(name=name)
            c = Cell(header + source, c.tags)
        out.append(c)
    return out


@style("partial")
def _partial(cells, ex):
    template = "\n\n{name} = functools.partial(_{name}_impl)\n"
    return rebind_exercises(cells, ex, template, header="import functools\n")


@style("augmented-assignment")
def _augmented(cells, ex):
    cells = insert_before_exercises(cells, ex, Cell("N = 0"), Cell("N += 1"))
    ex = {p + 2: n for p, n in ex.items()}
    cells = cells + [Cell("N += 1")]
    return checks_last(wrap_exercises(cells, ex, "assert N == 2"))


@style("inserted-cell-value")
def _inserted_value(cells, ex):
    cells = wrap_exercises(cells, ex, "assert LIMIT == 42")
    return insert_after_first_exercise(
        cells, ex, Cell("def compute_limit():\n    return 41 + 1"), Cell("LIMIT = compute_limit()")
    )


@style("star-import")
def _star_import(cells, ex):
    def star(source: str) -> str:
        source = re.sub(
            r"^from robolab\.(\w+) import .*$",
            r"from robolab.\1 import *",
            source,
            flags=re.MULTILINE,
        )
        return source

    # Only the first exercise cell: a star import in a later cell would rebind the names
    # defined before it to the library's own functions (the kernel holds those at the end,
    # so the notebook would delegate and the delegation guard rightly fails it).
    first = min(ex)
    return [Cell(star(c.source), c.tags) if p == first else c for p, c in enumerate(cells)]


@style("class-based")
def _class_based(cells, ex):
    template = (
        "\n\nclass _Solver_{name}:\n    @staticmethod\n"
        "    def solve(*args, **kwargs):\n"
        "        return _{name}_impl(*args, **kwargs)\n"
        "\n\n{name} = _Solver_{name}.solve\n"
    )
    return rebind_exercises(cells, ex, template)


@style("decorator")
def _decorator(cells, ex):
    deco = Cell(
        "import functools\n\n\ndef traced(fn):\n    @functools.wraps(fn)\n"
        "    def inner(*args, **kwargs):\n        return fn(*args, **kwargs)\n    return inner"
    )
    out = []
    for p, c in enumerate(cells):
        if p in ex:
            source = c.source
            for name in ex[p]:
                source = re.sub(rf"^def {name}\(", f"@traced\ndef {name}(", source, flags=re.M)
            c = Cell(source, c.tags)
        out.append(c)
    return insert_before_exercises(out, {p: n for p, n in ex.items()}, deco)


@style("future-first-cell")
def _future_first(cells, ex):
    strip = [
        Cell(c.source.replace("from __future__ import annotations\n", ""), c.tags) for c in cells
    ]
    # `Later` is never defined: the annotations only work when the future import,
    # made in the first cell, still holds in the exercise cells (as in IPython).
    strip = wrap_exercises(
        strip, ex, "", header="def {name}(*args: Later, **kwargs: Later) -> Later:"
    )
    return [Cell("from __future__ import annotations")] + strip


@style("redefinition")
def _redefinition(cells, ex):
    out = []
    for p, c in enumerate(cells):
        if p in ex:
            wrong = "\n\n".join(f"def {n}(*args, **kwargs):\n    return None" for n in ex[p])
            out.append(Cell(wrong))
        out.append(c)
    return out


@style("stub-then-solution")
def _stub_then_solution(cells, ex):
    out = []
    moved = []
    for p, c in enumerate(cells):
        if p in ex:
            stub = "\n\n".join(
                f"def {n}(*args, **kwargs):\n    raise NotImplementedError" for n in ex[p]
            )
            out.append(Cell(stub, c.tags))
            moved.append(Cell(c.source))
        else:
            out.append(c)
    return checks_last(out + moved)


@style("helpers-after")
def _helpers_after(cells, ex):
    out, rest = [], []
    for p, c in enumerate(cells):
        if p in ex:
            keep, move = _split_helpers(c.source, ex[p])
            out.append(Cell(keep, c.tags))
            rest.append(move)
        else:
            out.append(c)
    return checks_last(out + [Cell("# helpers I wrote later\n" + "\n\n".join(rest))])


@style("scratch-sleep")
def _scratch_sleep(cells, ex):
    return insert_after_first_exercise(
        cells,
        ex,
        Cell(
            f"import time\ntime.sleep({LONG_SLEEP})",
            jupyter_source=f"import time\ntime.sleep({SHORT_SLEEP})",
        ),
    )


@style("no-tags")
def _no_tags(cells, ex):
    return [Cell(c.source) for c in cells]


@style("percent-in-wrap")
def _percent_in_wrap(cells, ex):
    # The case: a continuation line that starts with `%` (demo lab only).
    out = []
    for c in cells:
        if re.search(r"^def wrap\(", c.source, flags=re.M):
            c = Cell(
                re.sub(
                    r"^def wrap\(angle\):\n(    .*\n|\n)*",
                    "def wrap(angle):\n    return ((np.asarray(angle, dtype=float) + np.pi)\n"
                    "% (2 * np.pi)) - np.pi\n\n\n",
                    c.source + "\n",
                    flags=re.M,
                ),
                c.tags,
            )
        out.append(c)
    return out


#: Which labs each style is graded in: once each (plain in all three), to keep the suite
#: to a few minutes (each variant is one pytest run of the hidden tests).
PLAN: dict[str, tuple[str, ...]] = {
    "plain": ("demo", "bayes", "frames"),
    "line-magics": ("demo",),
    "shell-lines": ("bayes",),
    "time-cell-magic": ("bayes", "frames"),
    "capture-cell-magic": ("bayes",),
    "time-line-magic": ("demo",),
    "percent-continuation": ("bayes",),
    "neq-continuation": ("demo",),
    "scipy-value": ("bayes",),
    "lambda-value": ("demo",),
    "partial": ("bayes",),
    "dict-comprehension": ("demo",),
    "augmented-assignment": ("bayes",),
    "inserted-cell-value": ("frames",),
    "star-import": ("frames",),
    "tuple-unpacking": ("bayes",),
    "class-based": ("demo",),
    "decorator": ("bayes",),
    "redefinition": ("demo",),
    "stub-then-solution": ("bayes",),
    "helpers-after": ("bayes",),
    "scratch-raises": ("bayes",),
    "scratch-syntax-error": ("demo",),
    "scratch-sleep": ("bayes",),
    "scratch-flood": ("demo",),
    "needed-cell-floods": ("bayes",),
    "global-setup": ("demo",),
    "walrus": ("bayes",),
    "display-and-plot": ("demo",),
    "no-tags": ("frames",),
    "percent-in-wrap": ("demo",),
    # Last of each lab: the future flag it sets stays in the shared Jupyter kernel.
    "future-first-cell": ("demo",),
}


def variants() -> list[Variant]:
    """Every planned variant, grouped by lab, in PLAN order within a lab."""
    base = {lab: solved_cells(lab) for lab in ("demo", "bayes", "frames")}
    out = []
    for lab in base:
        cells, ex = base[lab]
        for name, labs in PLAN.items():
            if lab in labs:
                out.append(Variant(name, lab, STYLES[name](list(cells), dict(ex))))
    return out


def wrong_variants() -> list[Variant]:
    """Notebooks whose visible checks fail in Jupyter (``robolab check`` must fail them too)."""
    cells, ex = solved_cells("demo")
    out = []
    for position, cell in enumerate(cells):
        if position in ex and "normalize" in ex[position]:
            cell = Cell(
                _rename(cell.source, "normalize", "_normalize_impl")
                + "\n\ndef normalize(weights):\n    return np.asarray(weights, dtype=float)\n",
                cell.tags,
            )
        out.append(cell)
    return [Variant("wrong-normalize", "demo", out)]
