"""Animations that replay a filter run: the landmark particle filter, MCL and FastSLAM.

Each function returns a :class:`matplotlib.animation.FuncAnimation`; in a notebook,
``show_animation(anim)`` renders it with ``to_jshtml`` (a player with play, step and
speed buttons that needs no extra package and works on Colab) and closes the figure, so
that no stray static frame is shown below it. Frames are rendered at a modest dpi so
that a whole animation stays well under :data:`MAX_BYTES` (tested).

The animations replay what a run recorded; none of them runs a filter itself, except
:func:`replay_fastslam`, which steps the student's ``fastslam_step`` once over a run to
record the particles and landmark estimates it then shows.
"""

from __future__ import annotations

from collections.abc import Callable

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.animation import FuncAnimation

from robolab.plotting.core import legend_outside, plot_map
from robolab.validation import as_array, check_count

__all__ = [
    "MAX_BYTES",
    "animate_landmark_pf",
    "animate_mcl",
    "animate_fastslam",
    "replay_fastslam",
    "show_animation",
]

#: Largest rendered animation (HTML bytes) a notebook should hold.
MAX_BYTES = 5 * 1024 * 1024
#: Resolution of the rendered frames: readable at notebook width, small on disk.
FRAME_DPI = 60


def show_animation(anim: FuncAnimation, *, fps: float | None = None):
    """Render an animation as an HTML player (``to_jshtml``'s) and close its figure.

    The frames are rendered by :func:`render_frames`: the still parts of the figure
    (map, axes, legend) once, then per frame only what the animation changes, the
    artists its frame function returns and the axes' titles (a frame costs a few
    artists' drawing and one PNG instead of the whole figure, twice, as
    ``FuncAnimation.save`` draws it). The player is matplotlib's own
    (:class:`matplotlib.animation.HTMLWriter`).

    Returns an ``IPython.display.HTML`` object (display it as a cell's last value).

    Raises
    ------
    ValueError
        When the rendered player would exceed :data:`MAX_BYTES`.
    """
    import tempfile
    from pathlib import Path

    from IPython.display import HTML
    from matplotlib.animation import HTMLWriter

    fig = anim._fig
    fig.set_dpi(FRAME_DPI)
    if fps is None:
        fps = 1000 / getattr(anim, "_interval", 200)
    frames = render_frames(anim)
    anim._draw_was_started = True  # rendered: no "deleted without rendering" warning
    writer = HTMLWriter(fps=fps, embed_frames=True, default_mode="once")
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "animation.html"
        writer.setup(fig, path, dpi=FRAME_DPI)
        writer._saved_frames = frames  # what its grab_frame collects, base64 PNGs
        writer.finish()
        html = path.read_text()
    plt.close(fig)
    if len(html) > MAX_BYTES:
        raise ValueError(
            f"the animation is {len(html) / 2**20:.1f} MiB, over {MAX_BYTES / 2**20:.0f} MiB: "
            "use fewer frames (every=...)"
        )
    return HTML(html)


def render_frames(anim: FuncAnimation) -> list[str]:
    """Every frame of ``anim`` as a base64 PNG at the figure's dpi, by blitting.

    The figure is drawn once without its changing artists (those the frame
    function returns, and every axes' title), which gives the background; each
    frame restores it and draws only the changing artists on it, in z-order.
    The pixels are those of a full draw of the frame (tested), as long as the
    frame function changes nothing else (the animations of this module do not).
    """
    import base64
    import io

    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from PIL import Image

    fig = anim._fig
    canvas = FigureCanvasAgg(fig)
    frames = list(anim.new_saved_frame_seq())
    changing = [*anim._func(frames[0]), *(ax.title for ax in fig.axes)]
    changing.sort(key=lambda a: a.get_zorder())
    for artist in changing:
        artist.set_animated(True)
    canvas.draw()  # animated artists are left out of a draw that is not a save
    background = canvas.copy_from_bbox(fig.bbox)
    out = []
    for frame in frames:
        anim._func(frame)
        canvas.restore_region(background)
        for artist in changing:
            fig.draw_artist(artist)
        png = io.BytesIO()
        Image.fromarray(np.asarray(canvas.buffer_rgba())).save(png, format="png")
        out.append(base64.encodebytes(png.getvalue()).decode("ascii"))
    for artist in changing:
        artist.set_animated(False)
    return out


def _frames(total: int, every: int) -> np.ndarray:
    every = check_count("every", every)
    idx = np.arange(0, total, every)
    if idx[-1] != total - 1:
        idx = np.append(idx, total - 1)  # always end on the final state
    return idx


def animate_landmark_pf(world, history: dict, true_path, *, every: int = 1) -> FuncAnimation:
    """Replay lab 03's particle filter: predicted particles, resampled particles, estimate.

    Parameters
    ----------
    world : robolab.world.cWorld
    history : dict
        ``particle_filter(..., return_history=True)``: ``path`` (T+1, 2), ``predicted``
        and ``resampled`` (T, N, 3).
    true_path : array_like, shape (T+1, 2)
    every : int
        Show every ``every``-th step.
    """
    path = as_array("history['path']", history["path"], ndim=2, finite=True)
    predicted = as_array("history['predicted']", history["predicted"], ndim=3)
    resampled = as_array("history['resampled']", history["resampled"], ndim=3)
    truth = as_array("true_path", true_path, shape=(len(path), None))
    size = float(getattr(world, "size", 100.0))
    fig, ax = plt.subplots(figsize=(7.5, 6.0))
    ax.set(xlim=(0, size), ylim=(0, size), xlabel="x [m]", ylabel="y [m]", aspect="equal")
    landmarks = np.asarray(world.landmarks, dtype=float)
    ax.scatter(landmarks[:, 0], landmarks[:, 1], marker="*", s=160, c="k", label="landmarks")
    pred = ax.scatter([], [], s=6, c="tab:orange", alpha=0.4, label="predicted")
    res = ax.scatter([], [], s=6, c="tab:red", alpha=0.6, label="resampled")
    (true_line,) = ax.plot([], [], "g-o", ms=4, label="true path")
    (est_line,) = ax.plot([], [], "b-x", ms=6, label="estimate")
    legend_outside(ax)
    fig.tight_layout()
    steps = _frames(len(predicted), every)

    def draw(k: int):
        i = steps[k]
        pred.set_offsets(predicted[i, :, :2])
        res.set_offsets(resampled[i, :, :2])
        true_line.set_data(truth[: i + 2, 0], truth[: i + 2, 1])
        est_line.set_data(path[: i + 2, 0], path[: i + 2, 1])
        ax.set_title(f"Landmark particle filter, step {i + 1} of {len(predicted)}")
        return pred, res, true_line, est_line

    return FuncAnimation(fig, draw, frames=len(steps), interval=500, blit=False)


def animate_mcl(grid, result: dict, *, max_points: int = 2000) -> FuncAnimation:
    """Replay an MCL run from its snapshots: particles on the map, truth and estimate.

    Parameters
    ----------
    grid : OccupancyGrid
    result : dict
        A run of :func:`robolab.plotting.mcl.run_mcl` (or ``run_kld``) with
        ``snapshots`` {time: (particles, weights)} taken often (for example
        ``snapshot_times=np.arange(0, 80, 2)``), ``t``, ``truth`` and ``estimate``.
    max_points : int
        At most this many particles drawn per frame (evenly chosen).
    """
    times = sorted(result["snapshots"])
    if len(times) < 2:
        raise ValueError(f"an animation needs at least 2 snapshots, got {len(times)}")
    fig, ax = plt.subplots(figsize=(8.0, 6.0))
    plot_map(grid, ax, title="MCL")
    cloud = ax.scatter([], [], s=5, c="tab:red", alpha=0.5, linewidths=0, label="particles",
                       zorder=3)
    (truth_dot,) = ax.plot([], [], "o", mfc="none", mec="tab:green", mew=2, ms=11,
                           label="true pose", zorder=4)
    (est_dot,) = ax.plot([], [], "x", color="tab:blue", mew=2, ms=9, label="estimate", zorder=5)
    t_all = np.asarray(result["t"], dtype=float)
    legend_outside(ax)
    fig.tight_layout()

    def draw(k: int):
        t = times[k]
        particles, _ = result["snapshots"][t]
        p = np.asarray(particles)
        if len(p) > max_points:
            p = p[np.linspace(0, len(p) - 1, max_points).astype(int)]
        cloud.set_offsets(p[:, :2])
        i = int(np.argmin(np.abs(t_all - t)))
        truth, est = result["truth"][i], result["estimate"][i]
        truth_dot.set_data([truth[0]], [truth[1]])
        est_dot.set_data([est[0]], [est[1]])
        ax.set_title(f"MCL at t = {t:.0f} s: {len(particles)} particles, "
                     f"error {result['position_error'][i]:.2f} m")
        return cloud, truth_dot, est_dot

    return FuncAnimation(fig, draw, frames=len(times), interval=400, blit=False)


def replay_fastslam(
    run,
    init_particles: Callable,
    fastslam_step: Callable,
    n_particles: int,
    rng: np.random.Generator,
    *,
    every: int = 10,
    init: str = "first_observation",
) -> dict:
    """Step ``fastslam_step`` over a fiducial run and record what an animation shows.

    Parameters
    ----------
    run : FiducialRun, FiducialRobot or .npz path
        See :func:`robolab.fiducials.as_robot`.
    init_particles, fastslam_step : callable
        The lab's functions (``init_particles(M, K, x0, init)`` and
        ``fastslam_step(state, command, z, Q, Qt, rng, dt=...)``).
    n_particles : int
    rng : numpy.random.Generator
    every : int
        Record every ``every``-th step (and the last).
    init : str
        Passed to ``init_particles``.

    Returns
    -------
    dict
        ``step`` (F,), ``poses`` (F, M, 3), ``landmarks`` (F, K, 2) the weighted means of
        the landmarks seen so far (NaN before), ``true_poses`` (T+1, 3), ``fiducials`` (K, 2).
    """
    from robolab.fiducials import as_robot

    robot = as_robot(run)
    every = check_count("every", every)
    state = init_particles(check_count("n_particles", n_particles), robot.n_fiducials,
                           robot.x0, init)
    seen = np.zeros(robot.n_fiducials, dtype=bool)
    record: dict[str, list] = {"step": [], "poses": [], "landmarks": []}

    def keep(step: int) -> None:
        w = np.asarray(state["weights"], dtype=float)
        lm = np.einsum("k,kjd->jd", w / w.sum(), np.asarray(state["means"], dtype=float))
        lm[~seen] = np.nan
        record["step"].append(step)
        record["poses"].append(np.array(state["poses"], dtype=float))
        record["landmarks"].append(lm)

    keep(0)
    step = 0
    while robot.run():
        step += 1
        z = robot.measurement()
        seen[np.asarray(z[:, 2], dtype=np.intp)] = True
        state = fastslam_step(state, robot.input(), z, robot.Q, robot.Qt, rng, dt=robot.dt)
        if step % every == 0:
            keep(step)
    if record["step"][-1] != step:
        keep(step)
    out = {key: np.array(value) for key, value in record.items()}
    out["true_poses"] = np.asarray(robot.true_poses, dtype=float)
    out["fiducials"] = np.asarray(robot.fiducials, dtype=float)
    return out


def animate_fastslam(replay: dict) -> FuncAnimation:
    """Replay FastSLAM: every particle's pose, the path so far and the landmark estimates."""
    truth = replay["true_poses"]
    fid = replay["fiducials"]
    fig, ax = plt.subplots(figsize=(8.0, 6.2))
    lo = np.nanmin(np.vstack([truth[:, :2], fid]), axis=0) - 1.0
    hi = np.nanmax(np.vstack([truth[:, :2], fid]), axis=0) + 1.0
    ax.set(xlim=(lo[0], hi[0]), ylim=(lo[1], hi[1]), xlabel="x [m]", ylabel="y [m]",
           aspect="equal")
    ax.scatter(fid[:, 0], fid[:, 1], marker="*", s=160, c="k", label="true fiducials", zorder=3)
    cloud = ax.scatter([], [], s=6, c="tab:red", alpha=0.5, label="particles", zorder=2)
    est = ax.scatter([], [], marker="+", s=90, c="tab:blue", label="estimated fiducials",
                     zorder=4)
    (true_line,) = ax.plot([], [], "g-", lw=1.2, label="true path")
    legend_outside(ax)
    fig.tight_layout()

    def draw(k: int):
        s = int(replay["step"][k])
        cloud.set_offsets(replay["poses"][k][:, :2])
        lm = replay["landmarks"][k]
        est.set_offsets(lm[np.isfinite(lm).all(axis=1)].reshape(-1, 2))
        true_line.set_data(truth[: s + 1, 0], truth[: s + 1, 1])
        ax.set_title(f"FastSLAM, step {s}: {np.isfinite(lm).all(axis=1).sum()} of "
                     f"{len(fid)} fiducials mapped")
        return cloud, est, true_line

    return FuncAnimation(fig, draw, frames=len(replay["step"]), interval=300, blit=False)
