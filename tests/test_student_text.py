"""Student-facing text never refers to the course documents the labs were built from.

Students do not have those documents, and the word clashes with random seeds. The
scan covers everything the student edition ships: notebooks (prose, code comments and
strings), the student README and every docstring, comment and message of the
``robolab`` package (visible checks and feedback included). A use of "seed" is
allowed only where it means a random seed (``rng``, ``SEED``, ``seed=``, "random seed").
"""

from __future__ import annotations

import io
import json
import re
import tokenize
from pathlib import Path

import pytest

from robolab.grading.exports.release import build_release

ROOT = Path(__file__).resolve().parents[1]
WORD = re.compile(r"\bseed(?:s|'s)?\b", re.IGNORECASE)
#: Context (40 characters around a match) that makes it a random seed.
RANDOM = re.compile(
    r"(?i:random|rng|generator|np\.random|seed\s*[=,)\]]|seed\s?:\s*(?:int|float|none|optional)|"
    r"[\"']seed[\"']|_seed|seed_|seed files?|"
    r"seeds? per\b|different seeds|several seeds|same seed|fixed seeds?)|\bSEEDS?\b"
)


def violations(text: str) -> list[str]:
    """The phrases of ``text`` that use "seed" for something other than a random seed."""
    found = []
    for match in WORD.finditer(text):
        window = text[max(0, match.start() - 40) : match.end() + 40]
        if match.group(0) == "SEED" or RANDOM.search(window):
            continue
        found.append(" ".join(window.split()))
    return found


@pytest.fixture(scope="module")
def edition(tmp_path_factory) -> Path:
    return build_release(tmp_path_factory.mktemp("student") / "edition")


def prose_of_code(source: str) -> str:
    """The comments and string literals of Python source (identifiers are not prose)."""
    try:
        tokens = list(tokenize.generate_tokens(io.StringIO(source).readline))
    except (tokenize.TokenError, SyntaxError, IndentationError):
        return source  # magics or broken code: scan all of it
    kinds = (tokenize.COMMENT, tokenize.STRING) + tuple(
        getattr(tokenize, name) for name in ("FSTRING_MIDDLE",) if hasattr(tokenize, name)
    )
    return "\n".join(t.string for t in tokens if t.type in kinds)


def _texts(edition: Path):
    for path in sorted(edition.rglob("*")):
        if path.suffix == ".ipynb":
            nb = json.loads(path.read_text(encoding="utf-8"))
            for index, cell in enumerate(nb["cells"], start=1):
                text = "".join(cell["source"])
                if cell["cell_type"] == "code":
                    text = prose_of_code(text)
                yield f"{path.relative_to(edition)} cell {index}", text
        elif path.suffix == ".py":
            yield str(path.relative_to(edition)), prose_of_code(path.read_text(encoding="utf-8"))
        elif path.suffix in (".md", ".txt", ".yaml", ".toml"):
            yield str(path.relative_to(edition)), path.read_text(encoding="utf-8")


def test_the_scan_sees_a_reference_and_lets_a_random_seed_pass():
    """The detector flags a document reference and accepts the random-seed uses the labs make."""
    assert violations("as the seed's handout says") and violations("(seed 004, figure 2)")
    assert violations("Beyond the seed: log-odds mapping")
    for ok in ("rng = np.random.default_rng(SEED)", "FiducialRobot(seed=0)",
               "8 runs with different seeds", "the random seed of the run", "def f(seed, n):"):
        assert not violations(ok), ok
    assert "seeds" not in prose_of_code("seeds = range(8)  # eight runs")
    assert "the seed's" in prose_of_code('x = 1  # as in the seed\'s text')


def test_student_edition_never_cites_a_source_document(edition):
    """No notebook, README, check message or docstring of the edition cites a source document."""
    bad = [f"{where}: ...{phrase}..."
           for where, text in _texts(edition) for phrase in violations(text)]
    assert not bad, f"{len(bad)} reference(s) to source documents:\n" + "\n".join(bad[:60])


def _feedback_strings(path: Path):
    """What of a hidden-test module can reach a student's feedback: the docstrings of its
    tests (the title of each check) and every string literal inside a function (assertion
    messages, ``pytest.fail`` texts, f-strings). Module docstrings and comments cannot."""
    import ast

    tree = ast.parse(path.read_text(encoding="utf-8"))
    for node in ast.walk(tree):
        if not isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            continue
        doc = ast.get_docstring(node)
        if doc and node.name.startswith("test"):
            yield f"{path.name}:{node.lineno} {node.name} (title)", doc
        body = node.body[1:] if doc else node.body
        for stmt in body:
            for sub in ast.walk(stmt):
                if isinstance(sub, ast.Constant) and isinstance(sub.value, str):
                    yield f"{path.name}:{sub.lineno} {node.name}", sub.value


def test_hidden_test_feedback_never_cites_a_source_document():
    """The check titles and messages a student reads in feedback cite no source document."""
    bad = [
        f"{where}: ...{phrase}..."
        for path in sorted((ROOT / "tests" / "labs").glob("test_*.py"))
        for where, text in _feedback_strings(path)
        for phrase in violations(text)
    ]
    assert not bad, f"{len(bad)} reference(s) in feedback text:\n" + "\n".join(bad[:80])
