"""Add the figure audit to solved notebooks: a first cell loads it, a last cell reports.

Usage: ``python tools/add_figure_audit.py build/solved`` (``make test`` runs it before
nbval). The audit (:mod:`robolab.plotting.audit`) checks every figure and displayed
value against docs/figures.md; the last cell fails when anything is off.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

FIRST = "%load_ext robolab.plotting.audit"
LAST = "from robolab.plotting import audit\naudit.report()"


def _cell(source: str, index: int) -> dict:
    return {"cell_type": "code", "execution_count": None, "id": f"figure-audit-{index}",
            "metadata": {}, "outputs": [], "source": source}


def add_audit(path: Path) -> None:
    nb = json.loads(path.read_text(encoding="utf-8"))
    if any(c.get("id", "").startswith("figure-audit") for c in nb["cells"]):
        return
    nb["cells"] = [_cell(FIRST, 0), *nb["cells"], _cell(LAST, 1)]
    path.write_text(json.dumps(nb, indent=1, ensure_ascii=False) + "\n", encoding="utf-8")


if __name__ == "__main__":
    for folder in sys.argv[1:]:
        for notebook in sorted(Path(folder).glob("*.ipynb")):
            add_audit(notebook)
