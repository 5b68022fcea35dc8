"""Tests of the autograder: notebook loading, codec, sandbox, proxy, hostile submissions."""

from __future__ import annotations

import json
import time
from pathlib import Path

from robolab.grading.running.proxy import Limits

#: Small limits so that hostile tests fail fast.
TEST_LIMITS = Limits(
    cpu_seconds=2, wall_seconds=4, memory_bytes=2**30, max_processes=32, max_output_bytes=64 * 2**10
)


def write_notebook(
    path: Path, *cells: str, lab: str | None = "demo", tags: dict | None = None
) -> Path:
    """A notebook with one code cell per source (a markdown cell when it starts with '# md').

    Written as JSON directly, in the layout Jupyter saves (source as a list of lines).
    """
    nb_cells = []
    for index, source in enumerate(cells):
        lines = source.splitlines(keepends=True)
        if source.startswith("# md"):
            nb_cells.append({"cell_type": "markdown", "metadata": {}, "source": lines})
        else:
            metadata = {"tags": tags[index]} if tags and index in tags else {}
            nb_cells.append(
                {
                    "cell_type": "code",
                    "execution_count": None,
                    "metadata": metadata,
                    "outputs": [],
                    "source": lines,
                }
            )
    metadata = {"kernelspec": {"name": "python3", "display_name": "Python 3", "language": "python"}}
    if lab is not None:
        metadata["robolab"] = {"lab": lab}
    nb = {"cells": nb_cells, "metadata": metadata, "nbformat": 4, "nbformat_minor": 5}
    path.write_text(json.dumps(nb, indent=1))
    return path


def wait_for_idle_import(notebook: Path, module: str, seconds: float = 600.0) -> None:
    """Open submissions of ``notebook`` until a warm worker has ``module`` imported.

    For the zygote's idle imports: they start once it has served a batch's first
    submissions and then sits idle. Raises AssertionError when they never come.
    """
    from robolab.grading.running.proxy import open_submission

    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        with open_submission(notebook, limits=TEST_LIMITS) as later:
            if later.loaded(module):
                return
        time.sleep(0.5)
    raise AssertionError(f"the zygote never imported {module} while idle")
