"""Build the notebooks of the mutation suite (see README.md in this folder).

A *mutant* is a file ``tests/labs/mutants/<lab>/<name>.py`` holding one complete
exercise function with exactly one plausible student mistake, its module
docstring naming the mistake (first line) and its class (a ``class: <name>``
line, one of :data:`CLASSES`). Module-level imports in the file are kept (they
make it lintable and importable); imports from ``solutions`` are dropped when
it is spliced, since the solved notebook defines those helpers already.

A mutant's notebook is the lab's solved notebook (``robolab solve``) with that
one function's definition replaced by the mutant's source. To keep ``make
test`` quick, mutants of *independent* exercises share a notebook: two
exercises are independent when neither is below the other (the grader's
dependency table, robolab.grading.running.answers), so each one's points depend
only on its own mutant, and what a notebook loses elsewhere is collateral.

Two more variants per lab grade the "free points" problem: every exercise
raising ValueError, and every exercise returning its first argument.
"""

from __future__ import annotations

import ast
import textwrap
from dataclasses import dataclass
from pathlib import Path

import nbformat

from robolab.grading.exports.solve import solve_notebook
from robolab.grading.labs import Lab, exercise_cells
from robolab.grading.running.answers import dependency_table

HERE = Path(__file__).resolve().parent

#: The mistake classes of issue 15 (and two general ones), with the words used in reports.
CLASSES = {
    "boundary": "a value at the boundary of a validity interval",
    "refusal": "an input the text says to refuse, accepted",
    "underflow": "numerics that break when a component vanishes (the log form)",
    "degenerate-weights": "a step where every weight vanishes",
    "angle-wrap": "angles far from 0 or near +-pi",
    "incoming-weights": "incoming weights that are not uniform",
    "self-consistency": "a value an oracle knows (a running average, a sum)",
    "empty-map": "a step that starts from an empty or partially known map",
    "jacobian-point": "where a Jacobian is evaluated",
    "reported-estimate": "which estimate is reported",
    "aliasing": "modifying an argument in place, or returning a view of it",
    "formula": "a wrong core formula (a sign, a transpose, a missing factor)",
    "result-type": "the wrong type, shape or exactness of the result",
    "delegation": "calling the library's own version of the exercise",
    "minimum-size": "the smallest valid input: one pose, particle, beam, landmark or state",
}


@dataclass(frozen=True)
class Mutant:
    """One mistake in one exercise function."""

    lab: str
    name: str  # the file's stem
    exercise: str  # the function it defines
    mistake: str  # the docstring's first line
    kind: str  # its class, a key of CLASSES
    source: str  # what replaces the exercise's definition: imports, then the function

    @property
    def id(self) -> str:
        return f"{self.lab}/{self.name}"


class MutantError(ValueError):
    """A mutant file does not follow the format of README.md."""


def read_mutant(path: Path, lab: str) -> Mutant:
    """Parse one mutant file; raise MutantError when it breaks the format."""
    text = path.read_text()
    tree = ast.parse(text, filename=str(path))
    doc = ast.get_docstring(tree) or ""
    body = tree.body[1:] if doc else tree.body
    funcs = [n for n in body if isinstance(n, ast.FunctionDef)]
    other = [n for n in body if not isinstance(n, (ast.FunctionDef, ast.Import, ast.ImportFrom))]
    if len(funcs) != 1 or other:
        raise MutantError(
            f"{path}: a mutant holds imports and exactly one function, got "
            f"{len(funcs)} functions and {len(other)} other statements"
        )
    kinds = [
        line.split(":", 1)[1].strip()
        for line in doc.splitlines()
        if line.strip().lower().startswith("class:")
    ]
    if not doc.strip() or len(kinds) != 1 or kinds[0] not in CLASSES:
        raise MutantError(
            f"{path}: the docstring must name the mistake on its first line and hold one "
            f"'class: <name>' line with a name from {sorted(CLASSES)}, got {kinds}"
        )
    keep = []
    for node in body:
        if isinstance(node, ast.ImportFrom) and (
            (node.module or "").split(".")[0] == "solutions" or node.module == "__future__"
        ):
            continue
        keep.append(ast.get_source_segment(text, node, padded=False))
    return Mutant(
        lab=lab,
        name=path.stem,
        exercise=funcs[0].name,
        mistake=doc.strip().splitlines()[0].strip(),
        kind=kinds[0],
        source="\n\n\n".join(keep) + "\n",
    )


def mutants_of(lab: str) -> list[Mutant]:
    """Every mutant of ``lab``, sorted by file name (none when the folder does not exist)."""
    folder = HERE / lab
    return [read_mutant(p, lab) for p in sorted(folder.glob("*.py")) if not p.name.startswith("_")]


def labs_with_mutants() -> list[str]:
    """Names of the labs that have a mutant folder."""
    return sorted(p.name for p in HERE.iterdir() if p.is_dir() and not p.name.startswith("_"))


# --- notebooks ---------------------------------------------------------------------------------


def solved(lab: Lab) -> nbformat.NotebookNode:
    """The lab's stub notebook with the reference solution in every exercise cell."""
    return solve_notebook(nbformat.read(str(lab.notebook), as_version=4), lab)


def exercises(lab: Lab) -> list[str]:
    """The lab's exercise function names, in notebook order."""
    nb = nbformat.read(str(lab.notebook), as_version=4)
    return [f.name for _, funcs in exercise_cells(nb) for f in funcs]


def replace_function(nb: nbformat.NotebookNode, name: str, source: str) -> nbformat.NotebookNode:
    """A copy of ``nb`` in which the exercise cell's definition of ``name`` is ``source``."""
    out = nbformat.from_dict(nb)
    for index, funcs in exercise_cells(out):
        node = next((f for f in funcs if f.name == name), None)
        if node is None:
            continue
        cell = out.cells[index]
        lines = cell.source.splitlines()
        start = min([node.lineno] + [d.lineno for d in node.decorator_list]) - 1
        lines[start : node.end_lineno] = source.rstrip("\n").splitlines()
        cell.source = "\n".join(lines) + "\n"
        return out
    raise MutantError(f"no exercise cell defines {name}")


def _signature(node: ast.FunctionDef) -> str:
    return ast.unparse(node.args)


def _first_argument(node: ast.FunctionDef) -> str | None:
    positional = node.args.posonlyargs + node.args.args
    return positional[0].arg if positional else None


#: The "free points" notebooks: every exercise replaced by a function that only ...
FREE_POINTS = {
    "raises": "raises ValueError (a refusal of every input)",
    "echo": "returns its first argument unchanged",
    "zeros": "returns zeros of the right shape (the reference's result, zeroed)",
    "clobber": "zeroes every array it is given, in place, and returns its first argument",
}

#: A cell put before the exercises of the "zeros" and "clobber" notebooks. ``{solution}``
#: is the reference module's source: the zeros stub needs the shape of the right answer.
_HELPERS = """\
import dataclasses as _dataclasses
import numbers as _numbers

import numpy as _np

_REFERENCE = {{"__name__": "_reference"}}
exec(compile({solution!r}, "reference", "exec"), _REFERENCE)


def _zeros_like(x):
    if isinstance(x, _np.ndarray):
        return _np.zeros_like(x)
    if hasattr(x, "tocsr") and hasattr(x, "shape"):  # a scipy.sparse matrix: no entries
        return type(x)(x.shape, dtype=x.dtype)
    if isinstance(x, (bool, _np.bool_)):
        return False
    if isinstance(x, _numbers.Number):  # int, float, Fraction, numpy scalars
        return type(x)(0)
    if isinstance(x, (tuple, list)):
        return type(x)(_zeros_like(v) for v in x)
    if isinstance(x, dict):
        return {{k: _zeros_like(v) for k, v in x.items()}}
    if _dataclasses.is_dataclass(x):
        arrays = {{
            f.name: _np.zeros_like(getattr(x, f.name))
            for f in _dataclasses.fields(x)
            if isinstance(getattr(x, f.name), _np.ndarray)
        }}
        return _dataclasses.replace(x, **arrays)
    return x


def _clobber(x):
    if isinstance(x, _np.ndarray) and x.flags.writeable and x.dtype.kind in "biufc":
        x[...] = 0
    elif isinstance(x, (tuple, list)):
        for v in x:
            _clobber(v)
    elif isinstance(x, dict):
        for v in x.values():
            _clobber(v)
"""


def _standalone_source(path: Path) -> str:
    """A solution module's source that runs without ``solutions`` (submissions cannot import
    it): each ``from solutions.<m> import ...`` is replaced by module ``m``'s own source."""
    text = path.read_text()
    lines = text.splitlines()
    before: list[str] = []
    for node in reversed(ast.parse(text).body):
        if isinstance(node, ast.ImportFrom) and (
            node.module == "__future__" or (node.module or "").startswith("solutions.")
        ):
            if node.module != "__future__":
                module = path.parent / f"{node.module.split('.')[1]}.py"
                before.insert(0, _standalone_source(module))
            del lines[node.lineno - 1 : node.end_lineno]
    return "\n".join(before + lines) + "\n"


def _call_arguments(node: ast.FunctionDef) -> str:
    """The arguments that pass each parameter of ``node`` on, as in its own signature."""
    a = node.args
    parts = [p.arg for p in a.posonlyargs + a.args]
    parts += [f"*{a.vararg.arg}"] if a.vararg else []
    parts += [f"{p.arg}={p.arg}" for p in a.kwonlyargs]
    parts += [f"**{a.kwarg.arg}"] if a.kwarg else []
    return ", ".join(parts)


def _parameter_names(node: ast.FunctionDef) -> list[str]:
    a = node.args
    names = [p.arg for p in a.posonlyargs + a.args + a.kwonlyargs]
    return names + [v.arg for v in (a.vararg, a.kwarg) if v is not None]


def free_points_variant(lab: Lab, kind: str) -> nbformat.NotebookNode:
    """The solved notebook with every exercise replaced by a function that only does
    what :data:`FREE_POINTS` says for ``kind``. Each must earn 0: refusal tests pay only
    for working functions, invariance tests only when the values are right, and tests
    compare with copies of the inputs taken before the call.
    """
    if kind not in FREE_POINTS:
        raise ValueError(f"kind must be one of {sorted(FREE_POINTS)}, got {kind!r}")
    nb = solved(lab)
    stub = nbformat.read(str(lab.notebook), as_version=4)
    for _, funcs in exercise_cells(stub):
        for node in funcs:
            first = _first_argument(node)
            if kind == "raises" or (first is None and kind != "zeros"):
                body = 'raise ValueError("refused")'
            elif kind == "echo":
                body = f"return {first}"
            elif kind == "zeros":
                body = f"return _zeros_like(_REFERENCE[{node.name!r}]({_call_arguments(node)}))"
            else:
                names = ", ".join(_parameter_names(node))
                body = f"for _argument in ({names},):\n    _clobber(_argument)\nreturn {first}"
            src = f"def {node.name}({_signature(node)}):\n" + textwrap.indent(body, "    ")
            nb = replace_function(nb, node.name, src)
    if kind in ("zeros", "clobber"):
        first_exercise = min(index for index, _ in exercise_cells(nb))
        helpers = _HELPERS.format(solution=_standalone_source(lab.solution))
        nb.cells.insert(first_exercise, nbformat.v4.new_code_cell(helpers))
    return nb


def _calls(lab: Lab) -> dict[str, frozenset[str]]:
    """For each exercise, the exercises below it: those the grader answers as the reference
    while it is graded (its reference solution's calls and the hidden tests' ``USES``)."""
    import importlib

    declared = getattr(importlib.import_module(f"tests.labs.test_{lab.name}"), "USES", None)
    return dependency_table(lab.solution, exercises(lab), declared)


def packs(lab: Lab, mutants: list[Mutant]) -> list[list[Mutant]]:
    """Group mutants into notebooks: one mutant per exercise, only independent exercises.

    Greedy: each mutant goes into the first group that has no mutant of its own
    exercise and none of an exercise that calls it or that it calls.
    """
    calls = _calls(lab)
    groups: list[list[Mutant]] = []
    for m in sorted(mutants, key=lambda m: (-len(calls.get(m.exercise, ())), m.name)):
        for group in groups:
            if all(
                g.exercise != m.exercise
                and g.exercise not in calls.get(m.exercise, ())
                and m.exercise not in calls.get(g.exercise, ())
                for g in group
            ):
                group.append(m)
                break
        else:
            groups.append([m])
    return groups


def pack_notebook(lab: Lab, group: list[Mutant], base: nbformat.NotebookNode | None = None):
    """The solved notebook with each mutant of ``group`` in place of its exercise."""
    nb = base if base is not None else solved(lab)
    for m in group:
        nb = replace_function(nb, m.exercise, m.source)
    return nb
