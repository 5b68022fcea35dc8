"""Build the lab notebooks from their text sources (jupytext percent format).

The source of truth of each lab is ``notebooks/NN_<lab>.py`` (jupytext's percent
format: ``# %%`` starts a code cell, ``# %% [markdown]`` a Markdown cell, and
``tags=["exercise"]`` after the marker keeps the cell's tags). The ``.ipynb`` next to it
is generated: students open it in Jupyter, and the grader, ``robolab solve`` and
``robolab release`` read it. ``tests/test_notebook_sources.py`` fails when the two
disagree.

Usage::

    python tools/sync_notebooks.py            # write every notebooks/*.ipynb from its .py
    python tools/sync_notebooks.py --check    # exit 1 and name the notebooks out of sync
    python tools/sync_notebooks.py --from-ipynb notebooks/04_odometry_mapping.ipynb
                                              # (re)write the .py from an edited .ipynb
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
from pathlib import Path

import jupytext

ROOT = Path(__file__).resolve().parents[1]
NOTEBOOKS = ROOT / "notebooks"
#: What the text source keeps of the notebook's and the cells' metadata.
NOTEBOOK_METADATA = "kernelspec,language_info,robolab"
CELL_METADATA = "tags"


def _existing_ids(target: Path) -> list[str]:
    try:
        return [c.get("id", "") for c in json.loads(target.read_text(encoding="utf-8"))["cells"]]
    except (OSError, ValueError, KeyError, TypeError):
        return []


def build(source: Path) -> str:
    """The ``.ipynb`` text generated from one percent-format source.

    Cell ids are kept from the existing ``.ipynb`` position by position (so an edit
    of the text changes only the cells it touches), and made from the cell's
    position and text where there is none: a rebuild is byte-identical.
    """
    nb = jupytext.read(source, fmt="py:percent")
    nb.metadata.pop("jupytext", None)
    ids = _existing_ids(source.with_suffix(".ipynb"))
    cells = []
    for index, cell in enumerate(nb.cells):
        cell_id = ids[index] if index < len(ids) and ids[index] else (
            hashlib.sha1(f"{source.stem}:{index}:{cell.source}".encode()).hexdigest()[:8]
        )
        out = {"cell_type": cell.cell_type}
        if cell.cell_type == "code":
            out["execution_count"] = None
        out["id"] = cell_id
        out["metadata"] = dict(cell.metadata)
        if cell.cell_type == "code":
            out["outputs"] = []
        out["source"] = cell.source.rstrip("\n").splitlines(keepends=True)
        cells.append(out)
    notebook = {"cells": cells, "metadata": dict(nb.metadata), "nbformat": 4, "nbformat_minor": 5}
    return json.dumps(notebook, indent=1, ensure_ascii=False) + "\n"


def to_text(notebook: Path) -> str:
    """The percent-format text of an ``.ipynb`` (to adopt an edit made in Jupyter)."""
    nb = jupytext.read(notebook)
    nb.metadata.setdefault("jupytext", {})
    nb.metadata["jupytext"]["notebook_metadata_filter"] = NOTEBOOK_METADATA
    nb.metadata["jupytext"]["cell_metadata_filter"] = CELL_METADATA
    nb.metadata["jupytext"].pop("text_representation", None)
    text = jupytext.writes(nb, fmt="py:percent")
    # jupytext records its own version in the header; drop it so upgrades do not churn.
    lines = text.splitlines(keepends=True)
    return "".join(line for line in lines if "jupytext_version" not in line)


def sources() -> list[Path]:
    return sorted(NOTEBOOKS.glob("[0-9][0-9]_*.py"))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="only report notebooks out of sync")
    parser.add_argument("--from-ipynb", nargs="+", type=Path, metavar="NB",
                        help="rewrite the .py sources of these notebooks from the .ipynb")
    args = parser.parse_args(argv)
    if args.from_ipynb:
        for nb in args.from_ipynb:
            nb.with_suffix(".py").write_text(to_text(nb), encoding="utf-8")
            print(f"wrote {nb.with_suffix('.py')}")
        return 0
    stale = []
    for source in sources():
        target = source.with_suffix(".ipynb")
        text = build(source)
        if target.is_file() and target.read_text(encoding="utf-8") == text:
            continue
        stale.append(target)
        if not args.check:
            target.write_text(text, encoding="utf-8")
            print(f"wrote {target.relative_to(ROOT)}")
    if args.check and stale:
        names = ", ".join(str(p.relative_to(ROOT)) for p in stale)
        print(f"out of sync with their .py source: {names}; run `make notebooks`", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
