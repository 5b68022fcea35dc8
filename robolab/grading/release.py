"""The student edition: stub notebooks, the library and the data; no solutions, no hidden tests.

``build_release(out)`` writes::

    out/notebooks/NN_<lab>.ipynb   stubs, outputs cleared (refused if an exercise is not a stub)
    out/robolab/                   the package (the grader ships too: it holds no answers)
    out/data/                      the bundled data
    out/README.md                  how to work through the labs and check them
    out/pyproject.toml             the repository's, with the ``solutions`` package left out

and never ``solutions/``, ``tests/`` or ``examples/``.
"""

from __future__ import annotations

import ast
import shutil
import sys
from pathlib import Path

import nbformat

from robolab.grading.labs import exercise_cells, project_root

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

__all__ = ["MARKER_FILE", "ReleaseError", "build_release", "is_stub"]

#: File that marks a folder as a release, so that rebuilding may replace it.
MARKER_FILE = ".robolab-release"

_IGNORE = shutil.ignore_patterns("__pycache__", "*.pyc", ".ipynb_checkpoints", ".DS_Store")

STUDENT_README = """\
# robolab: probabilistic-robotics labs

One Jupyter notebook per lab in `notebooks/`. In each, fill in the cells that
say `# YOUR CODE HERE` and run the visible check below each exercise.

    python -m venv .venv && .venv/bin/pip install -e .
    .venv/bin/pip install jupyterlab
    .venv/bin/jupyter lab notebooks/

Check a whole notebook from a terminal:

    .venv/bin/robolab check notebooks/<NN_lab>.ipynb

The visible checks are quick and friendly, and weaker than the tests your work
is graded with: passing them is a good sign, not a grade. Submit the notebook
file itself; only the functions you define are graded, so keep their names and
signatures as given.

Units are metres, radians and seconds; angles are wrapped to [-pi, pi); poses
are `(x, y, theta)` and many poses an `(N, 3)` array.
"""


class ReleaseError(RuntimeError):
    """The release cannot be built safely: an exercise holds code, or ``out`` is not ours."""


def is_stub(func: ast.FunctionDef) -> bool:
    """True when the function's body is a docstring (optional) and ``raise NotImplementedError``."""
    body = list(func.body)
    if (
        body
        and isinstance(body[0], ast.Expr)
        and isinstance(body[0].value, ast.Constant)
        and isinstance(body[0].value.value, str)
    ):
        body = body[1:]
    allowed = (ast.Pass, ast.Raise)
    raises = [s for s in body if isinstance(s, ast.Raise)]
    return (
        bool(raises)
        and all(isinstance(s, allowed) for s in body)
        and all(
            isinstance(r.exc, (ast.Name, ast.Call)) and "NotImplementedError" in ast.unparse(r.exc)
            for r in raises
        )
    )


def _toml_value(value) -> str:
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float)):
        return repr(value)
    if isinstance(value, list):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return (
            "{ " + ", ".join(f"{_toml_key(k)} = {_toml_value(v)}" for k, v in value.items()) + " }"
        )
    raise ReleaseError(f"cannot write {type(value).__name__} to TOML")


def _toml_key(key: str) -> str:
    return key if key.replace("-", "").replace("_", "").isalnum() else _toml_value(key)


def _table(name: str, data: dict) -> str:
    return f"[{name}]\n" + "".join(f"{_toml_key(k)} = {_toml_value(v)}\n" for k, v in data.items())


def student_pyproject(root: Path) -> str:
    """The repository's packaging metadata for the student edition: ``robolab`` only."""
    config = tomllib.loads((root / "pyproject.toml").read_text())
    project = {
        k: v
        for k, v in config["project"].items()
        if k not in ("optional-dependencies", "scripts", "readme")
    }
    project["readme"] = "README.md"
    parts = [_table("build-system", config["build-system"]), _table("project", project)]
    if scripts := config["project"].get("scripts"):
        parts.append(_table("project.scripts", scripts))
    parts.append(_table("tool.setuptools.packages.find", {"include": ["robolab*"]}))
    package_data = config.get("tool", {}).get("setuptools", {}).get("package-data")
    if package_data:
        parts.append(_table("tool.setuptools.package-data", package_data))
    return "\n".join(parts)


def _release_notebook(src: Path, dst: Path) -> None:
    nb = nbformat.read(str(src), as_version=4)
    for index, funcs in exercise_cells(nb):
        solved = [f.name for f in funcs if not is_stub(f)]
        if solved:
            raise ReleaseError(
                f"{src}: exercise cell {index} holds code, not a stub: {', '.join(solved)}"
            )
    for cell in nb.cells:
        if cell.cell_type == "code":
            cell.outputs = []
            cell.execution_count = None
    nbformat.write(nb, str(dst))


def _prepare(out: Path, root: Path) -> None:
    out = out.resolve()
    if (
        out == root
        or root in out.parents
        and out.relative_to(root).parts[0]
        in ("robolab", "solutions", "tests", "notebooks", "data", "examples")
    ):
        raise ReleaseError(f"{out}: refusing to build the release inside the project's own folders")
    if out.exists() and any(out.iterdir()):
        if not (out / MARKER_FILE).is_file():
            raise ReleaseError(
                f"{out} exists and is not a robolab release; choose an empty or new folder"
            )
        shutil.rmtree(out)
    out.mkdir(parents=True, exist_ok=True)


def build_release(out: Path, root: Path | None = None) -> Path:
    """Write the student edition of the project at ``root`` into ``out`` and return ``out``.

    Raises
    ------
    ReleaseError
        When a notebook's exercise cell is not a stub, or ``out`` holds something else.
    """
    root = (root or project_root()).resolve()
    out = Path(out)
    _prepare(out, root)
    shutil.copytree(root / "robolab", out / "robolab", ignore=_IGNORE)
    if (root / "data").is_dir():
        shutil.copytree(root / "data", out / "data", ignore=_IGNORE)
    (out / "notebooks").mkdir()
    for nb in sorted((root / "notebooks").glob("*.ipynb")):
        _release_notebook(nb, out / "notebooks" / nb.name)
    (out / "README.md").write_text(STUDENT_README)
    (out / "pyproject.toml").write_text(student_pyproject(root))
    (out / MARKER_FILE).write_text("built by `robolab release`; safe to delete and rebuild\n")
    return out
