"""What a cell's statements bind and read, without running them (:mod:`symtable` and :mod:`ast`).

:mod:`robolab.grading.loading.notebook` asks, for each top-level statement of a cell:
which names it may bind at module level, which of them it binds *surely* (on
every way through it: a binding in one branch of an ``if``, a loop body, a
``try`` body whose handler passes or a ``with suppress(...)`` body may not
happen), which names it reads at once and which its functions read when called,
and whether its bindings can be known at all before it runs (``globals()``,
``exec``, ``setattr`` on the module, ``%run``, ``%store``, a star import:
:func:`is_opaque`). Nothing here executes student code (docs/grading.md section 1).
"""

from __future__ import annotations

import ast
import getopt
import os
import re
import shlex
import symtable

__all__ = [
    "ALL",
    "OPAQUE_LINE_MAGICS",
    "code_strings",
    "is_opaque",
    "looks_up_by_value",
    "mutated",
    "mutated_inside",
    "name_strings",
    "note_written",
    "run_in_namespace",
    "scope_names",
    "shell_call",
    "statements",
    "surely_binds",
    "timed_statements",
]


#: Line magics whose bindings cannot be known before running them.
OPAQUE_LINE_MAGICS = frozenset({"run", "store"})


#: Calls through which a cell binds names no analysis sees (``globals()[n] = f``,
#: ``vars()``/``locals()`` at module level: the module's namespace). ``exec(src)`` too,
#: unless given a namespace of its own (``exec(src, ns)`` binds in ``ns``).
_OPAQUE_CALLS = frozenset({"globals", "vars", "locals"})


def shell_call(node: ast.AST, method: str, count: int) -> list[str] | None:
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


#: "Every name": what a statement that never falls through (``raise``) binds for what follows.
ALL = object()


def surely_binds(body: list[ast.stmt]) -> set[str] | object:
    """Names every path through ``body`` binds, or :data:`ALL` when no path falls through.

    The statements of a cell are taken to run (one that raises stops the cell, and
    is reported); what a branch, a loop, a ``try`` or ``with suppress(...)`` binds
    is sure only when every way through it binds it.
    """
    sure: set[str] = set()
    for node in body:
        found = _statement_binds(node)
        if found is ALL:
            return ALL
        sure |= found
    return sure


def _both(a, b):
    if a is ALL:
        return b
    if b is ALL:
        return a
    return a & b


def _statement_binds(node: ast.stmt) -> set[str] | object:
    if isinstance(node, (ast.Raise, ast.Return, ast.Break, ast.Continue)):
        return ALL
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
            branch = surely_binds(node.body)
        elif taken is False:
            branch = surely_binds(node.orelse)
        else:
            branch = _both(surely_binds(node.body), surely_binds(node.orelse))
        return branch if branch is ALL else branch | walrus
    if isinstance(node, (ast.Try, getattr(ast, "TryStar", ast.Try))):
        normal = surely_binds(node.body + node.orelse)
        for handler in node.handlers:
            normal = _both(normal, surely_binds(handler.body))
        final = surely_binds(node.finalbody)
        return ALL if ALL in (normal, final) else normal | final
    if isinstance(node, (ast.With, ast.AsyncWith)):
        if any(_suppresses(item.context_expr) for item in node.items):
            return set()
        targets = {
            n.id
            for item in node.items
            for n in ast.walk(item.optional_vars or ast.Pass())
            if isinstance(n, ast.Name)
        }
        inner = surely_binds(node.body)
        return inner if inner is ALL else inner | targets
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


#: Words every opaque construct of :func:`is_opaque` contains (most cells have none:
#: they are not walked).
_OPAQUE_WORDS = re.compile(r"globals|exec|vars|locals|modules|__main__|setattr|delattr|magic")


def is_opaque(tree: ast.AST, text: str | None = None) -> bool:
    """Whether ``tree`` (of source ``text``, when given) may bind module names no analysis sees.

    ``globals()``, ``exec`` without a namespace of its own, module-level
    ``vars()``/``locals()``, ``sys.modules``, ``__main__``, ``setattr``/``delattr`` on
    a name that may be a module (``me = sys.modules[__name__]`` in another cell),
    ``%run`` and ``%store``.
    """
    if text is not None and not _OPAQUE_WORDS.search(text):
        return False
    for node in ast.walk(tree):
        if isinstance(node, ast.Call):
            func = node.func
            if isinstance(func, ast.Name) and func.id in _OPAQUE_CALLS:
                return True
            if isinstance(func, ast.Name) and func.id == "exec":
                if len(node.args) + len(node.keywords) < 2:
                    return True
            if isinstance(func, ast.Name) and func.id in ("setattr", "delattr") and node.args:
                target = node.args[0]
                if not (isinstance(target, ast.Name) and target.id in ("self", "cls")):
                    return True
            args = shell_call(node, "run_line_magic", 2)
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


def code_strings(tree: ast.AST) -> list[str]:
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


def note_written(files: dict[str, str], tree: ast.Module) -> None:
    """Record the file a ``%%writefile [-a] NAME`` cell writes, with its text."""
    _, line, body = shell_call(tree.body[0].value, "run_cell_magic", 3)
    try:
        words = shlex.split(line)
    except ValueError:
        return
    names = [w for w in words if w not in ("-a", "--append")]
    if len(names) == 1:
        name = os.path.normpath(names[0])
        append = len(names) < len(words)
        files[name] = (files.get(name, "") if append else "") + body


def run_in_namespace(tree: ast.AST, files: dict[str, str]) -> list[str]:
    """The text of the notebook-written files that ``%run`` runs in the notebook's namespace:
    with ``-i``, and ``.ipy`` files (IPython source)."""
    found = []
    for node in ast.walk(tree):
        args = shell_call(node, "run_line_magic", 2)
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


def looks_up_by_value(tree: ast.AST) -> bool:
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


def name_strings(tree: ast.AST) -> set[str]:
    """String constants of ``tree`` that are identifiers (names looked up by string)."""
    return {
        node.value
        for node in ast.walk(tree)
        if isinstance(node, ast.Constant)
        and isinstance(node.value, str)
        and node.value.isidentifier()
    }


def statements(python: str, tree: ast.Module) -> list[tuple[ast.stmt, str]]:
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


def scope_names(table: symtable.SymbolTable) -> tuple[set[str], set[str], set[str]]:
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


def mutated(node: ast.stmt) -> set[str]:
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


def mutated_inside(node: ast.stmt) -> set[str]:
    """Names changed (:func:`mutated`) by statements nested in a compound statement
    (``for k in KEYS: PARAMS[k] = 0``), not inside functions or classes it defines."""
    found: set[str] = set()
    if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
        return found
    for field_name in ("body", "orelse", "finalbody", "handlers", "cases"):
        for child in getattr(node, field_name, None) or ():
            if isinstance(child, ast.stmt):
                found |= mutated(child) | mutated_inside(child)
            else:  # an except handler or a match case: its statements
                for stmt in child.body:
                    found |= mutated(stmt) | mutated_inside(stmt)
    return found


def timed_statements(tree: ast.Module) -> list[tuple[ast.stmt, str]]:
    """The statements of ``%time STATEMENT`` line magics (they run in the user's namespace)."""
    found = []
    for node in ast.walk(tree):
        args = shell_call(node, "run_line_magic", 2)
        if args is not None and args[0] == "time":
            try:
                found += [(n, ast.unparse(n)) for n in ast.parse(args[1]).body]
            except (SyntaxError, ValueError):
                pass
    return found
