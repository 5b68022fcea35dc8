"""`robolab release`: the student edition holds no solution code and no hidden test.

The release is built from a project root that mirrors this repository (links to
robolab/, solutions/, tests/, data/) and whose notebooks/ also holds the demo
lab's stub notebook, so that a lab with all its pieces is always released.
"""

from __future__ import annotations

import ast
import copy
import json
import os
import re
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import nbformat
import pytest

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10: the backport
    import tomli as tomllib

import robolab
from robolab.grading.exports.release import MARKER_FILE, ReleaseError, build_release, is_stub
from robolab.grading.exports.solve import solve_paths
from robolab.grading.labs import exercise_cells

REPO = Path(__file__).resolve().parents[3]
DEMO_STUB = REPO / "examples" / "demo_lab" / "demo.ipynb"


def mirror_root(path: Path, extra_notebooks: dict[str, Path]) -> Path:
    """A project root linking to the repository's folders, with extra notebooks added."""
    path.mkdir()
    for name in (
        "robolab",
        "solutions",
        "tests",
        "examples",
        "data",
        "pyproject.toml",
        "README.md",
    ):
        if (REPO / name).exists():
            (path / name).symlink_to(REPO / name)
    (path / "notebooks").mkdir()
    for nb in (REPO / "notebooks").glob("*.ipynb"):
        (path / "notebooks" / nb.name).symlink_to(nb)
    for name, src in extra_notebooks.items():
        shutil.copy(src, path / "notebooks" / name)
    return path


@pytest.fixture(scope="module")
def release(tmp_path_factory) -> Path:
    tmp = tmp_path_factory.mktemp("release")
    root = mirror_root(tmp / "project", {"99_demo.ipynb": DEMO_STUB})
    return build_release(tmp / "student", root)


def _normalise(text: str) -> str:
    return re.sub(r"\s+", " ", text).strip()


def _release_texts(release: Path) -> dict[Path, str]:
    """Every text file of the release, notebooks as their cells' sources and outputs."""
    texts = {}
    for path in release.rglob("*"):
        if not path.is_file():
            continue
        try:
            raw = path.read_text(encoding="utf-8")
        except UnicodeDecodeError:
            continue
        if path.suffix == ".ipynb":
            cells = json.loads(raw)["cells"]
            raw = (
                raw
                + "\n"
                + "\n".join("".join(c["source"]) + json.dumps(c.get("outputs", [])) for c in cells)
            )
        texts[path] = raw
    return texts


def _release_python(release: Path) -> list[tuple[Path, str]]:
    """Python sources of the release: .py files and notebook code cells."""
    sources = [(p, p.read_text()) for p in release.rglob("*.py")]
    for nb_path in release.rglob("*.ipynb"):
        nb = nbformat.read(str(nb_path), as_version=4)
        sources += [(nb_path, c.source) for c in nb.cells if c.cell_type == "code"]
    return sources


def _body(func: ast.FunctionDef) -> list[ast.stmt]:
    """A function's body without its docstring (stubs keep the docstring, never the code)."""
    body = func.body
    if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant):
        body = body[1:]
    return body


class _Renamer(ast.NodeTransformer):
    """Rename every identifier to its order of first appearance: ``w``/``weights`` -> ``v0``."""

    def __init__(self) -> None:
        self.names: dict[str, str] = {}

    def _new(self, name: str) -> str:
        return self.names.setdefault(name, f"v{len(self.names)}")

    def visit_Name(self, node: ast.Name) -> ast.Name:
        return ast.copy_location(ast.Name(self._new(node.id), node.ctx), node)

    def visit_arg(self, node: ast.arg) -> ast.arg:
        return ast.copy_location(ast.arg(self._new(node.arg)), node)


def _shape(func: ast.FunctionDef) -> str | None:
    """The body's structure with identifiers renamed, for bodies of 3+ statements."""
    body = _body(func)
    if sum(isinstance(n, ast.stmt) for b in body for n in ast.walk(b)) < 3:
        return None
    return ast.dump(_Renamer().visit(ast.Module(copy.deepcopy(body), [])))


def _functions(source: str) -> list[ast.FunctionDef]:
    try:
        tree = ast.parse(source)
    except SyntaxError:
        return []
    return [n for n in ast.walk(tree) if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef))]


def _body_text(text: str, func: ast.FunctionDef) -> str:
    body = _body(func)
    return (
        _normalise("\n".join(text.splitlines()[body[0].lineno - 1 : func.end_lineno]))
        if body
        else ""
    )


def _in_library():
    """A predicate: is this function's body, as code or as text, already in the robolab package?"""
    sources = [p.read_text() for p in (REPO / "robolab").rglob("*.py")]
    dumps = {ast.dump(ast.Module(_body(f), [])) for s in sources for f in _functions(s)}
    text = " ".join(_normalise(s) for s in sources)
    return lambda source, f: (
        ast.dump(ast.Module(_body(f), [])) in dumps or _body_text(source, f) in text
    )


def _secret_functions() -> list[tuple[str, str, ast.FunctionDef]]:
    """(file, source text, function) for every function of every solution and hidden test module.

    One exemption: a solution's private helper (``_name``) whose body is a
    function of the robolab library (a shared validation helper, say) is public
    by design, so its copy in the library is not a leak. Exercise functions and
    hidden tests are never exempt.
    """
    in_library = _in_library()
    files = [p for p in (REPO / "solutions").glob("*.py") if p.name != "__init__.py"]
    files += list((REPO / "tests" / "labs").glob("test_*.py"))
    return [
        (p.name, text, f)
        for p in files
        for text in [p.read_text()]
        for f in _functions(text)
        if not (p.parent.name == "solutions" and f.name.startswith("_") and in_library(text, f))
    ]


def test_no_secret_folders(release):
    assert sorted(p.name for p in release.iterdir()) == sorted(
        [MARKER_FILE, "README.md", "pyproject.toml", "notebooks", "robolab"]
    )
    pyproject = (release / "pyproject.toml").read_text()
    assert "solutions" not in pyproject
    config = tomllib.loads(pyproject)
    assert config["tool"]["setuptools"]["packages"]["find"]["include"] == ["robolab*"]
    assert config["project"]["scripts"]["robolab"] == "robolab.cli:main"
    assert "numpy>=2.0" in config["project"]["dependencies"]


def test_no_solution_or_hidden_test_code_structurally(release):
    """No function anywhere in the release has the body of a solution or hidden test function."""
    secret = {
        ast.dump(ast.Module(_body(f), [])): f"{name}:{f.name}"
        for name, _, f in _secret_functions()
        if _body(f)
    }
    shapes = {k: f"{name}:{f.name}" for name, _, f in _secret_functions() if (k := _shape(f))}
    assert any(v.startswith("demo.py") for v in secret.values())
    assert any(v.startswith("demo.py:normalize") for v in shapes.values())
    for path, source in _release_python(release):
        for func in _functions(source):
            key, shape = ast.dump(ast.Module(_body(func), [])), _shape(func)
            assert key not in secret, f"{path.relative_to(release)}: {func.name} is {secret[key]}"
            assert shape not in shapes, (
                f"{path.relative_to(release)}: {func.name} is {shapes[shape]}, renamed"
            )


def test_no_solution_or_hidden_test_text(release):
    """No solution body, hidden test function or grades marker line appears as text anywhere."""
    texts = {p: _normalise(t) for p, t in _release_texts(release).items()}
    needles = []
    for name, text, func in _secret_functions():
        lines = text.splitlines()
        if body := _body_text(text, func):  # the code of the function, without its docstring
            needles.append((f"{name}:{func.name} body", body))
        if name.startswith("test_"):
            start = min([func.lineno] + [d.lineno for d in func.decorator_list])
            needles.append(
                (f"{name}:{func.name}", _normalise("\n".join(lines[start - 1 : func.end_lineno])))
            )
            needles += [
                (f"{name}: marker", _normalise(d))
                for d in lines
                if d.strip().startswith("@pytest.mark.grades")
            ]
    assert len(needles) > 20
    for label, needle in needles:
        for path, text in texts.items():
            assert needle not in text, f"{label} appears in {path.relative_to(release)}"


def test_released_package_imports(release):
    code = (
        "import robolab, robolab.checks.demo, robolab.grading.commands;"
        "import robolab.grading.running.pytest_plugin;"
        "print(robolab.__file__)"
    )
    proc = subprocess.run([sys.executable, "-c", code], cwd=release, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    assert Path(proc.stdout.strip()).is_relative_to(release.resolve())


def test_released_package_finds_its_data_inside_itself(release, tmp_path):
    """The data ships as package data, so DATA_DIR works from any folder, without the repository."""
    code = "import robolab; print(robolab.DATA_DIR)"
    env = {**os.environ, "PYTHONPATH": str(release)}
    proc = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=env,
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    data_dir = Path(proc.stdout.strip())
    assert data_dir == (release / "robolab" / "data").resolve(), data_dir
    expected = sorted(p.name for p in (REPO / "data").iterdir() if p.is_file())
    assert sorted(p.name for p in data_dir.iterdir()) == expected
    config = tomllib.loads((release / "pyproject.toml").read_text())
    assert "data/*" in config["tool"]["setuptools"]["package-data"]["robolab"]


def test_wheel_holds_the_edition_and_its_data_only(tmp_path):
    """`robolab release` writes a wheel: robolab with its data and checks, no solutions or tests."""
    root = mirror_root(tmp_path / "project", {})
    out = build_release(tmp_path / "student", root=root, wheel=True)
    wheels = list((out / "dist").glob("robolab-*.whl"))
    assert len(wheels) == 1, wheels
    with zipfile.ZipFile(wheels[0]) as zf:
        names = zf.namelist()
    tops = {n.split("/")[0] for n in names}
    assert tops == {"robolab", f"robolab-{robolab.__version__}.dist-info"}, tops
    for needed in ("robolab/data/office.yaml", "robolab/data/localization.bag",
                   "robolab/checks/bayes.py", "robolab/grading/isolation/worker.py"):
        assert needed in names, f"{needed} missing from the wheel"
    assert not any("solutions" in n or n.startswith("tests/") for n in names)
    assert not (out / "build").exists(), "pip's build folder was left in the edition"


def test_released_notebook_keeps_its_stubs(release):
    stub = nbformat.read(str(DEMO_STUB), as_version=4)
    released = nbformat.read(str(release / "notebooks" / "99_demo.ipynb"), as_version=4)
    assert [c.source for c in released.cells] == [c.source for c in stub.cells]
    assert released.metadata["robolab"] == {"lab": "demo"}
    cells = exercise_cells(released)
    assert [f.name for _, fs in cells for f in fs] == ["normalize", "wrap", "mean_pose"]
    assert all(is_stub(f) for _, fs in cells for f in fs)
    for nb in (REPO / "notebooks").glob("*.ipynb"):
        assert (release / "notebooks" / nb.name).is_file()


def test_a_solved_notebook_is_refused(tmp_path):
    solved = solve_paths([DEMO_STUB], tmp_path / "solved")[0]
    root = mirror_root(tmp_path / "project", {"99_demo.ipynb": solved})
    with pytest.raises(ReleaseError, match="exercise cell 3 holds code, not a stub: normalize"):
        build_release(tmp_path / "student", root)


def test_rebuilds_a_release_but_never_overwrites_other_folders(tmp_path):
    root = mirror_root(tmp_path / "project", {})
    out = build_release(tmp_path / "student", root)
    (out / "stale.txt").write_text("old")
    build_release(out, root)
    assert not (out / "stale.txt").exists()
    precious = tmp_path / "precious"
    precious.mkdir()
    (precious / "thesis.tex").write_text("do not delete")
    with pytest.raises(ReleaseError, match="not a robolab release"):
        build_release(precious, root)
    assert (precious / "thesis.tex").is_file()
