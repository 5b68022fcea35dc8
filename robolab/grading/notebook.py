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
import functools
import getopt
import json
import os
import re
import shlex
import symtable
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path

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

#: Cell magics whose body runs as Python in the user's namespace, so its definitions persist.
#: ``%%timeit`` is not one: its body runs inside a timing function (nothing it defines persists).
PYTHON_CELL_MAGICS = frozenset({"time", "capture"})

#: Cell magics that write their body to a file (``%%file`` is IPython's alias of ``%%writefile``):
#: kept as the ``run_cell_magic`` call, which the worker's shell runs in the notebook's folder.
FILE_CELL_MAGICS = frozenset({"writefile", "file"})

#: Line magics whose bindings cannot be known before running them.
OPAQUE_LINE_MAGICS = frozenset({"run", "store"})

#: Calls through which a cell binds names no analysis sees (``globals()[n] = f``,
#: ``exec(src)``, ``vars()``/``locals()`` at module level: the module's namespace).
_OPAQUE_CALLS = frozenset({"globals", "exec", "vars", "locals"})

#: Names a notebook reads without binding them (a star import can still shadow them).
_BUILTINS = frozenset(dir(__import__("builtins"))) | {"get_ipython", "display", "__name__"}

#: Longest first line shown when naming a cell.
LABEL_CHARS = 40

_DEF_LINE = re.compile(r"^\s*(?:async\s+def|def|class)\s+([A-Za-z_]\w*)", re.MULTILINE)


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


# --- IPython syntax -> Python ------------------------------------------------------------------


@functools.lru_cache(maxsize=1)
def _transformer():
    from IPython.core.inputtransformer2 import TransformerManager  # ~0.4 s: only when needed

    return TransformerManager()


def to_python(source: str) -> str | None:
    """A cell's source as the Python a kernel runs; None when the cell is not Python.

    Plain Python is returned unchanged. Anything else goes through IPython's
    own ``TransformerManager.transform_cell``: line magics become
    ``get_ipython().run_line_magic(...)``, ``!cmd`` ``get_ipython().system(...)``,
    ``x = !cmd`` ``get_ipython().getoutput(...)``. A cell magic that runs its
    body as Python (``%%time``, ``%%capture``) becomes its body; ``%%writefile``
    stays the ``run_cell_magic`` call (it writes a file); any other cell magic
    (``%%bash``, ``%%html``, ``%%timeit``) defines no Python name, so None.

    The result may still not parse (the student's syntax error): that is for
    the caller to find.
    """
    return _python_and_tree(source)[0]


def _python_and_tree(source: str) -> tuple[str | None, ast.Module | SyntaxError | None]:
    """:func:`to_python` and its parse (or the SyntaxError), parsing each text once."""
    try:
        return source, ast.parse(source)
    except (SyntaxError, ValueError):  # ValueError: a NUL byte in the source
        pass
    try:
        python = _transformer().transform_cell(source)
    except Exception:  # noqa: BLE001 - IPython could not tokenize it: left for the parser to report
        python = source
    try:
        tree = ast.parse(python)
    except (SyntaxError, ValueError) as exc:
        return python, exc if isinstance(exc, SyntaxError) else SyntaxError(str(exc))
    magic = _cell_magic(tree)
    if magic is None:
        return python, tree
    name, body = magic
    if name in FILE_CELL_MAGICS:
        return python, tree
    return _python_and_tree(body) if name in PYTHON_CELL_MAGICS else (None, None)


def _cell_magic(tree: ast.Module) -> tuple[str, str] | None:
    """``(name, body)`` when transformed source is one ``run_cell_magic`` call."""
    if len(tree.body) != 1 or not isinstance(tree.body[0], ast.Expr):
        return None
    args = _shell_call(tree.body[0].value, "run_cell_magic", 3)
    return None if args is None else (args[0], args[2])


def _shell_call(node: ast.AST, method: str, count: int) -> list[str] | None:
    """The string arguments of ``get_ipython().<method>(...)`` with ``count`` of them, or None."""
    if (
        isinstance(node, ast.Call)
        and isinstance(node.func, ast.Attribute)
        and node.func.attr == method
        and len(node.args) == count
        and all(isinstance(a, ast.Constant) and isinstance(a.value, str) for a in node.args)
    ):
        return [a.value for a in node.args]
    return None


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
        _note_written(files, tree)
    statements = _statements(python, tree)
    if "run_line_magic" in python:
        statements += _timed_statements(tree)  # `%time y = f()` binds y in the kernel
    for node, text in statements:
        _add_statement(cell, node, text)
    cell.opaque = cell.star or _opaque(tree)
    if cell.opaque:
        # Code it runs from strings (`exec("def f(): ...")`) or from files the notebook
        # wrote (`%run -i helper.py`), and names it looks up by string
        # (`globals()["_f_impl"]`): what it may bind and read.
        for text in _code_strings(tree) + _run_in_namespace(tree, files) if depth < 3 else ():
            sub = _analyse(index, text, dict(files), depth + 1)
            cell.reads_now |= sub.reads_now - cell.binds
            cell.reads_later |= sub.reads_later
            cell.binds |= sub.binds
        cell.reads_now |= _name_strings(tree) - cell.binds
        cell.reads_functions = _looks_up_by_value(tree)
    cell.dynamic_writers = {
        node.name
        for node in tree.body
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and _opaque(node)
    }
    return cell


def _add_statement(cell: _Cell, node: ast.stmt, text: str) -> None:
    """Add what one top-level statement binds and reads to ``cell``."""
    try:
        table = symtable.symtable(text, "<cell>", "exec")
    except SyntaxError:  # e.g. `return` outside a function: Jupyter refuses the cell too
        return
    binds, now, later = _scope_names(table)
    changed = _mutated(node)  # `d[k] = v`, `obj.x = v`, `N += 1`: read, then rebind
    maybe_changed = _mutated_inside(node) - changed
    now |= changed | maybe_changed
    sure = _surely_binds([node])
    sure = (binds if sure is _ALL else sure & binds) | changed
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


# --- bindings that may not happen ----------------------------------------------------------------

#: "Every name": what a statement that never falls through (``raise``) binds for what follows.
_ALL = object()


def _surely_binds(body: list[ast.stmt]) -> set[str] | object:
    """Names every path through ``body`` binds, or :data:`_ALL` when no path falls through.

    The statements of a cell are taken to run (one that raises stops the cell, and
    is reported); what a branch, a loop, a ``try`` or ``with suppress(...)`` binds
    is sure only when every way through it binds it.
    """
    sure: set[str] = set()
    for node in body:
        found = _statement_binds(node)
        if found is _ALL:
            return _ALL
        sure |= found
    return sure


def _both(a, b):
    if a is _ALL:
        return b
    if b is _ALL:
        return a
    return a & b


def _statement_binds(node: ast.stmt) -> set[str] | object:
    if isinstance(node, (ast.Raise, ast.Return, ast.Break, ast.Continue)):
        return _ALL
    if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
        return {node.name}
    if isinstance(node, ast.Import):
        return {(a.asname or a.name).partition(".")[0] for a in node.names}
    if isinstance(node, ast.ImportFrom):
        return {a.asname or a.name for a in node.names if a.name != "*"}
    if isinstance(node, ast.If):
        taken = _constant_test(node.test)
        walrus = _walrus(node.test)
        if taken is True:
            branch = _surely_binds(node.body)
        elif taken is False:
            branch = _surely_binds(node.orelse)
        else:
            branch = _both(_surely_binds(node.body), _surely_binds(node.orelse))
        return branch if branch is _ALL else branch | walrus
    if isinstance(node, (ast.Try, getattr(ast, "TryStar", ast.Try))):
        normal = _surely_binds(node.body + node.orelse)
        for handler in node.handlers:
            normal = _both(normal, _surely_binds(handler.body))
        final = _surely_binds(node.finalbody)
        return _ALL if _ALL in (normal, final) else normal | final
    if isinstance(node, (ast.With, ast.AsyncWith)):
        if any(_suppresses(item.context_expr) for item in node.items):
            return set()
        targets = {
            n.id
            for item in node.items
            for n in ast.walk(item.optional_vars or ast.Pass())
            if isinstance(n, ast.Name)
        }
        inner = _surely_binds(node.body)
        return inner if inner is _ALL else inner | targets
    if isinstance(node, (ast.For, ast.AsyncFor, ast.While)):
        return _walrus(node.iter if isinstance(node, (ast.For, ast.AsyncFor)) else node.test)
    if isinstance(node, getattr(ast, "Match", ())):
        return _walrus(node.subject)  # which case matches is known only when it runs
    # A simple statement: every name it binds (assignment targets, imports, walrus).
    names: set[str] = set()
    for sub in ast.walk(node):
        if isinstance(sub, ast.Name) and isinstance(sub.ctx, (ast.Store, ast.Del)):
            names.add(sub.id)
    if isinstance(node, ast.AnnAssign) and node.value is None:
        return set()  # `x: int` binds nothing
    return names | _walrus(node)


def _walrus(node: ast.AST) -> set[str]:
    return {n.target.id for n in ast.walk(node) if isinstance(n, ast.NamedExpr)}


def _constant_test(test: ast.expr) -> bool | None:
    """The value of an ``if`` test known before running: a constant, or ``__name__ == "__main__"``
    (a notebook runs as ``__main__``)."""
    if isinstance(test, ast.Constant):
        return bool(test.value)
    if (
        isinstance(test, ast.Compare)
        and len(test.ops) == 1
        and isinstance(test.ops[0], (ast.Eq, ast.NotEq))
    ):
        sides = {ast.unparse(test.left), ast.unparse(test.comparators[0])}
        if sides == {"__name__", "'__main__'"}:
            return isinstance(test.ops[0], ast.Eq)
    return None


def _suppresses(expr: ast.expr) -> bool:
    """``with suppress(...)`` (or ``contextlib.suppress``): its body may stop anywhere."""
    func = expr.func if isinstance(expr, ast.Call) else expr
    name = func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", "")
    return name == "suppress"


def _opaque(tree: ast.AST) -> bool:
    """Whether ``tree`` may bind module names no analysis sees.

    ``globals()``, ``exec``, module-level ``vars()``/``locals()``, ``sys.modules``,
    ``__main__``, ``setattr``/``delattr`` on a module, ``%run`` and ``%store``.
    """
    for node in ast.walk(tree):
        if isinstance(node, ast.Call):
            func = node.func
            if isinstance(func, ast.Name) and func.id in _OPAQUE_CALLS:
                return True
            args = _shell_call(node, "run_line_magic", 2)
            if args is not None and args[0] in OPAQUE_LINE_MAGICS:
                return True
        if isinstance(node, ast.Attribute) and node.attr == "modules":
            if isinstance(node.value, ast.Name) and node.value.id == "sys":
                return True
        if isinstance(node, ast.Name) and node.id == "__main__":
            return True
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            modules = (
                [a.name for a in node.names] if isinstance(node, ast.Import) else [node.module]
            )
            if "__main__" in modules:
                return True
        if isinstance(node, ast.Constant) and node.value == "__main__":
            return True  # `__import__("__main__")`, `sys.modules["__main__"]`
    return False


def _code_strings(tree: ast.AST) -> list[str]:
    """String constants of ``tree`` that are Python binding something (code for ``exec``)."""
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Constant) and isinstance(node.value, str):
            try:
                parsed = ast.parse(node.value)
            except (SyntaxError, ValueError):
                continue
            if any(not isinstance(s, ast.Expr) for s in parsed.body):
                found.append(node.value)
    return found


def _note_written(files: dict[str, str], tree: ast.Module) -> None:
    """Record the file a ``%%writefile [-a] NAME`` cell writes, with its text."""
    _, line, body = _shell_call(tree.body[0].value, "run_cell_magic", 3)
    try:
        words = shlex.split(line)
    except ValueError:
        return
    names = [w for w in words if w not in ("-a", "--append")]
    if len(names) == 1:
        name = os.path.normpath(names[0])
        append = len(names) < len(words)
        files[name] = (files.get(name, "") if append else "") + body


def _run_in_namespace(tree: ast.AST, files: dict[str, str]) -> list[str]:
    """The text of the notebook-written files that ``%run`` runs in the notebook's namespace:
    with ``-i``, and ``.ipy`` files (IPython source)."""
    found = []
    for node in ast.walk(tree):
        args = _shell_call(node, "run_line_magic", 2)
        if args is None or args[0] != "run":
            continue
        try:
            opts, rest = getopt.getopt(shlex.split(args[1]), "nidtN:b:pD:l:rs:T:em:G")
        except (getopt.GetoptError, ValueError):
            continue
        if rest and ("-i" in dict(opts) or rest[0].lower().endswith(".ipy")):
            name = os.path.normpath(rest[0])
            text = files.get(name, files.get(name + ".py"))
            if text is not None:
                found.append(text)
    return found


def _looks_up_by_value(tree: ast.AST) -> bool:
    """``globals()[name]``, ``globals().get(name)``, ``getattr(module, name)`` with a name
    known only when the cell runs."""
    for node in ast.walk(tree):
        if (
            isinstance(node, ast.Subscript)
            and isinstance(node.ctx, ast.Load)
            and isinstance(node.value, ast.Call)
            and isinstance(node.value.func, ast.Name)
            and node.value.func.id in _OPAQUE_CALLS
            and not isinstance(node.slice, ast.Constant)
        ):
            return True
        if isinstance(node, ast.Call) and (
            (
                isinstance(node.func, ast.Name)
                and node.func.id == "getattr"
                and len(node.args) >= 2
                and not isinstance(node.args[1], ast.Constant)
            )
            or (
                isinstance(node.func, ast.Attribute)
                and node.func.attr == "get"
                and isinstance(node.func.value, ast.Call)
                and isinstance(node.func.value.func, ast.Name)
                and node.func.value.func.id in _OPAQUE_CALLS
            )
        ):
            return True
    return False


def _name_strings(tree: ast.AST) -> set[str]:
    """String constants of ``tree`` that are identifiers (names looked up by string)."""
    return {
        node.value
        for node in ast.walk(tree)
        if isinstance(node, ast.Constant)
        and isinstance(node.value, str)
        and node.value.isidentifier()
    }


def _statements(python: str, tree: ast.Module) -> list[tuple[ast.stmt, str]]:
    """Each top-level statement with its own source text (its lines, decorators included).

    Statements sharing a line (``a = 1; b = a``) are unparsed instead.
    """
    lines = python.splitlines()
    spans = []
    for node in tree.body:
        start = min([node.lineno] + [d.lineno for d in getattr(node, "decorator_list", [])])
        spans.append((start, node.end_lineno or node.lineno))
    out = []
    for i, (node, (start, end)) in enumerate(zip(tree.body, spans, strict=True)):
        shared = (i > 0 and spans[i - 1][1] >= start) or (
            i + 1 < len(spans) and spans[i + 1][0] <= end
        )
        if shared or node.col_offset != 0:
            out.append((node, ast.unparse(node)))
        else:
            out.append((node, "\n".join(lines[start - 1 : end]) + "\n"))
    return out


def _scope_names(table: symtable.SymbolTable) -> tuple[set[str], set[str], set[str]]:
    """(bound at module level, read at once, read when a function runs) for one statement."""
    binds: set[str] = set()
    now: set[str] = set()
    later: set[str] = set()
    for symbol in table.get_symbols():
        name = symbol.get_name()
        if symbol.is_assigned() or symbol.is_imported() or symbol.is_namespace():
            binds.add(name)
        if symbol.is_referenced():
            now.add(name)
    for child in table.get_children():
        _child_names(child, runs_now=True, binds=binds, now=now, later=later)
    return binds, now, later


#: symtable names of comprehension scopes (run at once, unlike ``lambda`` and ``def``).
_COMPREHENSIONS = frozenset({"listcomp", "setcomp", "dictcomp", "genexpr"})


def _child_names(
    table: symtable.SymbolTable, *, runs_now: bool, binds: set, now: set, later: set
) -> None:
    # A class body and a comprehension run when the enclosing code runs; a function
    # or lambda body only when called (then it sees the kernel's final globals).
    kind = table.get_type()
    kind = getattr(kind, "value", kind)  # an enum from Python 3.13
    runs = runs_now and (kind == "class" or table.get_name() in _COMPREHENSIONS)
    for symbol in table.get_symbols():
        if symbol.is_declared_global() and symbol.is_assigned():
            binds.add(symbol.get_name())  # `global X; X = ...` binds X when called
        if symbol.is_global() and symbol.is_referenced():
            (now if runs else later).add(symbol.get_name())
    for child in table.get_children():
        _child_names(child, runs_now=runs, binds=binds, now=now, later=later)


def _mutated(node: ast.stmt) -> set[str]:
    """Names a module-level statement changes from their previous value.

    The roots of subscript and attribute targets (``d[k] = v``, ``obj.x = v``)
    and the name of an augmented assignment (``N += 1``).
    """
    if isinstance(node, ast.AugAssign) and isinstance(node.target, ast.Name):
        return {node.target.id}
    if isinstance(node, ast.Assign):
        targets = node.targets
    elif isinstance(node, (ast.AugAssign, ast.AnnAssign)):
        targets = [node.target]
    elif isinstance(node, ast.Delete):
        targets = node.targets
    else:
        return set()
    roots = set()
    for target in targets:
        for sub in ast.walk(target):
            if isinstance(sub, (ast.Subscript, ast.Attribute)) and isinstance(
                sub.ctx, (ast.Store, ast.Del)
            ):
                base = sub.value
                while isinstance(base, (ast.Subscript, ast.Attribute)):
                    base = base.value
                if isinstance(base, ast.Name):
                    roots.add(base.id)
    return roots


def _mutated_inside(node: ast.stmt) -> set[str]:
    """Names changed (:func:`_mutated`) by statements nested in a compound statement
    (``for k in KEYS: PARAMS[k] = 0``), not inside functions or classes it defines."""
    found: set[str] = set()
    if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
        return found
    for field_name in ("body", "orelse", "finalbody", "handlers", "cases"):
        for child in getattr(node, field_name, None) or ():
            if isinstance(child, ast.stmt):
                found |= _mutated(child) | _mutated_inside(child)
            else:  # an except handler or a match case: its statements
                for stmt in child.body:
                    found |= _mutated(stmt) | _mutated_inside(stmt)
    return found


def _timed_statements(tree: ast.Module) -> list[tuple[ast.stmt, str]]:
    """The statements of ``%time STATEMENT`` line magics (they run in the user's namespace)."""
    found = []
    for node in ast.walk(tree):
        args = _shell_call(node, "run_line_magic", 2)
        if args is not None and args[0] == "time":
            try:
                found += [(n, ast.unparse(n)) for n in ast.parse(args[1]).body]
            except (SyntaxError, ValueError):
                pass
    return found


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
    from robolab.grading.labs import Lab, LabError, project_root

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
    problems = [
        CellProblem(cell.index, "syntax", _syntax_message(cell.error), labels[cell.index])
        for cell in cells
        if cell.error is not None and set(_DEF_LINE.findall(raw[cell.index])) & wanted
    ]
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


def _syntax_message(exc: SyntaxError) -> str:
    where = f"line {exc.lineno}" if exc.lineno else "somewhere"
    text = f": {exc.text.strip()}" if exc.text and exc.text.strip() else ""
    return f"it does not parse, so nothing in it is defined: {exc.msg} ({where}{text})"
