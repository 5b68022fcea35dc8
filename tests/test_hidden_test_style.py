"""Hidden tests speak to the student: every check says what it checked, on what, expected vs got.

A hidden test's failure is all a student sees of it (the grader never shows its
source), so, read from the AST of ``tests/labs/test_<lab>.py``:

- every test function has a docstring whose first paragraph, the check's title in
  the feedback, is a whole sentence (it ends with a period);
- every ``assert`` statement has a message;
- every ``numpy.testing.assert_*`` call has ``err_msg=``;
- no ``numpy.testing.assert_*`` compares an error (a difference, ``angle_diff``) with
  0: numpy prints the error as ACTUAL against DESIRED 0, so the student reads their
  error as their result; assert its size with a message that calls it an error;
- refusals go through the ``refuses`` fixture, which names the bad input when the
  function accepts it (``pytest.raises`` can only say "DID NOT RAISE").
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

from robolab.grading.labs import discover_labs
from robolab.grading.running.pytest_plugin import title_of

LABS_DIR = Path(__file__).resolve().parent / "labs"
#: Labs whose hidden tests follow the rules; a lab joins once its tests are rewritten.
ENFORCED = [lab.name for lab in discover_labs() if lab.hidden_tests.is_file()]
#: How a title may end: a whole sentence.
SENTENCE_ENDS = (".", "?", "!")
#: Functions whose result is an error between two values (compared with 0, it is printed
#: as the student's ACTUAL result).
ERROR_FUNCTIONS = {"angle_diff", "wrap_angle", "wrap", "abs", "absolute", "norm", "hypot"}
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


def _is_zero(node: ast.AST) -> bool:
    return isinstance(node, ast.Constant) and not isinstance(node.value, bool) and node.value == 0


def _is_error(node: ast.AST) -> bool:
    """A difference of two values: ``a - b``, ``angle_diff(a, b)``, ``np.abs(a - b)``."""
    if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Sub):
        return True
    if isinstance(node, ast.Call):
        leaf = _dotted(node.func).rsplit(".", 1)[-1].lstrip("_")
        differs = leaf == "angle_diff" or any(_is_error(a) for a in node.args)
        return leaf in ERROR_FUNCTIONS and differs
    return False


def _compares_an_error(actual: ast.AST, desired: ast.AST) -> bool:
    """``error`` against 0, or ``cos(a - b)`` against 1 (an angle error in disguise)."""
    if _is_error(actual) and _is_zero(desired):
        return True
    cosine = isinstance(actual, ast.Call) and _dotted(actual.func).rsplit(".", 1)[-1] == "cos"
    one = isinstance(desired, ast.Constant) and desired.value == 1
    return cosine and one and any(_is_error(a) for a in actual.args)


def style_problems(path: Path) -> list[str]:
    """Every break of the rules in one hidden test module, as ``line: what``."""
    tree = ast.parse(path.read_text(), filename=str(path))
    bare = _numpy_testing_asserts(tree)
    problems = []
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and node.name.startswith(
            "test_"
        ):
            title = title_of(ast.get_docstring(node))
            if not title:
                problems.append(f"{node.lineno}: test {node.name} has no docstring")
            elif not title.endswith(SENTENCE_ENDS):
                problems.append(
                    f"{node.lineno}: test {node.name}: its title (the docstring's first "
                    f"paragraph) is not a whole sentence ending with a period: {title[-60:]!r}"
                )
        elif isinstance(node, ast.Assert) and node.msg is None:
            problems.append(f"{node.lineno}: assert without a message: {ast.unparse(node)[:80]}")
        elif isinstance(node, ast.Call):
            name = _dotted(node.func)
            leaf = name.rsplit(".", 1)[-1]
            via_module = ".testing.assert_" in f".{name}" or name.startswith("testing.assert_")
            if (via_module or name in bare) and leaf not in NO_ERR_MSG:
                if not any(k.arg == "err_msg" for k in node.keywords):
                    problems.append(f"{node.lineno}: {name}(...) without err_msg=")
                if len(node.args) >= 2 and _compares_an_error(node.args[0], node.args[1]):
                    problems.append(
                        f"{node.lineno}: {name}(error, 0) prints the error as ACTUAL against "
                        "DESIRED 0: assert the error's size, with a message naming it an error"
                    )
            if name == "pytest.raises" or name == "raises":
                problems.append(
                    f"{node.lineno}: pytest.raises cannot name the bad input in the feedback: "
                    'use the refuses fixture, `with refuses(ValueError, "sigma = -1"):`'
                )
            if leaf == "refuses" and not (
                len(node.args) == 2
                and isinstance(node.args[1], (ast.Constant, ast.JoinedStr, ast.Name))
                and (not isinstance(node.args[1], ast.Constant) or str(node.args[1].value).strip())
            ):
                problems.append(
                    f"{node.lineno}: refuses(error, bad_input) names the bad input in words"
                )
    return problems


@pytest.mark.parametrize("lab", ENFORCED)
def test_hidden_tests_explain_themselves(lab):
    """Every hidden test of the lab has a docstring and every assertion a message."""
    path = LABS_DIR / f"test_{lab}.py"
    problems = style_problems(path)
    assert not problems, f"{path.name}:\n  " + "\n  ".join(problems)


def test_the_style_check_catches_each_rule(tmp_path):
    """The checker finds each broken rule once, and nothing in a test that keeps them all."""
    bad = tmp_path / "test_bad.py"
    bad.write_text(
        "import numpy as np\n"
        "import pytest\n"
        "from numpy.testing import assert_array_equal as aae\n"
        "def test_a(lab, refuses):\n"
        "    assert lab.f() == 1\n"
        "    np.testing.assert_allclose(lab.f(), 1)\n"
        "    aae(lab.f(), 1)\n"
        "    with pytest.raises(ValueError):\n"
        "        lab.f(-1)\n"
        "    with refuses(ValueError, ''):\n"
        "        lab.f(-1)\n"
        "def test_b(lab):\n"
        '    """has a docstring\n'
        '    cut at its first line"""\n'
        '    np.testing.assert_allclose(angle_diff(lab.f(), 1.0), 0.0, err_msg="f()")\n'
        '    np.testing.assert_allclose(lab.f() - 1.0, 0, err_msg="f()")\n'
        '    np.testing.assert_allclose(np.cos(lab.f() - 1.0), 1.0, err_msg="f()")\n'
        "def test_c(lab, refuses):\n"
        '    """Keeps every rule: a whole sentence,\n'
        '    over two lines.\n\n    More words.\n    """\n'
        '    assert lab.f() == 1, "f() == 1"\n'
        '    np.testing.assert_allclose(lab.f(), 1, err_msg="f()")\n'
        '    np.testing.assert_allclose(abs(lab.f()), 0.0, err_msg="|f()| = 0, not an error")\n'
        '    with refuses(ValueError, f"x = {-1}"):\n'
        "        lab.f(-1)\n"
    )
    found = style_problems(bad)
    lines = sorted(int(p.split(":")[0]) for p in found)
    # 4: no docstring; 5: bare assert; 6, 7: no err_msg; 8: pytest.raises; 10: empty input;
    # 12: a title that is no sentence; 15, 16, 17: an error compared with 0 (or cos with 1)
    assert lines == [4, 5, 6, 7, 8, 10, 12, 15, 16, 17], (
        f"expected one problem per broken rule: {found}"
    )


# --- refusals are promised by the docstring the student reads --------------------------------

LABS_WITH_STUBS = [
    lab for lab in discover_labs() if lab.hidden_tests.is_file() and lab.notebook is not None
]


def _stub_docstrings(lab) -> dict[str, ast.FunctionDef]:
    import nbformat

    from robolab.grading.labs import exercise_cells

    nb = nbformat.read(str(lab.notebook), as_version=4)
    return {f.name: f for _, funcs in exercise_cells(nb) for f in funcs}


def raises_section(doc: str) -> str:
    """The numpy-style ``Raises`` section of a docstring ("" without one)."""
    lines = doc.splitlines()
    for i, line in enumerate(lines[:-1]):
        if line.strip() == "Raises" and set(lines[i + 1].strip()) == {"-"}:
            body = []
            for j in range(i + 2, len(lines)):
                if (
                    j + 1 < len(lines)
                    and lines[j + 1].strip()
                    and set(lines[j + 1].strip()) == {"-"}
                ):
                    break  # the next section's header
                body.append(lines[j])
            return "\n".join(body)
    return ""


def _loop_values(node: ast.AST, name: str, parents: dict) -> list[str]:
    """The string literals a ``for`` loop around ``node`` binds to ``name`` ([] if none)."""
    while node in parents:
        node = parents[node]
        if not isinstance(node, ast.For) or not isinstance(node.iter, (ast.Tuple, ast.List)):
            continue
        targets = node.target.elts if isinstance(node.target, ast.Tuple) else [node.target]
        where = [i for i, t in enumerate(targets) if isinstance(t, ast.Name) and t.id == name]
        if not where:
            continue
        items = [
            e.elts[where[0]]
            if isinstance(node.target, ast.Tuple) and isinstance(e, ast.Tuple)
            else e
            for e in node.iter.elts
        ]
        return [i.value for i in items if isinstance(i, ast.Constant) and isinstance(i.value, str)]
    return []


def _texts(desc: ast.AST, parents: dict) -> list[str]:
    """What a refusal's description can read: loop variables replaced by their literals."""
    names = [n.id for n in ast.walk(desc) if isinstance(n, ast.Name)]
    fixed = ast.unparse(desc)
    for name in names:
        fixed = fixed.replace("{" + name + "}", "").replace(name, "")
    values = [v for name in names for v in _loop_values(desc, name, parents)]
    return [fixed + " " + v for v in values] if values else [ast.unparse(desc)]


def _exception(name: str) -> type | None:
    """The exception class a dotted name in a docstring means (None when unknown)."""
    import builtins
    import importlib

    if "." not in name:
        found = getattr(builtins, name, None)
    else:
        module, _, leaf = name.rpartition(".")
        try:
            found = getattr(importlib.import_module(module), leaf, None)
        except ImportError:
            found = None
    return found if isinstance(found, type) and issubclass(found, BaseException) else None


def _documents(raises: str, error: str) -> bool:
    """Whether a Raises section lists ``error`` or a subclass of it (LinAlgError: ValueError)."""
    wanted = _exception(error)
    for line in raises.splitlines():
        name = line.strip()
        if not name or line[:1].isspace():  # an entry's description, not its name
            continue
        if name == error.rsplit(".", 1)[-1]:
            return True
        found = _exception(name)
        if wanted is not None and found is not None and issubclass(found, wanted):
            return True
    return False


def refusals(path: Path) -> list[tuple[int, str, list[str], str]]:
    """Every ``with refuses(Error, "input"):`` block: (line, error, input texts, exercise)."""
    tree = ast.parse(path.read_text(), filename=str(path))
    parents = {child: node for node in ast.walk(tree) for child in ast.iter_child_nodes(node)}
    found = []
    for node in ast.walk(tree):
        if not isinstance(node, ast.With):
            continue
        for item in node.items:
            call = item.context_expr
            if not (isinstance(call, ast.Call) and _dotted(call.func) == "refuses"):
                continue
            error = _dotted(call.args[0]) if call.args else ""
            texts = _texts(call.args[1], parents) if len(call.args) > 1 else [""]
            called = [
                sub.func.attr
                for stmt in node.body
                for sub in ast.walk(stmt)
                if isinstance(sub, ast.Call)
                and isinstance(sub.func, ast.Attribute)
                and _dotted(sub.func.value) == "lab"
            ]
            found.append((node.lineno, error, texts, called[0] if called else ""))
    return found


@pytest.mark.parametrize("lab", LABS_WITH_STUBS, ids=lambda lab: lab.name)
def test_every_refusal_is_documented_and_named(lab):
    """Each refusal a hidden test demands is in the stub's Raises section and names the input.

    A student can only refuse what the docstring they read asks them to refuse; and
    when their function accepts the input, the feedback must say which input it was
    (a parameter of the exercise, by name).
    """
    stubs = _stub_docstrings(lab)
    problems = []
    for line, error, texts, called in refusals(lab.hidden_tests):
        stub = stubs.get(called)
        if stub is None:
            problems.append(f"{line}: refuses(...) calls no exercise of the lab ({called!r})")
            continue
        raises = raises_section(ast.get_docstring(stub) or "")
        if not _documents(raises, error):
            problems.append(
                f"{line}: a test demands {error} from {called}, whose stub docstring has no "
                f"Raises entry for it"
            )
        params = [a.arg for a in stub.args.posonlyargs + stub.args.args + stub.args.kwonlyargs]
        for text in texts:
            if not any(re.search(rf"(?<![\w.]){re.escape(p)}\b", text) for p in params):
                problems.append(
                    f"{line}: refuses({error}, {text}) names none of {called}'s parameters {params}"
                )
    assert not problems, f"{lab.hidden_tests.name}:\n  " + "\n  ".join(problems)


def test_raises_section_reads_numpy_style():
    """The Raises reader takes the section's body up to the next section header."""
    doc = "Sum.\n\nRaises\n------\nValueError\n    If x < 0.\n\nNotes\n-----\nTypeError here."
    assert raises_section(doc).split() == ["ValueError", "If", "x", "<", "0."], raises_section(doc)
    assert raises_section("No sections.") == "", "a docstring without Raises has an empty one"
    singular = "numpy.linalg.LinAlgError\n    If H is singular."
    assert _documents(singular, "ValueError"), "LinAlgError is a ValueError: it documents one"
    assert not _documents("TypeError\n    ValueError in words.", "ValueError"), (
        "only an entry's name documents an exception, not its description"
    )
