"""Animations replay what a run recorded, end on its final state and stay small as HTML."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from robolab.fiducials import FiducialRobot  # noqa: E402
from robolab.plotting import animation  # noqa: E402
from robolab.world import cWorld  # noqa: E402


@pytest.fixture(autouse=True)
def _close():
    yield
    plt.close("all")


def _pf_history(steps=6, n=50, seed=0):
    rng = np.random.default_rng(seed)
    predicted = rng.uniform(0, 100, (steps, n, 3))
    resampled = predicted[:, rng.integers(0, n, n)]
    path = np.cumsum(rng.normal(0, 5, (steps + 1, 2)), axis=0) + 50
    return {"path": path, "predicted": predicted, "resampled": resampled}


def test_landmark_pf_animation_shows_every_step_and_ends_on_the_last():
    """One frame per step (every=1); the last frame draws the last resampled set and whole path."""
    h = _pf_history()
    anim = animation.animate_landmark_pf(cWorld(), h, h["path"] + 1.0)
    frames = list(anim.new_frame_seq())
    assert len(frames) == 6
    pred, res, true_line, est_line = anim._func(frames[-1])
    np.testing.assert_allclose(res.get_offsets(), h["resampled"][-1, :, :2])
    np.testing.assert_allclose(np.column_stack(est_line.get_data()), h["path"])
    assert len(list(animation.animate_landmark_pf(cWorld(), h, h["path"], every=4)
                    .new_frame_seq())) == 3  # steps 0, 4 and the last (5)


def test_rendered_animation_is_a_player_under_the_size_limit():
    """to_jshtml gives a self-contained HTML player well under MAX_BYTES."""
    h = _pf_history(steps=4)
    html = animation.show_animation(animation.animate_landmark_pf(cWorld(), h, h["path"])).data
    assert "<script" in html and "anim" in html.lower()
    assert len(html) < animation.MAX_BYTES
    assert plt.get_fignums() == []  # the figure is closed: no stray static frame


def test_mcl_animation_follows_the_snapshots():
    """One frame per snapshot time, drawing that snapshot's particles and the truth then."""
    from robolab.maps import load_maze

    grid = load_maze()
    rng = np.random.default_rng(1)
    times = [0.0, 1.0, 2.0]
    snaps = {t: (rng.uniform(0.5, 3.0, (30, 3)), np.full(30, 1 / 30)) for t in times}
    t = np.array([0.0, 0.5, 1.0, 1.5, 2.0])
    truth = np.column_stack([t + 1, t + 1, t * 0])
    result = {"snapshots": snaps, "t": t, "truth": truth, "estimate": truth + 0.1,
              "position_error": np.full(5, 0.14)}
    anim = animation.animate_mcl(grid, result)
    frames = list(anim.new_frame_seq())
    assert len(frames) == 3
    cloud, truth_dot, _ = anim._func(frames[1])
    np.testing.assert_allclose(cloud.get_offsets(), snaps[1.0][0][:, :2])
    assert truth_dot.get_data()[0][0] == pytest.approx(2.0)
    with pytest.raises(ValueError, match="at least 2 snapshots"):
        animation.animate_mcl(grid, {**result, "snapshots": {0.0: snaps[0.0]}})


def test_fastslam_replay_records_the_step_it_runs_and_maps_only_what_was_seen():
    """The replay steps fastslam_step over the run; landmarks are NaN until first observed."""
    from solutions.fastslam import fastslam_step, init_particles

    run = FiducialRobot(seed=0, n_steps=40)
    rep = animation.replay_fastslam(run, init_particles, fastslam_step, 20,
                                    np.random.default_rng(0), every=10)
    assert list(rep["step"]) == [0, 10, 20, 30, 40]
    assert rep["poses"].shape == (5, 20, 3)
    assert np.isnan(rep["landmarks"][0]).all()  # nothing seen before the first step
    seen = np.isfinite(rep["landmarks"][-1]).all(axis=1)
    assert seen.any()
    err = np.linalg.norm(rep["landmarks"][-1][seen] - rep["fiducials"][seen], axis=1)
    assert err.max() < 1.0, err  # the replay runs the real filter, not noise
    anim = animation.animate_fastslam(rep)
    assert len(list(anim.new_frame_seq())) == 5


@pytest.mark.parametrize("kind", ["landmark_pf", "mcl"])
def test_blitted_frames_are_the_pixels_of_a_full_draw(kind):
    """render_frames draws the still parts once: each frame must equal savefig of that frame."""
    import base64
    import io

    from PIL import Image

    if kind == "landmark_pf":
        h = _pf_history(steps=3)
        anim = animation.animate_landmark_pf(cWorld(), h, h["path"])
    else:
        from robolab.maps import load_maze

        rng = np.random.default_rng(2)
        snaps = {t: (rng.uniform(0.5, 3.0, (40, 3)), np.full(40, 1 / 40)) for t in (0.0, 1.0, 2.0)}
        t = np.array([0.0, 1.0, 2.0])
        truth = np.column_stack([t + 1, t + 0.5, t * 0])
        anim = animation.animate_mcl(load_maze(), {"snapshots": snaps, "t": t, "truth": truth,
                                                   "estimate": truth + 0.2,
                                                   "position_error": np.full(3, 0.28)})
    fig = anim._fig
    fig.set_dpi(animation.FRAME_DPI)
    frames = animation.render_frames(anim)
    assert len(frames) == 3
    for k, frame in enumerate(list(anim.new_saved_frame_seq())):
        anim._func(frame)
        full = io.BytesIO()
        fig.savefig(full, format="png", dpi=animation.FRAME_DPI)
        blitted = np.asarray(Image.open(io.BytesIO(base64.b64decode(frames[k]))))
        np.testing.assert_array_equal(blitted, np.asarray(Image.open(full)))
    assert len(set(frames)) == 3  # and the frames differ: the changing artists are drawn
