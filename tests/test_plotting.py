"""robolab.plotting: figures are drawn, titled and labelled, and the geometry is exact."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from matplotlib.collections import EllipseCollection, PathCollection  # noqa: E402
from matplotlib.image import AxesImage  # noqa: E402
from matplotlib.patches import Ellipse  # noqa: E402
from matplotlib.quiver import Quiver  # noqa: E402

from robolab import plotting  # noqa: E402
from robolab.maps import OccupancyGrid  # noqa: E402


@pytest.fixture(autouse=True)
def _close_figures():
    yield
    plt.close("all")


def _scatter_offsets(ax):
    (coll,) = [c for c in ax.collections if isinstance(c, PathCollection)]
    return np.asarray(coll.get_offsets())


# -- new_axes ---------------------------------------------------------------------------
def test_new_axes_sets_title_labels_and_aspect():
    ax = plotting.new_axes("A title")
    assert ax.get_title() == "A title"
    assert ax.get_xlabel() == "x [m]" and ax.get_ylabel() == "y [m]"
    assert ax.get_aspect() == 1.0
    ax2 = plotting.new_axes("B", xlabel="t [s]", ylabel="p", equal=False)
    assert (ax2.get_xlabel(), ax2.get_ylabel(), ax2.get_aspect()) == ("t [s]", "p", "auto")


@pytest.mark.parametrize("title", ["", "   ", None])
def test_new_axes_requires_a_title(title):
    with pytest.raises(ValueError, match="title"):
        plotting.new_axes(title)


# -- plot_map ---------------------------------------------------------------------------
def _grid(origin=(0.0, 0.0, 0.0)):
    data = np.zeros((4, 6))
    data[0, :] = 1.0  # bottom row occupied
    data[3, 5] = -1.0  # one unknown cell, top right
    return OccupancyGrid(data, 0.5, np.array(origin, dtype=float))


def test_plot_map_extent_origin_and_labels():
    grid = _grid(origin=(-1.0, 2.0, 0.0))
    ax = plotting.plot_map(grid)
    (img,) = ax.images
    assert isinstance(img, AxesImage)
    assert img.origin == "lower"
    np.testing.assert_allclose(img.get_extent(), (-1.0, 2.0, 2.0, 4.0))
    assert ax.get_title() == "Occupancy grid"
    assert ax.get_xlabel() == "x [m]" and ax.get_ylabel() == "y [m]"


def test_plot_map_colours_free_occupied_unknown():
    grid = _grid()
    ax = plotting.plot_map(grid, title="maze", unknown_color="red")
    assert ax.get_title() == "maze"
    img = ax.images[0]
    rgba = img.to_rgba(img.get_array())  # (H, W, 4) in storage order
    np.testing.assert_allclose(rgba[0, 0, :3], 0.0, atol=1e-6)  # occupied -> black
    np.testing.assert_allclose(rgba[1, 0, :3], 1.0, atol=1e-6)  # free -> white
    np.testing.assert_allclose(rgba[3, 5], (1.0, 0.0, 0.0, 1.0))  # unknown -> red


def test_plot_map_into_existing_axes_keeps_its_title():
    ax = plotting.new_axes("mine")
    assert plotting.plot_map(_grid(), ax=ax) is ax
    assert ax.get_title() == "mine"


def test_plot_map_rotated_origin_places_cells_in_world():
    grid = _grid(origin=(1.0, 1.0, np.pi / 2))
    ax = plotting.plot_map(grid)
    img = ax.images[0]
    # The image's data-space corner (x0 + width, y0) must land at cell_to_world of the
    # (row 0, col W) corner: rotated by 90 degrees about the origin.
    corner = img.get_transform().transform([(1.0 + grid.width, 1.0)])
    expected = ax.transData.transform(grid.cell_to_world(np.array([-0.5, grid.shape[1] - 0.5])))
    np.testing.assert_allclose(corner[0], expected, atol=1e-6)


def test_plot_map_rejects_non_grid():
    with pytest.raises(TypeError, match="grid"):
        plotting.plot_map(np.zeros((3, 3)))


# -- plot_poses --------------------------------------------------------------------------
def test_plot_poses_path_and_heading_arrows():
    t = np.linspace(0, np.pi, 50)
    poses = np.stack([np.cos(t), np.sin(t), t + np.pi / 2], -1)
    ax = plotting.plot_poses(poses, label="truth", arrow_every=10, arrow_length=0.2)
    (line,) = ax.lines
    np.testing.assert_allclose(line.get_xydata(), poses[:, :2])
    (q,) = [c for c in ax.collections if isinstance(c, Quiver)]
    idx = [0, 10, 20, 30, 40, 49]
    np.testing.assert_allclose(q.get_offsets(), poses[idx, :2])
    np.testing.assert_allclose(np.hypot(q.U, q.V), 0.2)
    np.testing.assert_allclose(
        np.arctan2(q.V, q.U), np.arctan2(np.sin(poses[idx, 2]), np.cos(poses[idx, 2]))
    )
    assert q.get_facecolor()[0].tolist() == list(matplotlib.colors.to_rgba(line.get_color()))
    assert ax.get_title() == "Poses" and ax.get_xlabel() == "x [m]"


def test_plot_poses_single_pose_and_no_path():
    ax = plotting.plot_poses([1.0, 2.0, 0.0], path=False)
    assert not ax.lines
    (q,) = [c for c in ax.collections if isinstance(c, Quiver)]
    np.testing.assert_allclose(q.get_offsets(), [[1.0, 2.0]])
    np.testing.assert_allclose([q.U[0], q.V[0]], [0.5, 0.0])


@pytest.mark.parametrize("bad", [np.zeros((4, 2)), np.zeros((2, 3, 3)), [[0, 0, np.nan]]])
def test_plot_poses_bad_input(bad):
    with pytest.raises(ValueError, match="poses"):
        plotting.plot_poses(bad)


# -- plot_particles ----------------------------------------------------------------------
def test_plot_particles_sizes_follow_weights():
    rng = np.random.default_rng(0)
    p = rng.normal(size=(100, 3))
    w = rng.uniform(size=100)
    ax = plotting.plot_particles(p, w, size=5.0)
    (coll,) = [c for c in ax.collections if isinstance(c, PathCollection)]
    np.testing.assert_allclose(coll.get_offsets(), p[:, :2])
    np.testing.assert_allclose(coll.get_sizes(), 5.0 * 100 * w / w.sum())
    assert ax.get_title() == "Particles" and ax.get_ylabel() == "y [m]"


def test_plot_particles_uniform_without_weights_and_headings():
    ax = plotting.plot_particles(np.zeros((10, 3)), headings=True, size=3.0)
    coll = [c for c in ax.collections if isinstance(c, PathCollection)][0]
    np.testing.assert_allclose(coll.get_sizes(), 3.0)
    assert any(isinstance(c, Quiver) for c in ax.collections)


@pytest.mark.parametrize(
    ("particles", "weights", "match"),
    [
        (np.zeros((5, 4)), None, "particles"),
        (np.zeros((5, 2)), np.ones(4), "weights"),
        (np.zeros((5, 2)), -np.ones(5), "weights"),
        (np.zeros((5, 2)), np.zeros(5), "weights"),
    ],
)
def test_plot_particles_bad_input(particles, weights, match):
    with pytest.raises(ValueError, match=match):
        plotting.plot_particles(particles, weights)


# -- plot_landmarks -------------------------------------------------------------------------
def test_plot_landmarks_with_index_labels():
    lm = np.array([[20.0, 20.0], [80.0, 80.0], [20.0, 80.0]])
    ax = plotting.plot_landmarks(lm, labels=True)
    np.testing.assert_allclose(_scatter_offsets(ax), lm)
    assert [t.get_text() for t in ax.texts] == ["0", "1", "2"]
    assert ax.get_title() == "Landmarks"


def test_plot_landmarks_label_count_must_match():
    with pytest.raises(ValueError, match="labels"):
        plotting.plot_landmarks(np.zeros((3, 2)), labels=["a", "b"])


# -- covariance ellipses ----------------------------------------------------------------------
def _random_cov(rng):
    a = rng.normal(size=(2, 2))
    return a @ a.T + 0.01 * np.eye(2)


@pytest.mark.parametrize("seed", range(5))
def test_ellipse_semi_axes_and_orientation_match_eigen_decomposition(seed):
    rng = np.random.default_rng(seed)
    cov = _random_cov(rng)
    mean = rng.normal(size=2)
    n_std = 1.5 + seed
    ell = plotting.plot_covariance_ellipse(mean, cov, n_std=n_std)
    assert isinstance(ell, Ellipse)
    lam, vec = np.linalg.eigh(cov)  # ascending
    np.testing.assert_allclose(ell.width / 2, n_std * np.sqrt(lam[1]), rtol=1e-12)
    np.testing.assert_allclose(ell.height / 2, n_std * np.sqrt(lam[0]), rtol=1e-12)
    np.testing.assert_allclose(ell.center, mean)
    major = np.array([np.cos(np.radians(ell.angle)), np.sin(np.radians(ell.angle))])
    np.testing.assert_allclose(abs(major @ vec[:, 1]), 1.0, atol=1e-12)  # parallel to v1
    # Every drawn point lies at Mahalanobis distance n_std from the mean.
    pts = ell.get_patch_transform().transform(
        np.stack([np.cos(np.linspace(0, 6, 40)), np.sin(np.linspace(0, 6, 40))], -1)
    )
    d = pts - mean
    np.testing.assert_allclose(
        np.einsum("ni,ij,nj->n", d, np.linalg.inv(cov), d), n_std**2, rtol=1e-9
    )


def test_ellipse_axis_aligned_known_values():
    w, h, angle = plotting.covariance_ellipse_params(np.diag([0.25, 4.0]), n_std=2.0)
    assert (w, h) == pytest.approx((8.0, 2.0))  # 2 * 2 * sqrt(4), 2 * 2 * sqrt(0.25)
    assert angle == pytest.approx(90.0)


def test_ellipse_params_vectorized_equals_loop():
    rng = np.random.default_rng(1)
    covs = np.stack([_random_cov(rng) for _ in range(7)])
    w, h, a = plotting.covariance_ellipse_params(covs, 3.0)
    for k in range(7):
        assert (w[k], h[k], a[k]) == pytest.approx(plotting.covariance_ellipse_params(covs[k], 3.0))
    assert np.all((a > -90) & (a <= 90))


def test_ellipse_stack_returns_collection():
    rng = np.random.default_rng(2)
    covs = np.stack([_random_cov(rng) for _ in range(4)])
    means = rng.normal(size=(4, 2))
    coll = plotting.plot_covariance_ellipse(means, covs, edgecolor="k")
    assert isinstance(coll, EllipseCollection)
    np.testing.assert_allclose(coll.get_offsets(), means)
    assert coll.axes.get_title() == "Covariance ellipse"


def test_ellipse_degenerate_covariance_is_a_segment():
    w, h, angle = plotting.covariance_ellipse_params([[1.0, 1.0], [1.0, 1.0]], 1.0)
    assert h == pytest.approx(0.0, abs=1e-7) and w == pytest.approx(2 * np.sqrt(2.0))
    assert angle == pytest.approx(45.0)


@pytest.mark.parametrize(
    ("mean", "cov", "match"),
    [
        ([0, 0], [[1.0, 0.5], [0.0, 1.0]], "symmetric"),
        ([0, 0], [[1.0, 0.0], [0.0, -1.0]], "positive semi-definite"),
        ([0, 0], np.eye(3), "cov"),
        ([0, 0, 0], np.eye(2), "mean"),
        ([[0, 0], [1, 1]], np.eye(2), "same number"),
        ([0, 0], [[np.nan, 0], [0, 1]], "cov"),
    ],
)
def test_ellipse_bad_input(mean, cov, match):
    with pytest.raises(ValueError, match=match):
        plotting.plot_covariance_ellipse(mean, cov)


def test_ellipse_n_std_must_be_positive():
    with pytest.raises(ValueError, match="n_std"):
        plotting.covariance_ellipse_params(np.eye(2), 0.0)


# -- plot_scan --------------------------------------------------------------------------------
def test_plot_scan_ranges_angles_at_pose_drops_invalid():
    ranges = np.array([1.0, np.inf, 2.0, 0.0, np.nan, 5.0])
    angles = np.array([0.0, 0.5, np.pi / 2, 1.0, 1.5, np.pi])
    ax = plotting.plot_scan(
        (ranges, angles), origin=(1.0, 2.0, np.pi / 2), max_range=5.0, rays=True
    )
    # Hand computation: the sensor at (1, 2) facing +y; beam 0 (1 m ahead) -> (1, 3);
    # beam 2 (2 m to the sensor's left = world -x) -> (-1, 2); 5 m = max_range is dropped.
    np.testing.assert_allclose(_scatter_offsets(ax), [[1.0, 3.0], [-1.0, 2.0]], atol=1e-12)
    assert ax.get_title() == "Laser scan" and ax.get_xlabel() == "x [m]"


def test_plot_scan_points_default_origin():
    pts = np.array([[1.0, 0.0], [0.0, 2.0], [np.nan, 1.0]])
    ax = plotting.plot_scan(pts)
    np.testing.assert_allclose(_scatter_offsets(ax), pts[:2])


@pytest.mark.parametrize(
    ("scan", "origin", "match"),
    [
        (np.zeros((3, 3)), None, "scan"),
        ((np.ones(3), np.zeros(4)), None, "angles"),
        (np.zeros((3, 2)), (0.0, 0.0), "origin"),
    ],
)
def test_plot_scan_bad_input(scan, origin, match):
    with pytest.raises(ValueError, match=match):
        plotting.plot_scan(scan, origin=origin)


# -- plot_belief and composition --------------------------------------------------------------
def test_plot_belief_bars_and_labels():
    ax = plotting.plot_belief([0.75, 0.25], tick_labels=["open", "closed"], title="door")
    heights = [p.get_height() for p in ax.patches]
    assert heights == pytest.approx([0.75, 0.25])
    assert [t.get_text() for t in ax.get_xticklabels()] == ["open", "closed"]
    assert ax.get_title() == "door" and ax.get_ylabel() == "belief bel(x)"
    with pytest.raises(ValueError, match="belief"):
        plotting.plot_belief([0.5, -0.1])


def test_functions_compose_on_one_axes_and_never_show(monkeypatch):
    monkeypatch.setattr(plt, "show", lambda *a, **k: pytest.fail("plt.show() must not be called"))
    ax = plotting.new_axes("everything")
    assert plotting.plot_map(_grid(), ax=ax) is ax
    assert plotting.plot_poses(np.zeros((3, 3)), ax=ax) is ax
    assert plotting.plot_particles(np.zeros((3, 2)), ax=ax) is ax
    assert plotting.plot_landmarks(np.ones((2, 2)), ax=ax) is ax
    assert plotting.plot_scan(np.ones((2, 2)), ax=ax) is ax
    assert plotting.plot_covariance_ellipse(np.zeros(2), np.eye(2), ax=ax).axes is ax
    assert len(plt.get_fignums()) == 1
    assert ax.get_title() == "everything"


def test_ax_must_be_axes():
    with pytest.raises(TypeError, match="ax"):
        plotting.plot_landmarks(np.zeros((1, 2)), ax="not axes")


def test_convergence_time_is_the_start_of_the_last_run_below_tolerance():
    """Lock-on time: the first update after which the error never again reaches the tolerance."""
    from robolab.plotting.mcl import convergence_time

    t = np.arange(8.0)
    run = {"t": t, "position_error": np.array([3.0, 0.2, 0.1, 2.0, 0.4, 0.3, 0.2, 0.1])}
    assert convergence_time(run, 0.5) == 4.0
    assert convergence_time(run, 5.0) == 0.0
    still_off = {"t": t, "position_error": np.r_[np.zeros(7), 1.0]}
    assert convergence_time(still_off, 0.5) is None
    with_nan = {"t": t, "position_error": np.r_[0.1, np.nan, np.zeros(6)]}
    assert convergence_time(with_nan, 0.5) == 2.0  # a NaN error is not "locked on"
    with pytest.raises(ValueError):
        convergence_time(run, 0.0)


def test_graph_slam_figures_are_titled_and_labelled():
    """Lab 09: the graph, the sparsity image and the objective history draw on labelled axes."""
    import scipy.sparse

    from robolab.datasets import PoseGraph
    from robolab.plotting.graph_slam import plot_objective_history, plot_pose_graph, plot_sparsity

    g = PoseGraph(
        [[0, 0, 0], [1, 0, 0], [1, 1, 1.5]], [[0, 1], [1, 2], [0, 2]], np.zeros((3, 3)),
        np.broadcast_to(np.eye(3), (3, 3, 3)), landmarks=[[2.0, 2.0]], landmark_edges=[[2, 0]],
        landmark_measurements=[[1.0, 0.0]], landmark_information=[np.eye(2)],
    )
    ax = plot_pose_graph(g)
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert labels == ["loop closures (1)", "landmark edges (1)", "landmarks (1)", "poses (3)"]
    assert ax.get_title() and ax.get_xlabel() == "x [m]"
    H = scipy.sparse.csr_matrix(np.diag([1.0, 0.0, 2.0]))
    ax = plot_sparsity(H, n_poses=0)
    image = ax.get_images()[0].get_array()
    np.testing.assert_array_equal(np.asarray(image, dtype=bool), np.diag([True, False, True]))
    ax = plot_objective_history({"run": {"objective": np.array([100.0, 10.0, 9.0])}})
    assert ax.get_yscale() == "log" and ax.get_ylabel()
    plt.close("all")


def test_estimate_pose_is_the_weighted_mean_of_the_heaviest_cluster():
    """Two clusters: the heavier one wins; its weighted mean, headings averaged on the circle."""
    from robolab.plotting.mcl_runs import estimate_pose

    rng = np.random.default_rng(3)
    light = np.column_stack([rng.normal(1.0, 0.05, 60), rng.normal(1.0, 0.05, 60),
                             np.full(60, 0.5)])
    heavy = np.column_stack([rng.normal(8.0, 0.05, 40), rng.normal(4.0, 0.05, 40),
                             np.where(np.arange(40) % 2, np.pi - 0.1, -np.pi + 0.1)])
    p = np.vstack([light, heavy])
    w = np.r_[np.full(60, 0.2 / 60), rng.uniform(0.5, 1.5, 40)]
    w /= w.sum()
    est = estimate_pose(p, w)
    wh = w[60:] / w[60:].sum()
    np.testing.assert_allclose(est[:2], wh @ heavy[:, :2], rtol=0, atol=1e-12)
    heading = np.arctan2(wh @ np.sin(heavy[:, 2]), wh @ np.cos(heavy[:, 2]))
    assert abs(abs(est[2]) - np.pi) < 0.1 and abs(np.angle(np.exp(1j * (est[2] - heading)))) < 1e-12
    # unweighted: the 60 particles are the heaviest cluster
    np.testing.assert_allclose(estimate_pose(p)[:2], light[:, :2].mean(axis=0), atol=1e-12)
    # a cluster whose particles all weigh 0 cannot win; one weight carries everything
    w0 = np.zeros(100)
    w0[70] = 1.0
    np.testing.assert_allclose(estimate_pose(p, w0), p[70], atol=1e-12)


@pytest.mark.parametrize("spread", [0.3, 3.0, 1e12])
def test_kld_resample_stops_at_the_first_draw_that_meets_the_bound(spread):
    """Oracle: draw by draw, count the distinct bins k_j and stop at j >= max(n_min, n(k_j))."""
    from robolab.plotting.mcl_runs import KLD_BIN_SIZE, kld_resample
    from solutions.mcl import kld_sample_size

    rng = np.random.default_rng(4)
    p = rng.normal(0.0, spread, (400, 3))
    w = rng.random(400)
    out = kld_resample(p, w, np.random.default_rng(9), kld_sample_size, n_min=20, n_max=3000)
    draws = p[np.random.default_rng(9).choice(400, size=3000, p=w / w.sum())]
    seen = set()
    for j, d in enumerate(draws, start=1):
        seen.add(tuple(np.floor(d / np.asarray(KLD_BIN_SIZE, float)).astype(np.int64)))
        if j >= max(20, kld_sample_size(len(seen), 0.05, 2.326)):
            break
    np.testing.assert_array_equal(out, draws[:j])
