"""Progress bars in a notebook are one widget, not hundreds of text chunks in the saved output."""

from __future__ import annotations

import nbformat
import pytest
from nbclient import NotebookClient

CELL = """
from robolab.plotting import mcl_runs as mcl
for _ in mcl.tqdm(range(400), desc="scans", mininterval=0):
    pass
"""


@pytest.mark.slow
def test_a_long_loop_leaves_one_widget_and_no_text_chunks(tmp_path):
    """With ipywidgets installed, tqdm.auto draws a widget: no stderr text, no IProgress warning."""
    nb = nbformat.v4.new_notebook()
    nb.cells = [nbformat.v4.new_code_cell(CELL)]
    NotebookClient(nb, timeout=120, kernel_name="python3",
                   resources={"metadata": {"path": str(tmp_path)}}).execute()
    outputs = nb.cells[0].outputs
    streams = [o for o in outputs if o.get("output_type") == "stream"]
    assert not streams, f"text output from the progress bar: {[o['text'][:80] for o in streams]}"
    widget = "application/vnd.jupyter.widget-view+json"
    widgets = [o for o in outputs if widget in o.get("data", {})]
    assert len(widgets) == 1, outputs
