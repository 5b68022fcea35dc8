"""Solved copies of lab notebooks: each exercise cell gets the reference solution's code.

For the functions an exercise cell defines, the solved cell holds the solution
module's import lines, then the module-level definitions those functions use
(private helpers ``_like_this``, UPPER_CASE constants, and any other
module-level name that no exercise cell defines; found transitively), then the
functions themselves, each exactly as written in ``solutions/<lab>.py``
(decorators and ``#:`` comments included). Outputs are cleared.
"""

from __future__ import annotations

import ast
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import nbformat

from robolab.grading.labs import Lab, exercise_cells, lab_of_notebook, project_root

__all__ = ["SolutionSource", "SolveError", "solve_notebook", "solve_paths"]


class SolveError(ValueError):
    """A notebook cannot be solved: no lab, a bad exercise cell, or a stub without a solution."""


def _defined_names(node: ast.stmt) -> list[str]:
    if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
        return [node.name]
    if isinstance(node, ast.Assign):
        return [t.id for t in node.targets if isinstance(t, ast.Name)]
    if isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
        return [node.target.id]
    return []


@dataclass(frozen=True)
class SolutionSource:
    """A solution module, parsed: its imports and the source of each module-level definition."""

    path: Path
    imports: tuple[str, ...]
    definitions: dict[str, tuple[int, str]]  # name -> (order in the module, source)
    uses: dict[str, frozenset[str]]  # name -> module-level names its source refers to

    @classmethod
    def read(cls, path: Path) -> SolutionSource:
        """Parse a solution module.

        A function imported from another solution module (``from solutions.landmark_pf
        import low_variance_resample``: a lab reusing an earlier lab's exercise) is
        inlined with the definitions and imports it needs, so a solved notebook never
        imports ``solutions``, which students and the grading worker cannot see.
        """
        text = path.read_text()
        lines = text.splitlines()
        tree = ast.parse(text, filename=str(path))
        imports, definitions, uses = [], {}, {}
        borrowed: list[tuple[SolutionSource, str]] = []
        for order, node in enumerate(tree.body):
            start = min([node.lineno] + [d.lineno for d in getattr(node, "decorator_list", [])]) - 1
            while start > 0 and lines[start - 1].lstrip().startswith("#"):
                start -= 1  # keep the comment that documents a constant or helper
            source = "\n".join(lines[start : node.end_lineno])
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("solutions."):
                other = cls.read(path.parent / (node.module.split(".", 1)[1] + ".py"))
                for alias in node.names:
                    if alias.asname not in (None, alias.name):
                        raise SolveError(
                            f"{path}: import {alias.name} from {node.module} without 'as' "
                            "(its source is inlined under its own name)"
                        )
                    borrowed.append((other, alias.name))
                continue
            if isinstance(node, (ast.Import, ast.ImportFrom)):
                imports.append(ast.get_source_segment(text, node) or source)
            for name in _defined_names(node):
                definitions[name] = (order, source)
                uses[name] = frozenset(n.id for n in ast.walk(node) if isinstance(n, ast.Name))
        for other, name in borrowed:
            if name not in other.definitions:
                raise SolveError(f"{path}: {other.path} defines no {name!r}")
            imports += [i for i in other.imports if i not in imports]
            for dep in [*other.dependencies([name], exclude=set()), name]:
                if dep not in definitions:  # borrowed code goes first, in its module's order
                    order, source = other.definitions[dep]
                    definitions[dep] = (order - len(other.definitions) - 1, source)
                    uses[dep] = other.uses[dep]
        return cls(path, tuple(imports), definitions, uses)

    def functions(self) -> list[str]:
        """Public function names, in module order."""
        tree = ast.parse(self.path.read_text())
        return [
            n.name
            for n in tree.body
            if isinstance(n, ast.FunctionDef) and not n.name.startswith("_")
        ]

    def dependencies(self, names: Iterable[str], exclude: set[str]) -> list[str]:
        """Module-level names ``names`` use, transitively, minus ``exclude``, in module order."""
        wanted = set(names)
        found: set[str] = set()
        todo = list(wanted)
        while todo:
            for used in self.uses.get(todo.pop(), ()):
                if (
                    used in self.definitions
                    and used not in found
                    and used not in wanted
                    and used not in exclude
                ):
                    found.add(used)
                    todo.append(used)
        return sorted(found, key=lambda n: self.definitions[n][0])

    def cell_source(self, names: Sequence[str], exclude: set[str]) -> str:
        """The solved source of an exercise cell defining ``names``."""
        missing = [n for n in names if n not in self.definitions]
        if missing:
            raise SolveError(f"{', '.join(missing)}: no such function in {self.path}")
        parts = ["\n".join(self.imports)] if self.imports else []
        parts += [self.definitions[n][1] for n in self.dependencies(names, exclude)]
        parts += [self.definitions[n][1] for n in names]
        return "\n\n\n".join(parts) + "\n"


def solve_notebook(nb: nbformat.NotebookNode, lab: Lab) -> nbformat.NotebookNode:
    """A solved copy of ``nb`` (a notebook of ``lab``), with every output cleared."""
    solved = nbformat.from_dict(nb)
    try:
        cells = exercise_cells(solved)
    except SyntaxError as exc:
        raise SolveError(str(exc)) from None
    if not lab.solution.is_file():
        raise SolveError(f"lab {lab.name!r} has no reference solution: expected {lab.solution}")
    solution = SolutionSource.read(lab.solution)
    exercises = {f.name for _, funcs in cells for f in funcs}
    for index, funcs in cells:
        names = [f.name for f in funcs]
        if not names:
            raise SolveError(f"exercise cell {index} defines no function")
        try:
            solved.cells[index].source = solution.cell_source(names, exclude=exercises)
        except SolveError as exc:
            raise SolveError(f"exercise cell {index}: {exc}") from None
    for cell in solved.cells:
        if cell.cell_type == "code":
            cell.outputs = []
            cell.execution_count = None
    return solved


def _notebooks(inputs: Sequence[Path]) -> list[Path]:
    found = []
    for p in inputs:
        if p.is_dir():
            found += sorted(q for q in p.glob("*.ipynb") if q.is_file())
        elif p.is_file():
            found.append(p)
        else:
            raise SolveError(f"{p}: no such notebook or folder")
    return found


def solve_paths(inputs: Sequence[Path], out: Path, root: Path | None = None) -> list[Path]:
    """Solve each notebook (folders: every ``*.ipynb`` in them) into ``out``; return the paths."""
    root = root or project_root()
    notebooks = _notebooks([Path(p) for p in inputs])
    names = [p.name for p in notebooks]
    if dupes := sorted({n for n in names if names.count(n) > 1}):
        raise SolveError(
            f"several inputs are named {', '.join(dupes)}; solve them into different folders"
        )
    out.mkdir(parents=True, exist_ok=True)
    written = []
    for path in notebooks:
        lab_name = lab_of_notebook(path)
        if lab_name is None:
            raise SolveError(f"{path}: no robolab.lab in the notebook's metadata")
        nb = nbformat.read(str(path), as_version=4)
        try:
            solved = solve_notebook(nb, Lab(lab_name, root))
        except SolveError as exc:
            raise SolveError(f"{path}: {exc}") from None
        target = out / path.name
        nbformat.write(solved, str(target))
        written.append(target)
    return written
