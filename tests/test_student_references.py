"""Every reference in a student notebook resolves to what the student has.

A student gets the notebook, the library and Probabilistic Robotics; nothing else. So:

- a "section N" is a heading of the same notebook, unless the sentence cites the book;
- a constant named in backticks (``LOG_SPACE_BELOW``) is bound in the notebook or
  defined in the library, and a dotted ``robolab.x.y`` name imports;
- the text never sends the student to documents they do not have (handouts, course
  reports, other versions of the lab).
"""

from __future__ import annotations

import importlib
import json
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
NOTEBOOKS = sorted((ROOT / "notebooks").glob("[0-9][0-9]_*.ipynb"))
LIBRARY = "\n".join(p.read_text() for p in (ROOT / "robolab").rglob("*.py"))

HEADING = re.compile(r"^#{2,4}\s+(\d+(?:\.\d+)*)[.\s]", re.M)
SECTION = re.compile(r"\bsections?\s+(\d+(?:\.\d+)*)(?:\s+and\s+(\d+(?:\.\d+)*))?", re.I)
BOOK = re.compile(r"Probabilistic\s+Robotics|the book|Thrun|Table \d|chapter \d", re.I)
#: Named things of public software the text compares with (AMCL's source, ROS).
PUBLIC = re.compile(r"\bAMCL\b|\bROS\b|range_libc|filterpy", re.I)
CONSTANT = re.compile(r"`{1,2}([A-Z][A-Z0-9]*(?:_[A-Z0-9]+)+)`{1,2}")
DOTTED = re.compile(r"`{1,2}(robolab(?:\.\w+)+)(?:\(\))?`{1,2}")
ABSENT = re.compile(
    r"\bhandouts?\b|course report|versions? of this lab|lab sheet|\bassignment sheet", re.I
)


def _cells(path: Path) -> list[tuple[int, str, str]]:
    nb = json.loads(path.read_text(encoding="utf-8"))
    return [(i, c["cell_type"], "".join(c["source"])) for i, c in enumerate(nb["cells"], 1)]


def section_problems(text: str, headings: set[str]) -> list[str]:
    """The "section N" references of ``text`` that are neither a heading nor the book's."""
    problems = []
    for match in SECTION.finditer(text):
        sentence = text[max(0, match.start() - 160) : match.end() + 60]
        if BOOK.search(sentence):
            continue
        for number in filter(None, match.groups()):
            if number not in headings:
                problems.append(f"section {number} (no such heading)")
    return problems


def test_the_checks_see_what_they_must():
    """Each detector flags a dangling reference and lets a resolving one pass."""
    assert section_problems("see section 4", {"1", "2"}) == ["section 4 (no such heading)"]
    assert not section_problems("see section 2", {"2"})
    assert not section_problems("the beam model (Probabilistic Robotics, section 6.3)", set())
    assert section_problems("figures of sections 5 and 9", {"5", "7"})
    assert ABSENT.search("the corrections to the handout formulas")
    assert CONSTANT.findall("below ``LOG_SPACE_BELOW``") == ["LOG_SPACE_BELOW"]


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.stem)
def test_every_reference_in_a_notebook_resolves(path):
    cells = _cells(path)
    text = "\n".join(src for _, _, src in cells)
    headings = set(HEADING.findall("\n".join(s for _, kind, s in cells if kind == "markdown")))
    code = "\n".join(src for _, kind, src in cells if kind == "code")
    problems = []
    for index, _, source in cells:
        where = f"{path.name} cell {index}"
        problems += [f"{where}: {p}" for p in section_problems(source, headings)]
        problems += [f"{where}: refers to {m.group(0)!r}" for m in ABSENT.finditer(source)]
        for match in CONSTANT.finditer(source):
            name = match.group(1)
            if PUBLIC.search(source[max(0, match.start() - 80) : match.end()]):
                continue
            bound = re.search(rf"^\s*{name}\s*[:=]|import .*\b{name}\b", code, re.M)
            if not bound and not re.search(rf"^\s*{name}\s*[:=]", LIBRARY, re.M):
                problems.append(f"{where}: `{name}` is neither in the notebook nor the library")
        for dotted in set(DOTTED.findall(source)):
            if not _resolves(dotted):
                problems.append(f"{where}: `{dotted}` does not import")
    assert text and not problems, "\n".join(problems)


def _resolves(dotted: str) -> bool:
    parts = dotted.split(".")
    for cut in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:cut]))
        except ImportError:
            continue
        try:
            for attr in parts[cut:]:
                obj = getattr(obj, attr)
        except AttributeError:
            return False
        return True
    return False
