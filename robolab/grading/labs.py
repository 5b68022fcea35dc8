"""Where a lab's pieces live, and what an exercise cell defines.

A lab named ``<lab>`` is the files ``solutions/<lab>.py``,
``tests/labs/test_<lab>.py``, ``robolab/checks/<lab>.py`` and a stub notebook,
``notebooks/NN_<lab>.ipynb`` (or, for a lab that exists only to test the grader,
``examples/<lab>_lab/<lab>.ipynb``). All paths hang off a project root: the
repository by default, or ``$ROBOLAB_ROOT`` (the Gradescope bundle sets it).
"""

from __future__ import annotations

import ast
import json
import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import nbformat

__all__ = [
    "EXERCISE_TAG",
    "Lab",
    "LabError",
    "discover_labs",
    "exercise_cells",
    "find_lab",
    "lab_of_notebook",
    "project_root",
]

#: Tag that marks a code cell holding exercise stubs.
EXERCISE_TAG = "exercise"

_NOTEBOOK_NAME = re.compile(r"^(\d\d)_([a-z][a-z0-9_]*)\.ipynb$")


class LabError(LookupError):
    """A lab, or one of its files, cannot be found or read."""


def project_root() -> Path:
    """The folder holding ``solutions/``, ``tests/labs/`` and ``notebooks/``.

    ``$ROBOLAB_ROOT`` when set, else the parent of the ``robolab`` package
    (the repository, for an editable install).
    """
    env = os.environ.get("ROBOLAB_ROOT")
    if env:
        return Path(env).resolve()
    import robolab

    return Path(robolab.__file__).resolve().parent.parent


@dataclass(frozen=True)
class Lab:
    """The files of one lab under ``root``; a missing file's property is still its expected path."""

    name: str
    root: Path

    @property
    def solution(self) -> Path:
        return self.root / "solutions" / f"{self.name}.py"

    @property
    def hidden_tests(self) -> Path:
        return self.root / "tests" / "labs" / f"test_{self.name}.py"

    @property
    def checks(self) -> Path:
        return self.root / "robolab" / "checks" / f"{self.name}.py"

    @property
    def notebook(self) -> Path | None:
        """The stub notebook, or None when the lab has none."""
        for path in sorted((self.root / "notebooks").glob(f"[0-9][0-9]_{self.name}.ipynb")):
            return path
        grader_only = self.root / "examples" / f"{self.name}_lab" / f"{self.name}.ipynb"
        return grader_only if grader_only.is_file() else None


def find_lab(name: str, root: Path | None = None) -> Lab:
    """Return the lab ``name``; raise LabError when it has no hidden tests."""
    if not re.fullmatch(r"[a-z][a-z0-9_]*", name or ""):
        raise LabError(f"{name!r} is not a lab name (lower-case letters, digits and underscores)")
    lab = Lab(name, (root or project_root()).resolve())
    if not lab.hidden_tests.is_file():
        raise LabError(f"lab {name!r} has no hidden tests: expected {lab.hidden_tests}")
    return lab


def discover_labs(root: Path | None = None) -> list[Lab]:
    """Every lab that has hidden tests, a solution or a stub notebook, sorted by name."""
    root = (root or project_root()).resolve()
    names = {p.stem[len("test_") :] for p in (root / "tests" / "labs").glob("test_*.py")}
    names |= {p.stem for p in (root / "solutions").glob("*.py") if not p.stem.startswith("_")}
    names |= {
        m.group(2)
        for p in (root / "notebooks").glob("*.ipynb")
        if (m := _NOTEBOOK_NAME.match(p.name))
    }
    return [Lab(n, root) for n in sorted(names)]


def lab_of_notebook(path: Path) -> str | None:
    """The lab named in a notebook's metadata (``{"robolab": {"lab": ...}}``), or None.

    Raises
    ------
    LabError
        When the file is not a readable notebook.
    """
    # Plain JSON rather than nbformat: this runs once per submission and nbformat is slow to import.
    try:
        with open(path, encoding="utf-8") as f:
            nb = json.load(f)
        meta = nb.get("metadata", {}) if isinstance(nb, dict) else None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise LabError(f"{path} is not a readable notebook: {exc}") from exc
    if not isinstance(meta, dict) or "cells" not in nb:
        raise LabError(f"{path} is not a Jupyter notebook (no cells and metadata)")
    robolab_meta = meta.get("robolab")
    lab = robolab_meta.get("lab") if isinstance(robolab_meta, dict) else None
    return lab if isinstance(lab, str) and lab else None


def exercise_cells(nb: nbformat.NotebookNode) -> list[tuple[int, list[ast.FunctionDef]]]:
    """The exercise cells of a notebook and the top-level functions each defines.

    Returns
    -------
    list of (cell index, function definitions)

    Raises
    ------
    SyntaxError
        When an exercise cell does not parse (stubs must be plain Python).
    """
    found = []
    for index, cell in enumerate(nb.cells):
        if cell.cell_type != "code" or EXERCISE_TAG not in cell.get("metadata", {}).get("tags", []):
            continue
        try:
            tree = ast.parse(cell.source)
        except SyntaxError as exc:
            raise SyntaxError(
                f"exercise cell {index} does not parse: {exc.msg} (line {exc.lineno})"
            ) from exc
        found.append((index, [n for n in tree.body if isinstance(n, ast.FunctionDef)]))
    return found
