"""A cell's source as the Python IPython makes of it: magics, shell escapes, help.

A cell that parses as Python is kept as written; any other goes through IPython's own
``TransformerManager().transform_cell`` (imported only then: about 0.4 s). A cell magic
that runs its body as Python in the user namespace (``%%time``, ``%%capture``) becomes
its body; ``%%writefile`` is kept for :mod:`robolab.grading.loading.magics`.
"""

from __future__ import annotations

import ast
import functools

from robolab.grading.loading.bindings import shell_call

__all__ = ["FILE_CELL_MAGICS", "PYTHON_CELL_MAGICS", "to_python"]

#: Cell magics whose body runs as Python in the user's namespace, so its definitions persist.
#: ``%%timeit`` is not one: its body runs inside a timing function (nothing it defines persists).
PYTHON_CELL_MAGICS = frozenset({"time", "capture"})
#: Cell magics that write their body to a file (``%%file`` is IPython's alias of ``%%writefile``):
#: kept as the ``run_cell_magic`` call, which the worker's shell runs in the notebook's folder.
FILE_CELL_MAGICS = frozenset({"writefile", "file"})


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
    args = shell_call(tree.body[0].value, "run_cell_magic", 3)
    return None if args is None else (args[0], args[2])
