"""Progress bars in a notebook: one widget while live, tqdm's final line in the saved output.

A widget's state is not saved with the notebook, so a bar drawn by tqdm.auto would be
saved as the text it had when drawn ("0%"); robolab's bars end on their summary line.
Checked through Jupyter itself (nbclient), as a notebook run headless would be saved.
"""

from __future__ import annotations

import nbformat
import pytest
from nbclient import NotebookClient

CELL = """
from robolab.plotting import mcl_runs
for _ in mcl_runs.progress_bar(range(400), desc="scans", mininterval=0):
    pass
for _ in mcl_runs.progress_bar(range(5), desc="inner", leave=False):
    pass
print("done")
"""


@pytest.mark.slow
def test_a_finished_loop_is_saved_as_its_summary_line_not_zero_percent(tmp_path):
    nb = nbformat.v4.new_notebook()
    nb.cells = [nbformat.v4.new_code_cell(CELL)]
    NotebookClient(nb, timeout=120, kernel_name="python3",
                   resources={"metadata": {"path": str(tmp_path)}}).execute()
    outputs = nb.cells[0].outputs
    streams = [o for o in outputs if o.get("output_type") == "stream"]
    assert [s["text"] for s in streams] == ["done\n"], "the bars wrote text to stdout/stderr"
    shown = [o["data"] for o in outputs if o.get("output_type") == "display_data"]
    assert len(shown) == 2, outputs
    assert "400/400" in shown[0]["text/plain"] and "100%" in shown[0]["text/plain"]
    assert shown[1] == {"text/plain": ""}, "a bar with leave=False leaves nothing"
    widget = "application/vnd.jupyter.widget-view+json"
    assert not any(widget in data for data in shown), "a widget is saved: viewers show nothing"


def test_outside_a_kernel_it_is_the_text_bar():
    from tqdm.std import tqdm

    from robolab.progress import progress_bar

    bar = progress_bar(range(3), desc="x", disable=True)
    assert isinstance(bar, tqdm) and list(bar) == [0, 1, 2]
