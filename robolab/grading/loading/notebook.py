"""Load a student notebook: the cells a kernel needs to hold the graded functions.

The contract (docs/grading.md section 1): the functions graded are the objects
a kernel that ran the notebook top to bottom would hold at the end. So every
code cell is turned into Python the way IPython does it (line and cell magics,
``!`` shell lines, ``x = !cmd``), its names are analysed with :mod:`symtable`,
and the cells the graded functions need -- the last cell defining each of them,
and, transitively, the cells binding every module-level name they read -- are
kept *whole*, in notebook order. The worker runs exactly those cells.
Everything else (demos, plots, visible checks, scratch cells that raise, sleep
or flood the output) is skipped and costs nothing.

Nothing here executes student code. The notebook's JSON is read with
:mod:`json` rather than ``nbformat``, whose import costs seconds per graded
submission. IPython's input transformer (about 0.4 s to import) is imported
only for a cell that is not already plain Python: a cell that parses as
Python is left as it is, which is what IPython's transformation does to it.
"""

from __future__ import annotations

import ast
import builtins
import functools
import json
import re
import symtable
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from robolab.grading.labs import LabError, read_submission
from robolab.grading.loading.bindings import (
    ALL,
    code_strings,
    is_opaque,
    looks_up_by_value,
    mutated,
    mutated_inside,
    name_strings,
    note_written,
    run_in_namespace,
    scope_names,
    statements,
    surely_binds,
    timed_statements,
)
from robolab.grading.loading.ipython_syntax import (
    FILE_CELL_MAGICS,
    _cell_magic,
    _python_and_tree,
    to_python,
)

__all__ = [
    "CellProblem",
    "LoadedNotebook",
    "NotebookError",
    "cell_label",
    "lab_exercises",
    "load_notebook",
    "to_python",
]

#: Tag of the cells that hold exercise stubs (see DESIGN.md "Notebooks").
EXERCISE_TAG = "exercise"




#: Names a notebook reads without binding them (a star import can still shadow them).
_BUILTINS = frozenset(dir(__import__("builtins"))) | {"get_ipython", "display", "__name__"}

#: Longest first line shown when naming a cell.
LABEL_CHARS = 40

_DEF_LINE = re.compile(r"^\s*(?:async\s+def|def|class)\s+([A-Za-z_]\w*)", re.MULTILINE)
_WORD = re.compile(r"[A-Za-z_]\w*")


class NotebookError(Exception):
    """The file is not a readable Jupyter notebook."""


@dataclass
class CellProblem:
    """Something wrong with one needed cell; the other cells still load.

    Attributes
    ----------
    cell_index : int
        Index of the cell in the notebook (0-based, all cell types counted);
        -1 when the problem is not one cell's.
    kind : str
        ``"syntax"`` (the cell does not parse), ``"error"`` (running it
        raised), ``"timeout"`` (it ran past the load limit).
    message : str
        What went wrong, in words a student can act on.
    where : str
        The cell as a student finds it: ``"cell 12, `def p_hit(z, z_star, ...`"``
        (1-based position among all cells, and its first line).
    """

    cell_index: int
    kind: str
    message: str
    where: str = ""

    def __str__(self) -> str:
        return f"{self.where or 'loading the notebook'}: {self.message}"


@dataclass
class LoadedNotebook:
    """The cells of a notebook that the graded functions need, ready for a worker.

    Attributes
    ----------
    path : Path
        The notebook file.
    lab : str or None
        The lab named in the notebook metadata ``{"robolab": {"lab": ...}}``.
    source : str
        The needed cells joined in notebook order (``from __future__`` lines
        first), for reading; the worker runs ``cells`` one by one.
    functions : list of str
        Functions and classes the needed cells define, in order.
    problems : list of CellProblem
        Needed cells that do not parse.
    exercise_cells : list of int
        Indices of the cells tagged ``exercise``.
    cells : list of tuple of (int, str)
        ``(cell_index, python source)`` of each needed cell, in notebook order.
    labels : dict of int to str
        The student-facing name of every code cell (see :func:`cell_label`).
    graded : list of str
        The names the needed cells were chosen for (the lab's exercises, or
        every function the notebook defines when the lab is unknown).
    """

    path: Path
    lab: str | None
    source: str
    functions: list[str]
    problems: list[CellProblem]
    exercise_cells: list[int]
    cells: list[tuple[int, str]] = field(default_factory=list)
    labels: dict[int, str] = field(default_factory=dict)
    graded: list[str] = field(default_factory=list)

    def where(self, cell_index: int) -> str:
        """The student-facing name of a cell, ``""`` for an index that is no cell."""
        return self.labels.get(cell_index, "")

    def problem(self, cell_index: int, kind: str, message: str) -> CellProblem:
        """A :class:`CellProblem` of this notebook, named as a student finds the cell."""
        return CellProblem(cell_index, kind, message, self.where(cell_index))


def cell_label(cell_index: int, source: str) -> str:
    """How a student finds a cell: ``cell 12, `def p_hit(z, z_star, ...```.

    Parameters
    ----------
    cell_index : int
        0-based index among all cells (markdown included), as stored.
    source : str
        The cell's source as the student wrote it.
    """
    first = next((line.strip() for line in source.splitlines() if line.strip()), "")
    if len(first) > LABEL_CHARS:
        cut = first[:LABEL_CHARS]
        first = (cut.rsplit(" ", 1)[0] if " " in cut else cut) + " ..."
    return f"cell {cell_index + 1}, `{first}`" if first else f"cell {cell_index + 1} (empty)"


# --- what a cell binds and reads ---------------------------------------------------------------


@dataclass
class _Cell:
    """Names of one code cell: bound at module level, read now, read by its functions later."""

    index: int
    python: str | None
    #: every name it may bind (or change) at module level
    binds: set[str] = field(default_factory=set)
    #: the names it binds whatever branch runs (a binding in an `if`, `try`, loop or
    #: `with suppress` body may not happen: it does not replace an earlier one)
    sure: set[str] = field(default_factory=set)
    reads_now: set[str] = field(default_factory=set)
    reads_later: set[str] = field(default_factory=set)
    functions: list[str] = field(default_factory=list)
    #: function name -> the globals it assigns (``global X; X = ...``) when called
    global_writes: dict[str, set[str]] = field(default_factory=dict)
    #: functions it defines that bind globals no analysis sees (``globals()[n] = ...``)
    dynamic_writers: set[str] = field(default_factory=set)
    star: bool = False
    #: it may bind any name: a star import, ``globals()``, ``exec``, ``setattr`` on the
    #: module, ``%run``, ``%store -r``, or a call of a function that does one of these
    opaque: bool = False
    #: a ``%%writefile`` cell
    writes_files: bool = False
    #: it looks names up by a value known only when it runs (``globals()["_" + n]``):
    #: it may read any function or class defined before it
    reads_functions: bool = False
    #: its ``from __future__`` imports (they change how every later cell compiles)
    future: list[str] = field(default_factory=list)
    error: SyntaxError | None = None


def _analyse(index: int, source: str, files: dict[str, str] | None = None, depth: int = 0) -> _Cell:
    """What one cell binds and reads; ``files`` maps each file the cells before it wrote
    with ``%%writefile`` to its text (this cell's writes are added). ``depth`` counts
    the code strings and files analysed inside one another (a file may run itself)."""
    files = {} if files is None else files
    python, tree = _python_and_tree(source)
    cell = _Cell(index, python)
    if isinstance(tree, SyntaxError):
        cell.error = tree
    if not isinstance(tree, ast.Module):
        return cell
    magic = _cell_magic(tree)
    cell.writes_files = magic is not None and magic[0] in FILE_CELL_MAGICS
    if cell.writes_files:
        note_written(files, tree)
    found = statements(python, tree)
    if "run_line_magic" in python:
        found += timed_statements(tree)  # `%time y = f()` binds y in the kernel
    for node, text in found:
        _add_statement(cell, node, text)
    written = is_opaque(tree, python)
    cell.opaque = cell.star or written
    if cell.opaque:
        # Code it runs from strings (`exec("def f(): ...")`) or from files the notebook
        # wrote (`%run -i helper.py`), and names it looks up by string
        # (`globals()["_f_impl"]`): what it may bind and read.
        for text in code_strings(tree) + run_in_namespace(tree, files) if depth < 3 else ():
            sub = _analyse(index, text, dict(files), depth + 1)
            cell.reads_now |= sub.reads_now - cell.binds
            cell.reads_later |= sub.reads_later
            cell.binds |= sub.binds
        cell.reads_now |= name_strings(tree) - cell.binds
        cell.reads_functions = looks_up_by_value(tree)
    cell.dynamic_writers = {
        node.name
        for node in (tree.body if written else ())
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and is_opaque(node)
    }
    return cell


def _add_statement(cell: _Cell, node: ast.stmt, text: str) -> None:
    """Add what one top-level statement binds and reads to ``cell``."""
    try:
        table = symtable.symtable(text, "<cell>", "exec")
    except SyntaxError:  # e.g. `return` outside a function: Jupyter refuses the cell too
        return
    binds, now, later = scope_names(table)
    changed = mutated(node)  # `d[k] = v`, `obj.x = v`, `N += 1`: read, then rebind
    maybe_changed = mutated_inside(node) - changed
    now |= changed | maybe_changed
    sure = surely_binds([node])
    sure = (binds if sure is ALL else sure & binds) | changed
    if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
        sure &= {node.name}  # its `global X` assignments happen when it is called, if ever
    binds |= changed | maybe_changed
    cell.reads_now |= now - cell.binds
    cell.reads_later |= later
    cell.binds |= binds
    cell.sure |= sure
    if isinstance(node, ast.ImportFrom) and any(a.name == "*" for a in node.names):
        cell.star = True
    if isinstance(node, ast.ImportFrom) and node.module == "__future__":
        cell.future.append(ast.unparse(node))
    if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
        cell.functions.append(node.name)
        if binds - {node.name}:
            cell.global_writes[node.name] = binds - {node.name}


# --- which cells are needed --------------------------------------------------------------------


def needed_cells(cells: list[_Cell], graded: Iterable[str]) -> list[_Cell]:
    """The cells a kernel must run for ``graded`` and every name they use, in notebook order.

    A name read when a cell runs (top level, decorators, defaults, class bodies)
    resolves to the cells binding it *before* that cell; a global read inside a
    function resolves when it is called, so to the cells binding it anywhere. In
    both cases the cells are taken from the last one back, up to and including the
    last that binds the name whatever branch runs (:attr:`_Cell.sure`): a binding
    that may not happen (``if False:``, ``try: from old import f except
    ImportError: pass``) does not replace the one before it, so both run, in
    order, and Python decides. A cell whose bindings cannot be known
    (:attr:`_Cell.opaque`) may bind any name, so it is taken like such a binding;
    a builtin name nothing binds only a star import can shadow. ``%%writefile``
    cells always run (any cell may read the files they write).
    """
    writers: dict[str, set[str]] = {}
    dynamic: set[str] = set()
    for cell in cells:
        writers.update(cell.global_writes)
        dynamic |= cell.dynamic_writers
    for cell in cells:  # a cell calling `setup()` may bind the globals setup() assigns
        for name in cell.reads_now & writers.keys():
            cell.binds |= writers[name]
        if cell.reads_now & dynamic:  # `@export` that writes `globals()`
            cell.opaque = True
    binders: dict[str, list[int]] = {}
    for position, cell in enumerate(cells):
        for name in cell.binds:
            binders.setdefault(name, []).append(position)
    opaque = [p for p, cell in enumerate(cells) if cell.opaque]
    star = [p for p, cell in enumerate(cells) if cell.star]
    candidates: dict[str, list[int]] = {}
    needed: set[int] = set()
    todo: list[int] = []

    def resolve(name: str, before: int | None) -> None:
        if name not in candidates:
            own = binders.get(name, [])
            extra = star if name in _BUILTINS and not own else opaque
            candidates[name] = sorted(set(own) | set(extra))
        for position in reversed(candidates[name]):
            if before is not None and position >= before:
                continue
            if position not in needed:
                needed.add(position)
                todo.append(position)
            if name in cells[position].sure:
                return

    for name in graded:
        resolve(name, None)
    while todo:
        position = todo.pop()
        cell = cells[position]
        reads_now = set(cell.reads_now)
        if cell.reads_functions:  # it may read any function defined before it
            reads_now.update(n for c in cells[:position] for n in c.functions)
        for name in reads_now:
            resolve(name, position)
        for name in cell.reads_later:
            resolve(name, None)
    if needed:
        needed |= {p for p, cell in enumerate(cells) if cell.writes_files}
    return [cells[p] for p in sorted(needed)]


@functools.lru_cache(maxsize=64)
def lab_exercises(lab: str | None) -> tuple[str, ...]:
    """The exercise functions of a lab: those its stub notebook's exercise cells define.

    Falls back to the public functions of the lab's solution module; empty when
    the lab is unknown or has neither (then every function of a notebook is graded).
    """
    if not lab:
        return ()
    from robolab.grading.labs import Lab, project_root

    try:
        found = Lab(lab, project_root())
    except LabError:  # pragma: no cover - Lab() itself does not look at files
        return ()
    names: list[str] = []
    stub = found.notebook
    if stub is not None:
        try:
            nb = json.loads(stub.read_text(encoding="utf-8"))
            for cell in nb.get("cells", []):
                if cell.get("cell_type") == "code" and EXERCISE_TAG in cell.get("metadata", {}).get(
                    "tags", []
                ):
                    names += [
                        n.name
                        for n in ast.parse(_text(cell.get("source", ""))).body
                        if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef))
                    ]
        except (OSError, ValueError, SyntaxError, AttributeError):
            names = []
    if not names and found.solution.is_file():
        try:
            tree = ast.parse(found.solution.read_text(encoding="utf-8"))
        except (OSError, SyntaxError):
            return ()
        names = [
            n.name
            for n in tree.body
            if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef)) and not n.name.startswith("_")
        ]
    return tuple(dict.fromkeys(names))


# --- reading the notebook ----------------------------------------------------------------------


def _text(source: object) -> str:
    if isinstance(source, list) and all(isinstance(line, str) for line in source):
        return "".join(source)  # notebooks on disk store a list of lines
    return source if isinstance(source, str) else ""


def _read(path: Path) -> dict:
    try:  # never blocks on a fifo, never reads a device or a huge file without end
        text = read_submission(path).decode("utf-8")
    except LabError as exc:
        raise NotebookError(str(exc)) from None
    except UnicodeDecodeError as exc:
        raise NotebookError(f"{path}: is not a notebook: not UTF-8 text ({exc.reason})") from exc
    try:
        nb = json.loads(text)
    except json.JSONDecodeError as exc:
        raise NotebookError(
            f"{path}: is not a notebook: not valid JSON "
            f"(line {exc.lineno} column {exc.colno}: {exc.msg})"
        ) from exc
    except RecursionError:
        raise NotebookError(f"{path}: is not a notebook: its JSON is nested too deeply") from None
    except ValueError as exc:  # a number of more digits than Python converts
        raise NotebookError(f"{path}: is not a notebook: not valid JSON ({exc})") from None
    if not isinstance(nb, dict) or not isinstance(nb.get("cells"), list):
        raise NotebookError(f"{path}: is not a notebook: it has no list of cells")
    if not isinstance(nb.get("nbformat"), int) or nb["nbformat"] < 4:
        raise NotebookError(
            f"{path}: is not a notebook in format 4 or later (nbformat={nb.get('nbformat')!r}); "
            "open and save it in a current Jupyter to convert it"
        )
    return nb


def load_notebook(
    path: str | Path,
    *,
    lab: str | None = None,
    graded: Iterable[str] | None = None,
    every_function: bool = False,
) -> LoadedNotebook:
    """Read a notebook and choose the cells the graded functions need.

    Parameters
    ----------
    path : str or Path
        A ``.ipynb`` file (nbformat 4).
    lab : str, optional
        The lab it is graded as, whose exercises are graded; defaults to the
        notebook's metadata.
    graded : iterable of str, optional
        The names to grade; defaults to the lab's exercises
        (:func:`lab_exercises`) and the functions of the notebook's own
        exercise cells, or, when neither is known, every function and class
        the notebook defines.
    every_function : bool
        Grade every function and class the notebook defines, whatever its lab.

    Returns
    -------
    LoadedNotebook

    Raises
    ------
    NotebookError
        When the file cannot be read, is not JSON, or is not a notebook.
    """
    path = Path(path)
    nb = _read(path)
    metadata = nb.get("metadata") or {}
    robolab_meta = metadata.get("robolab") if isinstance(metadata, dict) else None
    meta_lab = robolab_meta.get("lab") if isinstance(robolab_meta, dict) else None
    if meta_lab is not None and not isinstance(meta_lab, str):
        raise NotebookError(
            f"{path}: metadata robolab.lab must be a string, got {type(meta_lab).__name__}"
        )

    cells: list[_Cell] = []
    files: dict[str, str] = {}  # what the %%writefile cells so far wrote
    raw: dict[int, str] = {}
    labels: dict[int, str] = {}
    exercise_cells: list[int] = []
    for index, cell in enumerate(nb["cells"]):
        if not isinstance(cell, dict) or cell.get("cell_type") != "code":
            continue
        source = cell.get("source", "")
        if not isinstance(source, str) and not (
            isinstance(source, list) and all(isinstance(line, str) for line in source)
        ):
            raise NotebookError(
                f"{path}: is not a notebook: cell {index + 1} has a source that is not text"
            )
        source = _text(source)
        cell_metadata = cell.get("metadata")
        tags = cell_metadata.get("tags") if isinstance(cell_metadata, dict) else None
        if isinstance(tags, list) and EXERCISE_TAG in tags:
            exercise_cells.append(index)
        raw[index] = source
        labels[index] = cell_label(index, source)
        cells.append(_analyse(index, source, files))

    if graded is None:
        names = [] if every_function else list(lab_exercises(lab or meta_lab))
        for cell in cells:
            if cell.index in exercise_cells and not every_function:
                names += [n for n in cell.functions if n not in names]
        if not names:  # unknown lab: every function, also those of cells that do not parse
            names = list(
                dict.fromkeys(
                    n
                    for cell in cells
                    for n in (_DEF_LINE.findall(raw[cell.index]) if cell.error else cell.functions)
                )
            )
    else:
        names = list(graded)

    needed = needed_cells(cells, names)
    wanted = set(names) | {n for cell in needed for n in cell.reads_now | cell.reads_later}
    # A cell that does not parse binds nothing: name it when it defines a graded function
    # or mentions a name the needed cells use and no cell binds (an imports cell).
    unbound = wanted - {n for cell in cells for n in cell.binds} - set(dir(builtins))
    problems = []
    for cell in cells:
        if cell.error is None:
            continue
        missing = sorted(unbound & set(_WORD.findall(raw[cell.index])))
        if missing or set(_DEF_LINE.findall(raw[cell.index])) & wanted:
            message = _syntax_message(cell.error, missing)
            problems.append(CellProblem(cell.index, "syntax", message, labels[cell.index]))
    # A skipped cell's `from __future__` imports still hold in the cells after it.
    chosen = {cell.index for cell in needed}
    kept = [
        (cell.index, cell.python)
        if cell.index in chosen
        else (cell.index, "\n".join(cell.future) + "\n")
        for cell in cells
        if cell.index in chosen or (cell.future and needed and cell.index < needed[-1].index)
    ]
    return LoadedNotebook(
        path=path,
        lab=meta_lab,
        source=_joined(kept),
        functions=list(dict.fromkeys(n for cell in needed for n in cell.functions)),
        problems=problems,
        exercise_cells=exercise_cells,
        cells=kept,
        labels=labels,
        graded=names,
    )


def _joined(cells: list[tuple[int, str]]) -> str:
    """The needed cells as one text, their ``from __future__`` lines moved to its head."""
    future: list[str] = []
    parts = []
    for _, source in cells:
        lines = source.splitlines(keepends=True)
        drop = set()
        for node in ast.parse(source).body if "__future__" in source else ():
            if isinstance(node, ast.ImportFrom) and node.module == "__future__":
                drop.update(range(node.lineno - 1, node.end_lineno))
                line = ast.get_source_segment(source, node)
                if line not in future:
                    future.append(line)
        parts.append("".join(line for i, line in enumerate(lines) if i not in drop).rstrip())
    text = "\n\n".join([*(["\n".join(future)] if future else []), *filter(None, parts)])
    return text + "\n" if text else ""


def _syntax_message(exc: SyntaxError, needed: Sequence[str] = ()) -> str:
    where = f"line {exc.lineno}" if exc.lineno else "somewhere"
    text = f": {exc.text.strip()}" if exc.text and exc.text.strip() else ""
    uses = (
        f"; your graded functions use {', '.join(needed)}, which only this cell would define"
        if needed
        else ""
    )
    return f"it does not parse, so nothing in it is defined: {exc.msg} ({where}{text}){uses}"
