"""The student edition: stub notebooks, the library and the data; no solutions, no hidden tests.

``build_release(out)`` writes::

    out/notebooks/NN_<lab>.ipynb   stubs, outputs cleared (refused if an exercise is not a stub)
    out/robolab/                   the package (the grader ships too: it holds no answers)
    out/robolab/data/              the bundled data, as package data (``robolab.DATA_DIR``)
    out/README.md                  how to work through the labs and check them
    out/pyproject.toml             the repository's, with the ``solutions`` package left out
    out/dist/robolab-*.whl         with ``wheel=True``: the edition as one installable file

and never ``solutions/``, ``tests/`` or ``examples/``.
"""

from __future__ import annotations

import ast
import shutil
import subprocess
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

## On your machine

    python -m venv .venv && .venv/bin/pip install -e '.[lab]'
    .venv/bin/jupyter lab notebooks/

or, with only the wheel (`dist/robolab-*.whl`) and a notebook:

    pip install "$(ls robolab-*.whl)[lab]" && jupyter lab

(`[lab]` adds JupyterLab; without it robolab installs only what the labs import, for
a Jupyter you already have.)

The maps, bags and data sets come inside the package (`robolab.DATA_DIR`), so a
notebook runs from any folder.

## On Google Colab

Upload the notebook, then make this its first cell and run it (replace the
address with the one your course gives for the wheel, or upload the wheel and
write its file name):

    %pip install --quiet "robolab @ https://example.org/your-course/robolab-0.1.0-py3-none-any.whl"

Colab then has everything the labs import (numpy, scipy, matplotlib,
ipywidgets, rosbags, filterpy); sliders and animations work there too.

## Checking your work

Check a whole notebook from a terminal:

    robolab check notebooks/<NN_lab>.ipynb

The visible checks are quick and friendly, and weaker than the tests your work
is graded with: passing them is a good sign, not a grade. Submit the notebook
file itself. What is graded: the functions your notebook defines when it runs
top to bottom (the last definition of a name wins), with the names and
signatures as given; cells that only show, plot or check cost nothing.

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
    extras = config["project"].get("optional-dependencies", {})
    if "lab" in extras:  # the student's JupyterLab; the instructor's extras stay behind
        parts.append(_table("project.optional-dependencies", {"lab": extras["lab"]}))
    if scripts := config["project"].get("scripts"):
        parts.append(_table("project.scripts", scripts))
    parts.append(_table("tool.setuptools.packages.find", {"include": ["robolab*"]}))
    package_data = dict(config.get("tool", {}).get("setuptools", {}).get("package-data", {}))
    # The bundled data travels inside the package, so a wheel install finds it.
    package_data["robolab"] = sorted({*package_data.get("robolab", []), "data/*"})
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


def build_wheel(edition: Path) -> Path:
    """Build the wheel of a student edition into ``edition/dist`` and return its path.

    Uses ``pip wheel`` on the edition's own ``pyproject.toml`` (so the wheel holds
    exactly the edition: ``robolab`` with its data, no ``solutions``).

    Raises
    ------
    ReleaseError
        When pip cannot build it (its last lines of output are in the message).
    """
    dist = edition / "dist"
    dist.mkdir(exist_ok=True)
    for old in dist.glob("robolab-*.whl"):
        old.unlink()
    cmd = [sys.executable, "-m", "pip", "wheel", "--quiet", "--no-deps", "-w", str(dist)]
    try:
        import setuptools

        if int(setuptools.__version__.split(".")[0]) >= 68:
            cmd.append("--no-build-isolation")  # offline, with the build tools already here
    except ImportError:
        pass
    proc = subprocess.run(cmd + [str(edition)], capture_output=True, text=True, check=False)
    wheels = sorted(dist.glob("robolab-*.whl"))
    if proc.returncode != 0 or not wheels:
        tail = "\n".join((proc.stdout + proc.stderr).strip().splitlines()[-8:])
        raise ReleaseError(f"building the wheel of {edition} failed:\n{tail}")
    # pip leaves its build folder in the edition; the wheel is what ships.
    for junk in ("build", "robolab.egg-info"):
        shutil.rmtree(edition / junk, ignore_errors=True)
    return wheels[-1]


def build_release(out: Path, root: Path | None = None, *, wheel: bool = False) -> Path:
    """Write the student edition of the project at ``root`` into ``out`` and return ``out``.

    Parameters
    ----------
    out : Path
        A new or empty folder, or an earlier release (it is replaced).
    root : Path, optional
        The project; default the one this package belongs to.
    wheel : bool
        Also build ``out/dist/robolab-<version>-py3-none-any.whl`` (:func:`build_wheel`).

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
        shutil.copytree(root / "data", out / "robolab" / "data", ignore=_IGNORE)
    (out / "notebooks").mkdir()
    for nb in sorted((root / "notebooks").glob("*.ipynb")):
        _release_notebook(nb, out / "notebooks" / nb.name)
    (out / "README.md").write_text(STUDENT_README)
    (out / "pyproject.toml").write_text(student_pyproject(root))
    (out / MARKER_FILE).write_text("built by `robolab release`; safe to delete and rebuild\n")
    if wheel:
        build_wheel(out)
    return out
