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
import stat
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
    "display_path",
    "exercise_cells",
    "find_lab",
    "lab_of_notebook",
    "project_root",
    "read_notebook",
    "read_submission",
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


#: Largest notebook file read (bytes): a real one with figures is a few MiB.
MAX_NOTEBOOK_BYTES = 64 * 2**20
#: Deepest nesting of JSON arrays and objects accepted anywhere in a notebook
#: (nbformat's own documents nest about 8 deep).
MAX_NOTEBOOK_DEPTH = 100
_KINDS = {
    stat.S_IFDIR: "a folder",
    stat.S_IFIFO: "a named pipe (fifo)",
    stat.S_IFSOCK: "a socket",
    stat.S_IFCHR: "a character device",
    stat.S_IFBLK: "a block device",
}


def read_submission(path: str | os.PathLike) -> bytes:
    """The bytes of a submitted file, read without ever blocking or reading without end.

    ``path`` is opened non-blocking and must be a regular file (after symbolic
    links) of at most :data:`MAX_NOTEBOOK_BYTES`: a fifo, a device or a folder
    is refused rather than read.

    Raises
    ------
    LabError
        Naming ``path`` as given and what is wrong with it.
    """
    shown = display_path(path)
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_NOCTTY)
    except OSError as exc:
        raise LabError(f"{shown}: cannot read the notebook: {exc.strerror or exc}") from None
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            kind = _KINDS.get(stat.S_IFMT(info.st_mode), "not a regular file")
            raise LabError(f"{shown}: is not a notebook file: it is {kind}")
        if info.st_size > MAX_NOTEBOOK_BYTES:
            raise LabError(
                f"{shown}: is too large for a notebook ({info.st_size} bytes; "
                f"at most {MAX_NOTEBOOK_BYTES} are read)"
            )
        with os.fdopen(os.dup(fd), "rb") as f:
            data = f.read(MAX_NOTEBOOK_BYTES + 1)
    except OSError as exc:
        raise LabError(f"{shown}: cannot read the notebook: {exc.strerror or exc}") from None
    finally:
        os.close(fd)
    if len(data) > MAX_NOTEBOOK_BYTES:
        raise LabError(f"{shown}: is too large for a notebook (it grew while it was read)")
    return data


def read_notebook(path: str | os.PathLike) -> dict:
    """A submitted notebook's JSON document, checked to be a notebook's shape.

    Every failure, whatever the file holds (not UTF-8, not JSON, JSON nested
    thousands deep, numbers too long to convert, a list instead of an object,
    no cells, metadata that is not an object), is a :class:`LabError` with a
    one-line reason naming ``path`` as given, so that one bad file fails only
    its own submission.

    Raises
    ------
    LabError
        When the file cannot be read or is not a notebook.
    """
    shown = display_path(path)
    data = read_submission(path)
    try:
        nb = json.loads(data.decode("utf-8"))
    except UnicodeDecodeError as exc:
        raise LabError(f"{shown}: is not a notebook: not UTF-8 text ({exc.reason})") from None
    except json.JSONDecodeError as exc:
        raise LabError(
            f"{shown}: is not a notebook: not valid JSON "
            f"(line {exc.lineno} column {exc.colno}: {exc.msg})"
        ) from None
    except RecursionError:
        raise LabError(
            f"{shown}: is not a notebook: its JSON is nested too deeply to read"
        ) from None
    except ValueError as exc:  # a number of more digits than Python converts
        raise LabError(f"{shown}: is not a notebook: not valid JSON ({exc})") from None
    if not isinstance(nb, dict):
        raise LabError(
            f"{shown}: is not a notebook: its JSON is {type(nb).__name__}, not an object"
        )
    if not isinstance(nb.get("cells"), list):
        raise LabError(f"{shown}: is not a notebook: it has no list of cells")
    if not isinstance(nb.get("metadata", {}), dict):
        raise LabError(f"{shown}: is not a notebook: its metadata is not an object")
    depth = _depth(nb)
    if depth > MAX_NOTEBOOK_DEPTH:
        raise LabError(
            f"{shown}: is not a notebook: its JSON is nested {depth} levels deep "
            f"(at most {MAX_NOTEBOOK_DEPTH} are accepted)"
        )
    return nb


def _depth(value: object) -> int:
    """How deep JSON arrays and objects nest in ``value`` (iteratively: no recursion limit)."""
    deepest, level = 0, [value]
    while level:
        deepest += 1
        level = [
            child
            for item in level
            if isinstance(item, (dict, list))
            for child in (item.values() if isinstance(item, dict) else item)
            if isinstance(child, (dict, list))
        ]
    return deepest


def display_path(path: str | os.PathLike) -> str:
    """A path (or any text holding one) as UTF-8 text: bytes that were not UTF-8 become
    ``\\xNN`` (and any other lone surrogate ``\\uDNNN``)."""
    try:
        return os.fsencode(path).decode("utf-8", "backslashreplace")
    except UnicodeEncodeError:  # a surrogate that no file name produced
        return os.fspath(path).encode("utf-8", "backslashreplace").decode("utf-8")


def lab_of_notebook(path: Path) -> str | None:
    """The lab named in a notebook's metadata (``{"robolab": {"lab": ...}}``), or None.

    Raises
    ------
    LabError
        When the file is not a readable notebook (see :func:`read_notebook`).
    """
    meta = read_notebook(path).get("metadata", {})
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
