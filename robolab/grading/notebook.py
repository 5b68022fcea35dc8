"""Load a student notebook: keep its definitions, drop everything that would run.

A submission is graded by calling its exercise functions, so only what a
module would *define* is kept from each code cell: ``def``, ``class``,
imports and assignments of constant expressions. Plots, loops, demos and the
visible-check calls are dropped, so a slow or broken demo cell cannot cost the
student points. A cell that does not parse is recorded as a
:class:`CellProblem` and the other cells still load. Exercises are found by
function name, never by cell position.

Nothing here executes student code: parsing is done with :mod:`ast` only.
The notebook's JSON is read with :mod:`json` rather than ``nbformat``, whose
import (through jsonschema's format checkers) costs seconds, once per graded
submission; only the structure used here is checked.
"""

from __future__ import annotations

import ast
import builtins
import json
import re
from dataclasses import dataclass, field
from pathlib import Path

__all__ = [
    "CellProblem",
    "LoadedNotebook",
    "NotebookError",
    "extract_definitions",
    "load_notebook",
]

#: Tag of the cells that hold exercise stubs (see DESIGN.md "Notebooks").
EXERCISE_TAG = "exercise"

# A line magic (%time, %matplotlib), a cell magic (%%time) or a shell line (!pip).
_MAGIC_OR_SHELL = re.compile(r"^\s*(%|!)")
# `x = !ls` and `x = %time f()` assign a magic's output.
_ASSIGNED_MAGIC = re.compile(r"^\s*[\w.,\s\[\]()]+=\s*(%|!)")

_DEFINITIONS = (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef, ast.Import, ast.ImportFrom)


class NotebookError(Exception):
    """The file is not a readable Jupyter notebook."""


@dataclass
class CellProblem:
    """Something wrong with one cell that did not stop the rest from loading.

    Attributes
    ----------
    cell_index : int
        Index of the cell in the notebook (0-based, all cell types counted).
    kind : str
        ``"syntax"`` when the cell does not parse, ``"error"`` when defining
        its contents raised in the worker.
    message : str
        What went wrong, in words a student can act on.
    """

    cell_index: int
    kind: str
    message: str


@dataclass
class LoadedNotebook:
    """The definitions kept from a notebook, ready to execute in a worker.

    Attributes
    ----------
    path : Path
        The notebook file.
    lab : str or None
        The lab named in the notebook metadata ``{"robolab": {"lab": ...}}``.
    source : str
        The kept definitions of all code cells, joined in notebook order.
    functions : list of str
        Names of the top-level functions the kept source defines, in order of
        first definition.
    problems : list of CellProblem
        Cells that could not be loaded.
    exercise_cells : list of int
        Indices of the cells tagged ``exercise``.
    cells : list of tuple of (int, str)
        ``(cell_index, kept definitions)`` for each code cell with something
        kept; the worker defines them cell by cell so one failing cell does not
        hide the others.
    """

    path: Path
    lab: str | None
    source: str
    functions: list[str]
    problems: list[CellProblem]
    exercise_cells: list[int]
    cells: list[tuple[int, str]] = field(default_factory=list)


_BUILTIN_NAMES = frozenset(dir(builtins))


def load_notebook(path: str | Path) -> LoadedNotebook:
    """Read a notebook and keep the definitions of its code cells.

    Parameters
    ----------
    path : str or Path
        A ``.ipynb`` file (nbformat 4).

    Returns
    -------
    LoadedNotebook

    Raises
    ------
    NotebookError
        When the file cannot be read, is not JSON, or is not a notebook.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise NotebookError(f"{path}: cannot read the notebook: {exc.strerror or exc}") from exc
    except UnicodeDecodeError as exc:
        raise NotebookError(f"{path}: is not a notebook: not UTF-8 text ({exc.reason})") from exc
    try:
        nb = json.loads(text)
    except json.JSONDecodeError as exc:
        raise NotebookError(
            f"{path}: is not a notebook: not valid JSON "
            f"(line {exc.lineno} column {exc.colno}: {exc.msg})"
        ) from exc
    if not isinstance(nb, dict) or not isinstance(nb.get("cells"), list):
        raise NotebookError(f"{path}: is not a notebook: it has no list of cells")
    if not isinstance(nb.get("nbformat"), int) or nb["nbformat"] < 4:
        raise NotebookError(
            f"{path}: is not a notebook in format 4 or later (nbformat={nb.get('nbformat')!r}); "
            "open and save it in a current Jupyter to convert it"
        )

    metadata = nb.get("metadata") or {}
    robolab_meta = metadata.get("robolab") if isinstance(metadata, dict) else None
    lab = robolab_meta.get("lab") if isinstance(robolab_meta, dict) else None
    if lab is not None and not isinstance(lab, str):
        raise NotebookError(
            f"{path}: metadata robolab.lab must be a string, got {type(lab).__name__}"
        )

    problems: list[CellProblem] = []
    cells: list[tuple[int, str]] = []
    exercise_cells: list[int] = []
    known: set[str] = set()  # names the kept statements have defined so far, across cells
    for index, cell in enumerate(nb["cells"]):
        if not isinstance(cell, dict) or cell.get("cell_type") != "code":
            continue
        cell_metadata = cell.get("metadata")
        tags = cell_metadata.get("tags") if isinstance(cell_metadata, dict) else None
        if isinstance(tags, list) and EXERCISE_TAG in tags:
            exercise_cells.append(index)
        source = cell.get("source", "")
        if isinstance(source, list) and all(isinstance(line, str) for line in source):
            source = "".join(source)  # notebooks on disk store a list of lines
        if not isinstance(source, str):
            raise NotebookError(
                f"{path}: is not a notebook: cell {index} has a source that is not text"
            )
        try:
            kept = extract_definitions(source, known=known)
        except SyntaxError as exc:
            problems.append(CellProblem(index, "syntax", _syntax_message(exc)))
            continue
        if kept.strip():
            cells.append((index, kept))

    future, cells = _hoist_future_imports(cells)
    source = "\n\n".join([future] * bool(future) + [kept for _, kept in cells])
    return LoadedNotebook(
        path=path,
        lab=lab,
        source=source + "\n" if source else "",
        functions=_function_names(kept for _, kept in cells),
        problems=problems,
        exercise_cells=exercise_cells,
        cells=cells,
    )


def _hoist_future_imports(cells: list[tuple[int, str]]) -> tuple[str, list[tuple[int, str]]]:
    """Move ``from __future__`` imports out of the cells, to head the joined source.

    Python allows them only at the start of a module; solved cells (and students)
    put them at the top of every cell, which would make the joined source invalid.
    """
    future: list[str] = []
    rest = []
    for index, kept in cells:
        lines = kept.splitlines(keepends=True)
        drop = set()
        for node in ast.parse(kept).body:
            if isinstance(node, ast.ImportFrom) and node.module == "__future__":
                drop.update(range(node.lineno - 1, node.end_lineno))
                line = ast.get_source_segment(kept, node)
                if line not in future:
                    future.append(line)
        remaining = "".join(line for i, line in enumerate(lines) if i not in drop)
        if remaining.strip():
            rest.append((index, remaining))
    return "\n".join(future) + ("\n" if future else ""), rest


def extract_definitions(cell_source: str, known: set[str] | None = None) -> str:
    """Keep the top-level definitions of one cell's source.

    Kept: ``def``, ``class``, ``import``, ``from ... import`` and assignments
    (plain or annotated) whose value is a constant expression. Dropped:
    everything else (calls, loops, plots, bare expressions, ``if``/``with``
    blocks). IPython magics and shell lines are removed before parsing.

    Parameters
    ----------
    cell_source : str
        The source of one code cell.
    known : set of str, optional
        Names defined by statements kept so far (updated in place). When given,
        an assignment that reads a name neither known nor a builtin is dropped:
        ``history = [belief]`` after a dropped ``belief = np.array(...)`` would
        only raise NameError while defining the notebook.

    Returns
    -------
    str
        The kept statements, in order, as source text.

    Raises
    ------
    SyntaxError
        When the cell (without its magics) does not parse.
    """
    text = _drop_magics(cell_source)
    tree = ast.parse(text)
    lines = text.splitlines(keepends=True)
    kept = []
    for node in tree.body:
        if _is_definition(node) and (known is None or _reads_only(node, known)):
            if known is not None:
                known.update(_defined_names(node))
            # Source segments keep the student's formatting, comments inside
            # functions and decorators (which start before node.lineno).
            start = min([node.lineno] + [d.lineno for d in getattr(node, "decorator_list", [])])
            kept.append("".join(lines[start - 1 : node.end_lineno]).rstrip() + "\n")
    return "".join(kept)


def _reads_only(node: ast.stmt, known: set[str]) -> bool:
    """True when an assignment reads only known names or builtins (other statements pass)."""
    if not isinstance(node, (ast.Assign, ast.AnnAssign)):
        return True
    read = {n.id for n in ast.walk(node.value) if isinstance(n, ast.Name)}
    return read <= known | _BUILTIN_NAMES


def _defined_names(node: ast.stmt) -> set[str]:
    if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
        return {node.name}
    if isinstance(node, (ast.Import, ast.ImportFrom)):
        return {(a.asname or a.name).split(".")[0] for a in node.names}
    targets = node.targets if isinstance(node, ast.Assign) else [node.target]
    return {n.id for t in targets for n in ast.walk(t) if isinstance(n, ast.Name)}


def _drop_magics(source: str) -> str:
    lines = source.splitlines()
    if lines and lines[0].lstrip().startswith("%%"):
        return ""  # a cell magic (%%time, %%bash) makes the whole cell not Python
    kept = []
    for line in lines:
        if _MAGIC_OR_SHELL.match(line) or _ASSIGNED_MAGIC.match(line):
            kept.append("")  # keep line numbers stable for error messages
        else:
            kept.append(line)
    return "\n".join(kept)


def _is_definition(node: ast.stmt) -> bool:
    if isinstance(node, _DEFINITIONS):
        return True
    if isinstance(node, ast.Assign):
        return all(_is_target(t) for t in node.targets) and _is_constant(node.value)
    if isinstance(node, ast.AnnAssign):
        return node.value is not None and _is_target(node.target) and _is_constant(node.value)
    return False


def _is_target(node: ast.expr) -> bool:
    if isinstance(node, ast.Name):
        return True
    if isinstance(node, (ast.Tuple, ast.List)):
        return all(_is_target(e) for e in node.elts)
    return False  # attribute or subscript targets mutate something: not a definition


def _is_constant(node: ast.expr) -> bool:
    """Literals, containers of and arithmetic on them, dotted names like ``np.pi``, and
    numpy/math functions of constants like ``np.sqrt(2 * np.pi)``."""
    if isinstance(node, ast.Constant):
        return True
    if isinstance(node, (ast.Tuple, ast.List, ast.Set)):
        return all(_is_constant(e) for e in node.elts)
    if isinstance(node, ast.Dict):
        return all(k is not None and _is_constant(k) for k in node.keys) and all(
            _is_constant(v) for v in node.values
        )
    if isinstance(node, ast.UnaryOp):
        return _is_constant(node.operand)
    if isinstance(node, ast.BinOp):
        return _is_constant(node.left) and _is_constant(node.right)
    if isinstance(node, ast.Name):
        return True
    if isinstance(node, ast.Attribute):
        return _is_constant(node.value) and not isinstance(node.value, ast.Constant)
    if isinstance(node, ast.Call):
        # np.sqrt(2 * np.pi), np.deg2rad(10), np.array([...]), math.log(2): pure
        # functions of constants are constants too (students define them at top level).
        return (
            _root_name(node.func) in _PURE_MODULES
            and all(_is_constant(a) for a in node.args)
            and all(k.arg is not None and _is_constant(k.value) for k in node.keywords)
        )
    return False


#: Modules whose functions, called on constants, make constants (by their usual import names).
_PURE_MODULES = frozenset({"np", "numpy", "math"})


def _root_name(node: ast.expr) -> str | None:
    """``np`` for ``np.linalg.norm``; None unless an attribute chain on a name."""
    if not isinstance(node, ast.Attribute):
        return None
    while isinstance(node, ast.Attribute):
        node = node.value
    return node.id if isinstance(node, ast.Name) else None


def _function_names(sources) -> list[str]:
    names: list[str] = []
    for source in sources:
        for node in ast.parse(source).body:
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and node.name not in names:
                names.append(node.name)
    return names


def _syntax_message(exc: SyntaxError) -> str:
    where = f"line {exc.lineno}" if exc.lineno else "somewhere"
    text = f": {exc.text.strip()}" if exc.text and exc.text.strip() else ""
    return f"{exc.msg} ({where}{text})"
