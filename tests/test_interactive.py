"""Lab sliders: widgets in a kernel, one static figure elsewhere; both run the student's code."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from robolab.plotting import interactive  # noqa: E402
from robolab.plotting.interactive import Slider  # noqa: E402


@pytest.fixture(autouse=True)
def _close():
    yield
    plt.close("all")


def _figure_of(values: list):
    def draw(a, n=1):
        values.append((a, n))
        fig, ax = plt.subplots()
        ax.set_title(f"a = {a}")
        return fig

    return draw


def test_without_a_kernel_it_draws_once_at_the_defaults():
    """Outside IPython there are no widgets: the drawing runs once with the slider values."""
    calls = []
    out = interactive.interact_or_static(
        _figure_of(calls), a=Slider(0, 1, 0.1, 0.3), n=Slider(1, 9, 1, 4, integer=True),
    )
    assert out is None and calls == [(0.3, 4)] and isinstance(calls[0][1], int)


def test_in_a_kernel_sliders_redraw_the_figure_shown_through_a_handle(monkeypatch):
    """With widgets, one slider per control, the figure drawn at the defaults, redrawn on a move."""
    shown = []
    monkeypatch.setattr(interactive, "widgets_available", lambda: True)

    class Handle:
        def update(self, obj):
            shown.append(obj)

    import IPython.display

    def display(obj, display_id=False):
        if display_id:
            shown.append(obj)
            return Handle()

    monkeypatch.setattr(IPython.display, "display", display)
    calls = []
    box = interactive.interact_or_static(_figure_of(calls), a=Slider(0, 1, 0.1, 0.5, "a"))
    sliders = [c for c in box.children if hasattr(c, "value") and hasattr(c, "max")]
    assert len(sliders) == 1 and sliders[0].value == 0.5 and sliders[0].max == 1
    sliders[0].value = 0.8
    assert [a for a, _ in calls] == [0.5, pytest.approx(0.8)]
    assert [f.axes[0].get_title() for f in shown] == ["a = 0.5", "a = 0.8"]
    assert not plt.get_fignums(), "figures are shown through the handle, not again by the cell"


@pytest.mark.slow
def test_a_notebook_run_headless_saves_the_figure_of_the_initial_values(tmp_path):
    """Run headless by Jupyter (nbclient), the saved cell holds a PNG, not a widget repr."""
    import nbformat
    from nbclient import NotebookClient

    cell = (
        "%matplotlib inline\n"
        "import matplotlib.pyplot as plt\n"
        "from robolab.plotting.interactive import Slider, interact_or_static\n"
        "def draw(a):\n"
        "    fig, ax = plt.subplots()\n"
        "    ax.plot([0, 1], [0, a])\n"
        "    return fig\n"
        "interact_or_static(draw, a=Slider(0, 1, 0.1, 0.5, 'a'));"
    )
    nb = nbformat.v4.new_notebook()
    nb.cells = [nbformat.v4.new_code_cell(cell)]
    NotebookClient(nb, timeout=120, kernel_name="python3",
                   resources={"metadata": {"path": str(tmp_path)}}).execute()
    data = [o["data"] for o in nb.cells[0].outputs if o["output_type"] == "display_data"]
    images = [d for d in data if "image/png" in d]
    assert len(images) == 1, [list(d) for d in data]


def test_a_slider_refuses_a_default_outside_its_range():
    """A default outside [low, high] is a programming error, reported with the slider's name."""
    with pytest.raises(ValueError, match="sigma"):
        Slider(0.0, 1.0, 0.1, 2.0, "sigma")


def test_beam_model_explorer_calls_the_students_model_with_normalized_weights():
    """The sliders' weights are normalized before the student's model sees them."""
    from robolab.maps import load_maze
    from solutions import beam_model as bm

    seen = []

    def model(z, z_star, params, log=False):
        seen.append(params)
        return bm.beam_range_finder_model(z, z_star, params, log=log)

    grid = load_maze()
    beams = np.deg2rad(np.arange(0, 360, 30))
    params = {"z_hit": 2.0, "z_short": 1.0, "z_max": 0.5, "z_rand": 0.5, "sigma_hit": 0.2,
              "lambda_short": 1.0, "max_range": 5.0}
    with pytest.raises(ValueError):
        Slider(0, 1, 0.05, 2.0)  # z_hit = 2 is outside a weight slider: callers pass weights
    params.update(z_hit=0.5, z_short=0.25, z_max=0.125, z_rand=0.125)
    scan = np.full(beams.size, 2.0)
    interactive.beam_model_explorer(model, bm.pose_likelihood_map, scan, grid, beams, params,
                                    lattice=0.5)
    total = sum(seen[0][k] for k in ("z_hit", "z_short", "z_max", "z_rand"))
    assert total == pytest.approx(1.0)
    assert plt.get_fignums(), "the static figure was drawn"
