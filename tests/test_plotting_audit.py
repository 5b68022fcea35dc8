"""The figure audit flags each kind of style problem and passes a figure that follows the guide."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from robolab.plotting.audit import audit_figure, audit_value  # noqa: E402


@pytest.fixture(autouse=True)
def _close():
    yield
    plt.close("all")


def good_figure():
    fig, ax = plt.subplots(figsize=(7, 4))
    x = np.linspace(0, 10, 200)
    ax.plot(x, np.sin(x), label="sin")
    ax.scatter(x[::10], np.cos(x[::10]), s=16, label="samples")
    ax.set(title="Waves", xlabel="time [s]", ylabel="height [m]")
    ax.legend(loc="upper left", bbox_to_anchor=(1.02, 1))
    fig.tight_layout()
    return fig, ax


def test_a_figure_that_follows_the_guide_passes():
    """Title, labelled axes, visible legend entries outside the data: nothing to report."""
    fig, _ = good_figure()
    assert audit_figure(fig) == []


@pytest.mark.parametrize(
    "spoil, expected",
    [
        (lambda fig, ax: ax.set_title(""), "no title"),
        (lambda fig, ax: ax.set_xlabel(""), "x axis has no label"),
        (lambda fig, ax: ax.set_ylabel(""), "y axis has no label"),
        (lambda fig, ax: fig.set_size_inches(18, 4), "wide"),
        (lambda fig, ax: ax.scatter([1], [0], s=1, label="tiny") and ax.legend(), "tiny"),
        (lambda fig, ax: ax.plot([1, 2], [0, 0], alpha=0.05, label="ghost") and ax.legend(),
         "ghost"),
        (lambda fig, ax: ax.plot([50, 60], [50, 60], "o", label="away") and ax.set_xlim(0, 10)
         and ax.set_ylim(-1.5, 1.5) and ax.legend(loc="upper left", bbox_to_anchor=(1.02, 1)),
         "nothing inside the panel"),
        (lambda fig, ax: ax.legend(loc="center", fontsize=30, markerscale=3), "covers"),
    ],
    ids=["title", "xlabel", "ylabel", "width", "tiny-marker", "transparent", "off-view",
         "covering"],
)
def test_each_problem_is_named(spoil, expected):
    """One spoilt property of a good figure gives a sentence naming it."""
    fig, ax = good_figure()
    spoil(fig, ax)
    problems = audit_figure(fig)
    assert any(expected in p for p in problems), problems


def test_a_legend_entry_drawn_too_small_is_flagged():
    """A marker legible on the plot but drawn tiny in the legend (markerscale) is flagged."""
    fig, ax = good_figure()
    ax.plot([2, 3], [0.5, 0.5], "o", ms=4, label="poses")
    ax.legend(loc="upper left", bbox_to_anchor=(1.02, 1), markerscale=0.5)
    assert any("'poses'" in p and "drawn in the legend" in p for p in audit_figure(fig))


def test_robolab_draws_a_fine_particle_cloud_with_a_readable_legend_entry():
    """robolab.plotting's legend handler enlarges tiny scatter markers in legends only."""
    import robolab.plotting  # noqa: F401 - registers the handler

    fig, ax = good_figure()
    cloud = ax.scatter(np.random.default_rng(0).uniform(0, 10, 300), np.zeros(300), s=4,
                       alpha=0.3, label="particles")
    legend = ax.legend(loc="upper left", bbox_to_anchor=(1.02, 1))
    assert audit_figure(fig) == []
    drawn = legend.legend_handles[-1]
    assert np.sqrt(drawn.get_sizes().max()) >= 3 and drawn.get_alpha() >= 0.5
    assert cloud.get_sizes().max() == 4 and cloud.get_alpha() == 0.3  # the plot is unchanged


def test_shared_axes_and_suptitles_count():
    """Panels sharing y with a labelled panel need no label; a suptitle titles the figure."""
    fig, axes = plt.subplots(1, 2, figsize=(9, 4), sharey=True)
    for ax in axes:
        ax.plot([0, 1], [0, 1])
        ax.set_xlabel("x [m]")
    axes[0].set_ylabel("y [m]")
    fig.suptitle("Two panels")
    assert audit_figure(fig) == []
    axes[0].set_ylabel("")
    assert any("y axis has no label" in p for p in audit_figure(fig))


def test_panels_too_small_to_read():
    """Eight panels in one row at notebook width are too small."""
    fig, axes = plt.subplots(1, 8, figsize=(12, 3))
    for ax in axes:
        ax.plot([0, 1], [0, 1])
        ax.set(title="p", xlabel="x [m]", ylabel="y [m]")
    assert any("too small" in p for p in audit_figure(fig))


@pytest.mark.parametrize(
    "value, stray",
    [(np.float64(0.5), True), (np.int64(3), True), (0.5, False), ("text", False), (None, False)],
)
def test_stray_reprs(value, stray):
    """A cell that ends in a numpy scalar shows np.float64(...): flagged; plain values are not."""
    assert (audit_value(value) is not None) is stray


def test_a_matplotlib_object_left_as_the_cell_value_is_flagged():
    """`ax.legend()` as the last line prints <matplotlib.legend.Legend at 0x...>."""
    fig, ax = good_figure()
    assert audit_value(ax.legend()) is not None
    assert audit_value(ax.plot([0], [0])) is not None


@pytest.mark.parametrize(
    "cell, quiet",
    [("ax.legend();", True), ("ax.legend();  # keep it quiet", True), ("ax.legend()", False),
     ("x = 1\nax.legend()\n", False), ("s = 'a;'", False), ("", False)],
)
def test_a_semicolon_ends_the_display_like_jupyter(cell, quiet):
    """A trailing `;` (comments after it allowed) hides the value, as in Jupyter."""
    from robolab.plotting.audit import _quiet

    assert _quiet(cell) is quiet


@pytest.mark.slow
def test_the_audit_sees_figures_under_the_inline_backend(tmp_path):
    """In Jupyter with its default inline backend (no MPLBACKEND), figures are audited
    before the backend shows and closes them; printed numpy reprs are caught too."""
    import os

    import nbformat
    from nbclient import NotebookClient

    nb = nbformat.v4.new_notebook()
    nb.cells = [
        nbformat.v4.new_code_cell("%load_ext robolab.plotting.audit"),
        nbformat.v4.new_code_cell(
            "import matplotlib.pyplot as plt, numpy as np\nfig, ax = plt.subplots()\n"
            "ax.plot([1, 2], [3, 4]);\nprint('extent', (np.float64(0.5), 1.0))"
        ),
        nbformat.v4.new_code_cell("from robolab.plotting import audit\naudit.report()"),
    ]
    env = {k: v for k, v in os.environ.items() if k != "MPLBACKEND"}
    client = NotebookClient(nb, timeout=120, kernel_name="python3", allow_errors=True,
                            resources={"metadata": {"path": str(tmp_path)}})
    client.km = client.create_kernel_manager()
    client.start_new_kernel(env=env)
    client.start_new_kernel_client()
    client.execute(cleanup_kc=True)
    error = nb.cells[-1].outputs[-1]
    assert error["output_type"] == "error", nb.cells[-1].outputs
    assert "no title" in error["evalue"] and "np.float64" in error["evalue"]
