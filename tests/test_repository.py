"""The repository itself: no merge leftovers in any tracked text file."""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MARKER = re.compile(r"^(<{7}|>{7}) |^={7}$", re.M)


def test_no_conflict_markers_are_committed():
    files = subprocess.run(["git", "ls-files"], cwd=ROOT, capture_output=True, text=True)
    if files.returncode != 0:
        import pytest

        pytest.skip("not a git checkout")
    found = []
    for name in files.stdout.splitlines():
        path = ROOT / name
        text_file = path.suffix in {".py", ".md", ".toml", ".txt", ".yaml", ".yml", ".cfg"}
        if text_file or name == "Makefile":
            try:
                text = path.read_text(encoding="utf-8")
            except (OSError, UnicodeDecodeError):
                continue
            lines = (text[: m.start()].count("\n") + 1 for m in MARKER.finditer(text))
            found += [f"{name}:{line}" for line in lines]
    assert not found, found
