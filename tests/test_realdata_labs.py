"""The labs' steps onto real data (robolab.realdata), each on the data set it names.

Every test skips when its data set is absent from ../shared/data. The numbers
asserted are what independent implementations reach on the same data (issue 18):
FastSLAM 0.02-0.03 m landmark RMSE after alignment on Freiburg, MCL tracking
about 0.08 m median on the Neato bag.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from robolab.datasets import DataSetUnavailable

SHARED = Path(__file__).resolve().parents[1].parent / "shared" / "data"


def _need(name):
    if not (SHARED / name).is_dir():
        pytest.skip(f"../shared/data/{name} not present")
    return SHARED / name


# -- lab 07: FastSLAM on Freiburg ------------------------------------------------------------
@pytest.fixture(scope="module")
def freiburg():
    from robolab.datasets import read_freiburg

    return read_freiburg(_need("freiburg_course"))


@pytest.mark.parametrize("seed", [0, 1])
def test_fastslam_on_freiburg_maps_the_landmarks_with_and_without_ess(freiburg, seed):
    from robolab.realdata.fastslam import run_fastslam_freiburg
    from solutions.fastslam import fastslam_step, init_particles

    lab = {"fastslam_step": fastslam_step, "init_particles": init_particles}
    def run(ess_threshold):
        rng = np.random.default_rng(seed)
        return run_fastslam_freiburg(freiburg, 100, rng, ess_threshold=ess_threshold, **lab)

    every, ess = run(None), run(0.5)
    assert every["rmse_aligned"] < 0.05 and ess["rmse_aligned"] < 0.05
    assert every["rmse"] < 0.2 and ess["rmse"] < 0.2  # the start at the origin fixes the frame
    # the book resamples after every step with an observation; ESS only when depleted
    steps_with_obs = sum(len(o) > 0 for o in freiburg.observations)
    assert every["resamples"] == steps_with_obs
    assert 0 < ess["resamples"] < steps_with_obs / 5
    assert np.all(np.isfinite(ess["landmarks"])) and ess["path"].shape == (len(freiburg) + 1, 3)


def test_fastslam_ess_none_is_the_old_behaviour(freiburg):
    """ess_threshold=None is resample=True: the same run as a step that always resamples."""
    from robolab.realdata.fastslam import run_fastslam_freiburg
    from solutions.fastslam import fastslam_step, init_particles

    def old_step(state, command, observations, Q, Qt, rng, dt=1.0, resample=True):
        assert resample is True
        return fastslam_step(state, command, observations, Q, Qt, rng, dt)

    a = run_fastslam_freiburg(
        freiburg, 30, np.random.default_rng(4), ess_threshold=None,
        fastslam_step=fastslam_step, init_particles=init_particles,
    )
    b = run_fastslam_freiburg(
        freiburg, 30, np.random.default_rng(4), ess_threshold=None,
        fastslam_step=old_step, init_particles=init_particles,
    )
    np.testing.assert_array_equal(a["landmarks"], b["landmarks"])


@pytest.mark.parametrize("qt_scale", [1e-4, 1e-2, 1.0, 100.0])
def test_fastslam_step_resamples_exactly_when_the_ess_is_low(qt_scale):
    from solutions.fastslam import fastslam_step, init_particles

    q, qt = np.diag([0.01, 0.01, 0.01]), np.diag([0.01, 0.001]) * qt_scale
    state = init_particles(50, 2, np.zeros(3), "first_observation")
    state = fastslam_step(state, [1.0, 0.0], [[2.0, 0.3, 0]], q, qt, np.random.default_rng(0))
    assert np.allclose(state["weights"], 1 / 50)  # a first sighting only initializes
    outcomes = []
    for seed in range(6):
        args = (state, [0.2, 0.0], [[1.8, 0.35, 0]], q, qt)
        # the same rng stream up to the resampling: the same importance weights
        w = fastslam_step(*args, np.random.default_rng(seed), resample=False)["weights"]
        new = fastslam_step(*args, np.random.default_rng(seed), resample=0.5)
        low = 1.0 / np.sum(w**2) < 0.5 * 50
        resampled = bool(np.all(new["weights"] == 1 / 50))
        assert resampled == low
        if not low:
            np.testing.assert_allclose(new["weights"], w)  # kept, not reset
        outcomes.append(low)
    # tight noise depletes the particles, loose noise does not
    if qt_scale <= 1e-2:
        assert all(outcomes)
    if qt_scale >= 100:
        assert not any(outcomes)
    for bad in (1.5, 0.0, -0.5):
        with pytest.raises(ValueError, match="resample"):
            fastslam_step(state, [0.2, 0.0], None, q, qt, np.random.default_rng(0), resample=bad)


# -- lab 04: mapping the Intel lab -----------------------------------------------------------
def test_intel_corrected_poses_map_consistently_and_raw_odometry_smears():
    from robolab.datasets import read_carmen
    from robolab.evaluation import occupancy_iou, occupied_distances
    from robolab.realdata.mapping import carmen_poses, map_carmen
    from solutions.odometry_mapping import INVERSE_SENSOR_MODEL, logodds_update

    log = read_carmen(_need("intel_lab") / "intel-corrected.log.gz")
    kw = {"every": 10, "resolution": 0.2}
    even = map_carmen(log, logodds_update, INVERSE_SENSOR_MODEL, **kw)
    odd = map_carmen(log, logodds_update, INVERSE_SENSOR_MODEL, start=5, **kw)
    raw = map_carmen(
        log, logodds_update, INVERSE_SENSOR_MODEL, poses=carmen_poses(log, "odometry"), **kw
    )
    # two halves of the scans with corrected poses see the same walls ...
    assert np.median(occupied_distances(odd, even)) < 0.1
    assert occupancy_iou(odd, even, tolerance=0.2) > 0.5
    # ... raw odometry puts them elsewhere
    assert np.median(occupied_distances(raw, even)) > 0.25
    assert occupancy_iou(raw, even, tolerance=0.2) < 0.5 * occupancy_iou(odd, even, tolerance=0.2)
    # unseen space stays unknown, not walls
    assert even.occupied.mean() < 0.1 and even.unknown.mean() > 0.05


# -- lab 05: tracking on the Neato bag -------------------------------------------------------
def test_mcl_tracks_the_real_neato_robot():
    from robolab.plotting.mcl import run_mcl
    from robolab.realdata.localization import neato_localization
    from solutions.mcl import DEFAULT_PARAMS, init_gaussian, likelihood_field, mcl_step

    data = neato_localization(_need("olin_ac109_1"))
    field = likelihood_field(data.grid, 0.1, 1.0)
    params = {
        **DEFAULT_PARAMS,
        "laser_pose": data.laser_pose,
        "max_beams": 40,
        "alphas": (0.1, 0.1, 0.1, 0.1),
    }
    rng = np.random.default_rng(0)
    particles = init_gaussian(data.truth[0], np.diag([0.01, 0.01, 0.005]), 200, rng)
    res = run_mcl(data, mcl_step, particles, field, params, rng, every=3, progress=False)
    assert np.median(res["position_error"]) < 0.15
    assert np.percentile(res["position_error"], 90) < 0.4


def test_missing_real_data_raises_a_friendly_note(tmp_path):
    from robolab.realdata.localization import neato_localization

    with pytest.raises(DataSetUnavailable, match="fetch"):
        neato_localization(tmp_path)
