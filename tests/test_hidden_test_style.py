"""Hidden tests speak to the student: every check says what it checked, on what, expected vs got.

A hidden test's failure is all a student sees of it (the grader never shows its
source), so, read from the AST of ``tests/labs/test_<lab>.py``:

- every test function has a docstring (its first line is the check's title);
- every ``assert`` statement has a message;
- every ``numpy.testing.assert_*`` call has ``err_msg=``.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

LABS_DIR = Path(__file__).resolve().parent / "labs"
#: Labs whose hidden tests follow the rules; a lab joins once its tests are rewritten.
ENFORCED = [
    "frames",
    "bayes",
    "beam_model",
    "landmark_pf",
    "demo",
    "odometry_mapping",
    "mcl",
    "ekf_mapping",
    "fastslam",
    "ekf_slam",
    "graph_slam",
]
#: numpy.testing functions without an err_msg parameter.
NO_ERR_MSG = {"assert_raises", "assert_raises_regex", "assert_warns", "assert_no_warnings"}


def _dotted(node: ast.AST) -> str:
    if isinstance(node, ast.Attribute):
        return f"{_dotted(node.value)}.{node.attr}"
    if isinstance(node, ast.Name):
        return node.id
    return ""


def _numpy_testing_asserts(tree: ast.Module) -> set[str]:
    """Names under which this module can call numpy.testing's asserts without the prefix."""
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module == "numpy.testing":
            names |= {a.asname or a.name for a in node.names if a.name.startswith("assert_")}
    return names


def style_problems(path: Path) -> list[str]:
    """Every break of the rules in one hidden test module, as ``line: what``."""
    tree = ast.parse(path.read_text(), filename=str(path))
    bare = _numpy_testing_asserts(tree)
    problems = []
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and node.name.startswith(
            "test_"
        ):
            if not (ast.get_docstring(node) or "").strip():
                problems.append(f"{node.lineno}: test {node.name} has no docstring")
        elif isinstance(node, ast.Assert) and node.msg is None:
            problems.append(f"{node.lineno}: assert without a message: {ast.unparse(node)[:80]}")
        elif isinstance(node, ast.Call):
            name = _dotted(node.func)
            leaf = name.rsplit(".", 1)[-1]
            via_module = ".testing.assert_" in f".{name}" or name.startswith("testing.assert_")
            if (via_module or name in bare) and leaf not in NO_ERR_MSG:
                if not any(k.arg == "err_msg" for k in node.keywords):
                    problems.append(f"{node.lineno}: {name}(...) without err_msg=")
    return problems


@pytest.mark.parametrize("lab", ENFORCED)
def test_hidden_tests_explain_themselves(lab):
    """Every hidden test of the lab has a docstring and every assertion a message."""
    path = LABS_DIR / f"test_{lab}.py"
    problems = style_problems(path)
    assert not problems, f"{path.name}:\n  " + "\n  ".join(problems)


def test_the_style_check_catches_each_rule(tmp_path):
    """The checker itself finds a missing docstring, a bare assert and an assert_allclose."""
    bad = tmp_path / "test_bad.py"
    bad.write_text(
        "import numpy as np\n"
        "from numpy.testing import assert_array_equal as aae\n"
        "def test_a(lab):\n"
        "    assert lab.f() == 1\n"
        "    np.testing.assert_allclose(lab.f(), 1)\n"
        "    aae(lab.f(), 1)\n"
        "def test_b(lab):\n"
        '    """has a docstring"""\n'
        '    assert lab.f() == 1, "f() == 1"\n'
        '    np.testing.assert_allclose(lab.f(), 1, err_msg="f()")\n'
    )
    found = style_problems(bad)
    assert len(found) == 4, f"expected 4 problems (docstring, assert, 2 calls), got {found}"
