"""Styles that bind an exercise in ways only running the notebook reveals, one exercise at a time.

Each style rewrites how *one* exercise function ``f`` of a solved notebook gets
bound: in a branch that never runs after the real definition, through
``globals()``/``exec``/``setattr`` on the module in a cell without the exercise
tag, from a module written with ``%%writefile`` and imported or ``%run``, under
``if __name__ == "__main__":``, and so on. Styles are grouped by the construct
they exercise (:data:`CONSTRUCTS`). A *combination* notebook of a lab gives each
of its exercises one style (:func:`combinations`), so every lab is covered by one
notebook, one Jupyter run and one grading run, and a style that breaks shows as
the exercise it was given losing points.

Every combination is run by Jupyter first (tests/grading/test_fidelity.py): its
visible checks pass there and each exercise holds a working function.
"""

from __future__ import annotations

import ast
import re
import textwrap
from collections.abc import Callable
from dataclasses import dataclass

from robolab.grading.labs import discover_labs
from robolab.grading.loading.notebook import _analyse
from tests.grading.loading.fidelity_variants import Cell, Variant, solved_cells

#: Every lab of the course (the demo lab is covered by fidelity_variants).
LABS = tuple(lab.name for lab in discover_labs() if lab.name != "demo")

#: A style: (cells, position of f's exercise cell, f, a unique stem for file and module names)
#: -> the new cells. It may insert cells only right after the exercise cell (before its
#: visible check) or right before it, and must leave the function correct.
Style = Callable[[list[Cell], int, str, str], list[Cell]]


@dataclass(frozen=True)
class Construct:
    """A style and what it needs from the exercise it is given."""

    style: Style
    #: The exercise cell must define f from its own names only (a module written to a
    #: file sees no notebook names).
    self_contained: bool = False


CONSTRUCTS: dict[str, dict[str, Construct]] = {}


def construct(group: str, name: str, *, self_contained: bool = False):
    def register(fn: Style) -> Style:
        CONSTRUCTS.setdefault(group, {})[name] = Construct(fn, self_contained)
        return fn

    return register


# --- helpers ---------------------------------------------------------------------------------


def _impl(source: str, f: str) -> str:
    """The exercise cell with ``def f(`` renamed ``def _f_impl(``."""
    renamed = re.sub(rf"^def {f}\(", f"def _{f}_impl(", source, flags=re.MULTILINE)
    assert renamed != source, f"no top-level def {f} in the cell"
    return renamed


def _after(cells: list[Cell], at: int, *new: str) -> list[Cell]:
    return (
        cells[: at + 1] + [Cell(textwrap.dedent(c).strip() + "\n") for c in new] + cells[at + 1 :]
    )


def _before(cells: list[Cell], at: int, *new: str) -> list[Cell]:
    return cells[:at] + [Cell(c) for c in new] + cells[at:]


def _replace(cells: list[Cell], at: int, source: str, tags: list[str] | None = None) -> list[Cell]:
    return cells[:at] + [Cell(source, cells[at].tags if tags is None else tags)] + cells[at + 1 :]


def _rebound(cells: list[Cell], at: int, f: str, *binding: str) -> list[Cell]:
    """f renamed ``_f_impl`` in its cell; ``binding`` cells (untagged) bind f again."""
    return _after(_replace(cells, at, _impl(cells[at].source, f)), at, *binding)


def _wrapped(cells: list[Cell], at: int, f: str, body: str) -> list[Cell]:
    """f renamed ``_f_impl`` and called by a wrapper that runs ``body`` (asserts) first."""
    wrapper = f"\n\ndef {f}(*args, **kwargs):\n{textwrap.indent(body, '    ')}\n"
    wrapper += f"    return _{f}_impl(*args, **kwargs)\n"
    return _replace(cells, at, _impl(cells[at].source, f).rstrip() + "\n" + wrapper)


def _without_future(source: str) -> tuple[str, str]:
    """(the ``from __future__`` lines, the rest of the cell)."""
    future = [line for line in source.splitlines() if line.startswith("from __future__")]
    rest = [line for line in source.splitlines() if not line.startswith("from __future__")]
    return "\n".join(future), "\n".join(rest) + "\n"


BRANCHES = "a binding in a branch that may not run"
MAIN = "the notebook runs as __main__"
DYNAMIC = "a binding no analysis can see"
FILES = "files the notebook writes and runs"

#: Styles that add one cell after f's exercise cell, which still defines f; the cell's
#: source names f as ``{f}`` and a unique stem as ``{stem}``.
AFTER = {
    BRANCHES: {
        "if-false-redefinition": "if False:\n    def {f}(*args, **kwargs):\n        return None",
        "try-import-old-version": "try:\n    from old_{stem} import {f}\n"
        "except ImportError:\n    pass",
        "for-over-nothing": "for {f} in []:\n    pass",
        "while-false": "while False:\n    {f} = None",
        "with-suppress-import": "import contextlib\n\nwith contextlib.suppress(ImportError):\n"
        "    from old_{stem} import {f}",
        "match-no-case": 'match "graded":\n    case "draft":\n        {f} = None',
        "define-if-missing": "try:\n    {f}\nexcept NameError:\n    {f} = None",
        "guarded-by-globals": 'if "{f}" not in globals():\n    {f} = None',
    },
}

#: Styles that rename f ``_f_impl`` in its exercise cell and bind f again in a cell
#: after it, without the exercise tag.
REBOUND = {
    BRANCHES: {
        "if-else-both-bind": "FAST_{stem} = True\nif FAST_{stem}:\n    {f} = _{f}_impl\n"
        "else:\n    {f} = _{f}_impl",
    },
    MAIN: {
        # pickle stores a function as `__main__.<name>`: it loads back only when the
        # notebook's module is `sys.modules["__main__"]`, as in Jupyter.
        "pickled-by-reference": "import pickle\n\n{f} = pickle.loads(pickle.dumps(_{f}_impl))",
        "import-main-attribute": "import __main__\n\n__main__.{f} = _{f}_impl",
        "sys-modules-main-dict": "import sys\n\n"
        'sys.modules["__main__"].__dict__["{f}"] = _{f}_impl',
    },
    DYNAMIC: {
        "globals-item": 'globals()["{f}"] = _{f}_impl',
        "globals-loop-by-name": 'for _n in ["{f}"]:\n'
        '    globals()[_n] = globals()["_" + _n + "_impl"]',
        "globals-update": 'globals().update({{"{f}": _{f}_impl}})',
        "vars-item": 'vars()["{f}"] = _{f}_impl',
        "locals-item": 'locals()["{f}"] = _{f}_impl',
        "exec-assignment": 'exec("{f} = _{f}_impl")',
        "exec-compiled": 'exec(compile("{f} = _{f}_impl", "<answers>", "exec"))',
        "setattr-on-module": 'import sys\n\nsetattr(sys.modules[__name__], "{f}", _{f}_impl)',
    },
}


def _after_style(template: str) -> Style:
    return lambda cells, at, f, stem: _after(cells, at, template.format(f=f, stem=stem))


def _rebound_style(template: str) -> Style:
    return lambda cells, at, f, stem: _rebound(cells, at, f, template.format(f=f, stem=stem))


for _group, _styles in AFTER.items():
    for _name, _template in _styles.items():
        construct(_group, _name)(_after_style(_template))
for _group, _styles in REBOUND.items():
    for _name, _template in _styles.items():
        construct(_group, _name)(_rebound_style(_template))


# --- styles that rewrite the exercise cell itself ----------------------------------------------


@construct(MAIN, "main-guard")
def _main_guard(cells, at, f, stem):
    future, rest = _without_future(cells[at].source)
    body = textwrap.indent(rest, "    ")
    return _replace(
        cells, at, (future + "\n" if future else "") + f'if __name__ == "__main__":\n{body}'
    )


@construct(MAIN, "name-is-main-when-called")
def _name_is_main(cells, at, f, stem):
    return _wrapped(cells, at, f, 'assert __name__ == "__main__", __name__')


@construct(DYNAMIC, "exec-whole-cell")
def _exec_cell(cells, at, f, stem):
    return _replace(cells, at, f"exec({cells[at].source!r})", tags=[])


@construct(DYNAMIC, "setattr-on-module")
def _setattr_module(cells, at, f, stem):
    return _rebound(cells, at, f, f'import sys\n\nsetattr(sys.modules[__name__], "{f}", _{f}_impl)')


@construct(DYNAMIC, "exporting-decorator")
def _exporting_decorator(cells, at, f, stem):
    source = re.sub(rf"^def {f}\(", f"@export_{stem}\ndef _{f}_impl(", cells[at].source, flags=re.M)
    exporter = (
        f"def export_{stem}(fn):\n    globals()[fn.__name__[1:-len('_impl')]] = fn\n    return fn\n"
    )
    return _before(_replace(cells, at, source), at, exporter)


# --- files the notebook writes: %%writefile, import, %run ---------------------------------


def _module(cells: list[Cell], at: int, stem: str, use: str, tags=None) -> list[Cell]:
    """The exercise cell written to ``<stem>.py`` with %%writefile; the cell then runs ``use``."""
    written = Cell(f"%%writefile {stem}.py\n{cells[at].source}")
    return _before(_replace(cells, at, use, tags), at, written.source)


@construct(FILES, "writefile-import", self_contained=True)
def _writefile_import(cells, at, f, stem):
    return _module(cells, at, stem, f"from {stem} import {f}")


@construct(FILES, "writefile-star-import", self_contained=True)
def _writefile_star(cells, at, f, stem):
    return _module(cells, at, stem, f"from {stem} import *")


@construct(FILES, "writefile-run", self_contained=True)
def _writefile_run(cells, at, f, stem):
    return _module(cells, at, stem, f"%run {stem}.py", tags=[])


@construct(FILES, "writefile-run-interactive")
def _writefile_run_i(cells, at, f, stem):
    return _module(cells, at, stem, f"%run -i {stem}.py", tags=[])


@construct(FILES, "writefile-in-two-parts", self_contained=True)
def _writefile_append(cells, at, f, stem):
    tree = ast.parse(cells[at].source)
    lines = cells[at].source.splitlines(keepends=True)
    split = next(n.lineno - 1 for n in tree.body if not isinstance(n, (ast.Import, ast.ImportFrom)))
    head, tail = "".join(lines[:split]), "".join(lines[split:])
    return _before(
        _replace(cells, at, f"import {stem}\n\n{f} = {stem}.{f}"),
        at,
        f"%%writefile {stem}.py\n{head}",
        f"%%writefile -a {stem}.py\n{tail}",
    )


@construct(FILES, "writefile-reload", self_contained=True)
def _writefile_reload(cells, at, f, stem):
    use = f"import importlib\nimport {stem}\n\n{stem} = importlib.reload({stem})\n{f} = {stem}.{f}"
    return _module(cells, at, stem, use)


@construct(FILES, "writefile-ipy-run")
def _writefile_ipy(cells, at, f, stem):
    cells = _replace(cells, at, _impl(cells[at].source, f))
    return _after(cells, at, f"%%writefile {stem}.ipy\n%time {f} = _{f}_impl\n", f"%run {stem}.ipy")


@construct(FILES, "writefile-data-read-at-load")
def _writefile_data(cells, at, f, stem):
    cells = _wrapped(cells, at, f, f'assert TABLE_{stem}["answer"] == 42')
    return _before(
        cells,
        at,
        f'%%writefile {stem}.json\n{{"answer": 42}}\n',
        f'import json\n\nwith open("{stem}.json") as fh:\n    TABLE_{stem} = json.load(fh)',
    )


@construct(FILES, "file-in-working-folder-at-call")
def _file_at_call(cells, at, f, stem):
    # Read when f is called: the working folder is still the notebook's then.
    cells = _wrapped(
        cells,
        at,
        f,
        f'assert open("{stem}.txt").read().strip() == "ok", "the working folder changed"',
    )
    return _before(cells, at, f"%%writefile {stem}.txt\nok\n")


@construct(FILES, "store-restore")
def _store(cells, at, f, stem):
    cells = _wrapped(cells, at, f, f"assert STORED_{stem} == 1")
    return _before(cells, at, f"%store -r\nSTORED_{stem} = 1")


# --- combinations -----------------------------------------------------------------------------


def all_styles() -> list[tuple[str, str]]:
    """``(construct, style)`` of every style, the constructs taken in turn (each lab gets a mix)."""
    groups = [[(group, name) for name in styles] for group, styles in CONSTRUCTS.items()]
    out = []
    for rank in range(max(len(g) for g in groups)):
        out += [g[rank] for g in groups if rank < len(g)]
    return out


def _self_contained(source: str) -> bool:
    """Whether a cell's functions read only names the cell itself binds (or builtins)."""
    import builtins

    cell = _analyse(0, source)
    free = (cell.reads_now | cell.reads_later) - cell.binds - set(dir(builtins))
    return not free


@dataclass
class Combination(Variant):
    """A lab's notebook whose exercises each carry one style: ``{exercise: (construct, style)}``."""

    assignment: dict[str, tuple[str, str]] | None = None


def combinations(labs: tuple[str, ...] = LABS) -> list[Combination]:
    """One notebook per lab, its exercises given the styles in turn (every style at least once).

    A style that needs a self-contained exercise is given the next exercise that is.
    """
    styles = all_styles()
    pending = list(styles)  # every style once first, then round again
    out = []
    turn = 0
    for lab in labs:
        cells, exercises = solved_cells(lab)
        assignment: dict[str, tuple[str, str]] = {}
        plan = []
        for at, names in exercises.items():
            contained = _self_contained(cells[at].source)
            for f in names:
                if not pending:
                    turn += 1
                queue = pending or styles[turn % len(styles) :] + styles[: turn % len(styles)]
                pick = next(
                    s for s in queue if contained or not CONSTRUCTS[s[0]][s[1]].self_contained
                )
                if pick in pending:
                    pending.remove(pick)
                assignment[f] = pick
                plan.append((at, f, pick))
        for at, f, (group, name) in sorted(plan, reverse=True):  # last first: positions hold
            stem = f"answers_{lab}_{f}"
            cells = CONSTRUCTS[group][name].style(list(cells), at, f, stem)
        out.append(Combination("combination", lab, cells, assignment))
    assert not pending, f"styles given to no exercise: {pending}"
    return out
