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


def test_without_a_kernel_it_draws_once_at_the_defaults():
    """Outside IPython there are no widgets: the drawing runs once with the slider values."""
    calls = []
    out = interactive.interact_or_static(
        lambda a, n: calls.append((a, n)),
        a=Slider(0, 1, 0.1, 0.3), n=Slider(1, 9, 1, 4, integer=True),
    )
    assert out is None and calls == [(0.3, 4)] and isinstance(calls[0][1], int)


def test_in_a_kernel_it_builds_sliders_that_rerun_the_drawing(monkeypatch):
    """With widgets available, interact builds one slider per control and draws at the defaults."""
    monkeypatch.setattr(interactive, "widgets_available", lambda: True)
    calls = []
    box = interactive.interact_or_static(lambda a: calls.append(a), a=Slider(0, 1, 0.1, 0.5, "a"))
    sliders = [c for c in box.widget.children if hasattr(c, "value") and hasattr(c, "max")]
    assert len(sliders) == 1 and sliders[0].value == 0.5 and sliders[0].max == 1
    sliders[0].value = 0.8
    assert calls[0] == 0.5 and calls[-1] == pytest.approx(0.8)


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
