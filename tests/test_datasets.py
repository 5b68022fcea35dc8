"""robolab.datasets: readers for CARMEN, Freiburg, MRCLAM and ROS bags, and the download.

Small files in each format are written here with known content (the oracle);
the real files in ../shared/data are read where present (skipped when absent).
No test touches the network: pooch's download is replaced.
"""

from __future__ import annotations

import gzip
from pathlib import Path

import numpy as np
import pytest

from robolab.bag import BagError, BagWriter
from robolab.datasets import (
    REGISTRY,
    CarmenError,
    DataSetUnavailable,
    FreiburgError,
    MrclamError,
    fetch,
    locate,
    read_carmen,
    read_freiburg,
    read_mrclam,
    read_recording,
    read_track,
)
from robolab.geometry import angle_diff, compose, relative, wrap_angle

SHARED = Path(__file__).resolve().parents[1].parent / "shared" / "data"
INTEL = SHARED / "intel_lab" / "intel-corrected.log.gz"
FREIBURG = SHARED / "freiburg_course"
OLIN = SHARED / "olin_ac109_1"

# ------------------------------------------------------------------------------- CARMEN
CARMEN_LOG = """\
# message formats defined: PARAM SYNC ODOM FLASER RLASER TRUEPOS
PARAM robot_frontlaser_offset 0.0 nohost 0
ODOM 0 0 0 0 0 0 0.5 host 0.5
ODOM 1 0 0.1 0.2 0.05 0 1.5 host 1.5
FLASER 4 1.0 2.0 3.0 81.83 0.1 0.2 0.3 0.4 0.5 0.6 1.0 host 1.0
FLASER 4 1.5 2.5 3.5 81.83 0.2 0.3 0.4 0.5 0.6 0.7 2.0 host 2.0
ROBOTLASER1 0 -1.5 3.0 1.0 20.0 0.01 0 3 1 2 3 0 0.5 0.6 0.7 0.4 0.5 0.6 0 0 0 0 0 1.2 host 1.2
RAWLASER1 0 -1.5 3.0 1.5 20.0 0.01 0 3 1 2 3 2 9 9 1.3 host 1.3
TRUEPOS 1 2 0.5 0 0 0 1.4 host 1.4
NEFF 15
"""


@pytest.fixture(params=["plain", "gzip"])
def carmen_file(tmp_path, request):
    if request.param == "plain":
        path = tmp_path / "run.log"
        path.write_text(CARMEN_LOG)
    else:
        path = tmp_path / "run.log.gz"
        with gzip.open(path, "wt") as fh:
            fh.write(CARMEN_LOG)
    return path


def test_carmen_fields_land_in_the_right_arrays(carmen_file):
    log = read_carmen(carmen_file)
    np.testing.assert_array_equal(log.odometry.stamps, [0.5, 1.5])
    np.testing.assert_allclose(log.odometry.poses[1], [1.0, 0.0, 0.1])
    np.testing.assert_allclose(log.velocities, [[0, 0], [0.2, 0.05]])
    fl = log.laser()  # FLASER is the default
    assert len(fl) == 2 and fl.scans.ranges.shape == (2, 4)
    np.testing.assert_allclose(fl.scans.ranges[1], [1.5, 2.5, 3.5, 81.83])
    np.testing.assert_allclose(fl.laser_poses[0], [0.1, 0.2, 0.3])
    np.testing.assert_allclose(fl.robot_poses[1], [0.5, 0.6, 0.7])
    np.testing.assert_array_equal(fl.scans.stamps, [1.0, 2.0])
    np.testing.assert_allclose(fl.scans.angles, -np.pi / 2 + np.pi / 4 * np.arange(4))
    assert fl.scans.range_max == 81.83 and not fl.scans.valid[0, 3]  # a no-return reading
    rl = log.laser("ROBOTLASER1")
    np.testing.assert_allclose(rl.scans.angles, [-1.5, -0.5, 0.5])
    assert rl.scans.range_max == 20.0
    np.testing.assert_allclose(rl.laser_poses[0], [0.5, 0.6, 0.7])
    np.testing.assert_allclose(rl.robot_poses[0], [0.4, 0.5, 0.6])
    assert rl.scans.stamps[0] == 1.2
    raw = log.laser("RAWLASER1")
    np.testing.assert_allclose(raw.scans.angles, [-1.5, 0.0, 1.5])
    assert raw.laser_poses is None and raw.scans.stamps[0] == 1.3
    np.testing.assert_allclose(log.truth.poses[0], [1, 2, 0.5])
    assert log.params == {"robot_frontlaser_offset": "0.0"}


@pytest.mark.parametrize("n, step", [(180, 1.0), (181, 1.0), (360, 0.5), (361, 0.5)])
def test_carmen_flaser_covers_180_degrees_from_minus_90(tmp_path, n, step):
    path = tmp_path / "f.log"
    path.write_text(f"FLASER {n} " + "1.0 " * n + "0 0 0 0 0 0 3.0 h 3.0\n")
    angles = np.rad2deg(read_carmen(path).laser().scans.angles)
    np.testing.assert_allclose(angles, -90.0 + step * np.arange(n), atol=1e-9)
    custom = read_carmen(path, start_angle=0.0, angular_resolution=0.01).laser().scans.angles
    np.testing.assert_allclose(custom, 0.01 * np.arange(n))


@pytest.mark.parametrize(
    "line, where",
    [
        ("FLASER 4 1 2 3 4 0 0 0 0 0\n", ":1:"),  # too few fields
        ("ODOM 0 0 x 0 0 0 0.5 h 0.5\n", ":1:"),  # not a number
        ("ODOM 0 0 0\n", ":1:"),
        ("ROBOTLASER1 0 -1.5 3.0 1.0 20.0 0.01 0 5 1 2\n", ":1:"),
    ],
)
def test_carmen_malformed_lines_name_the_line(tmp_path, line, where):
    path = tmp_path / "bad.log"
    path.write_text(line)
    with pytest.raises(CarmenError, match=where):
        read_carmen(path)


def test_carmen_scans_of_different_lengths_and_missing_files_raise(tmp_path):
    path = tmp_path / "mixed.log"
    path.write_text("FLASER 2 1 2 0 0 0 0 0 0 1 h 1\nFLASER 3 1 2 3 0 0 0 0 0 0 2 h 2\n")
    with pytest.raises(CarmenError, match="different lengths"):
        read_carmen(path)
    with pytest.raises(FileNotFoundError):
        read_carmen(tmp_path / "none.log")
    one = tmp_path / "one.log"
    one.write_text("FLASER 2 1 2 0 0 0 0 0 0 1 h 1\n")
    with pytest.raises(CarmenError, match="no RLASER"):
        read_carmen(one).laser("RLASER")


@pytest.fixture(scope="module")
def intel():
    if not INTEL.is_file():
        pytest.skip("../shared/data/intel_lab not present")
    return read_carmen(INTEL)


def _sharpness(laser, angles) -> float:
    """Concentration of all scan endpoints on a 10 cm grid: sum of squared cell shares."""
    scans = laser.scans
    valid = scans.valid
    a = laser.laser_poses[:, 2:3] + angles[None, :]
    x = laser.laser_poses[:, 0:1] + scans.ranges * np.cos(a)
    y = laser.laser_poses[:, 1:2] + scans.ranges * np.sin(a)
    cells = np.floor(np.stack([x[valid], y[valid]], -1) / 0.1).astype(np.int64)
    _, counts = np.unique(cells, axis=0, return_counts=True)
    share = counts / counts.sum()
    return float(np.sum(share**2))


def test_intel_log_reads_whole_and_its_beam_geometry_is_the_sharpest(intel):
    laser = intel.laser("FLASER")
    assert len(laser) == 910 and laser.scans.beams == 180
    assert len(intel.odometry) == 14541
    assert laser.scans.range_max == pytest.approx(81.83)
    assert np.sum(np.diff(laser.scans.stamps) <= 0) == 4  # kept in log order, as recorded
    # a corrected log: the laser pose field is the corrected pose (here equal to the odom field)
    np.testing.assert_allclose(laser.laser_poses, laser.robot_poses)
    default = laser.scans.angles
    np.testing.assert_allclose(np.rad2deg(default[[0, -1]]), [-90.0, 89.0])
    best = _sharpness(laser, default)
    for other in (default + np.deg2rad(2.0), default - np.deg2rad(2.0), default[::-1]):
        assert best > _sharpness(laser, other)


def test_intel_raw_odometry_anchored_at_the_corrected_start_drifts_gradually(intel):
    from robolab.geometry import anchor_odometry

    laser = intel.laser("FLASER")
    raw = intel.odometry.at(laser.scans.stamps)
    anchored = anchor_odometry(raw, laser.laser_poses[0])
    err = np.hypot(*(anchored[:, :2] - laser.laser_poses[:, :2]).T)
    assert err[0] == pytest.approx(0.0, abs=1e-9)
    assert err[:10].max() < 0.3  # the first scans agree
    assert err.max() > 1.0  # raw odometry drifts: what the corrected poses fix


# ----------------------------------------------------------------------------- Freiburg
def _freiburg(tmp_path, world="1 2 1\n2 0 4\n5 3 3\n", sensor=None):
    sensor = sensor or (
        "ODOMETRY 0.1 0.2 -0.05\nSENSOR 1 2.0 0.3\nSENSOR 5 4.0 1.4\n"
        "ODOMETRY 0.0 0.1 0.0\n"
        "ODOMETRY 0.2 0.0 0.1\nSENSOR 2 1.5 -0.2\n"
    )
    (tmp_path / "world.dat").write_text(world)
    (tmp_path / "sensor_data.dat").write_text(sensor)
    return tmp_path


def test_freiburg_steps_odometry_and_observations(tmp_path):
    data = read_freiburg(_freiburg(tmp_path))
    assert len(data) == 3
    np.testing.assert_array_equal(data.landmark_ids, [1, 2, 5])
    np.testing.assert_allclose(data.landmarks, [[2, 1], [0, 4], [3, 3]])
    np.testing.assert_allclose(data.odometry[0], [0.1, 0.2, -0.05])
    np.testing.assert_allclose(data.observations[0], [[2.0, 0.3, 1], [4.0, 1.4, 5]])
    assert data.observations[1].shape == (0, 3)
    np.testing.assert_allclose(data.indexed_observations(0), [[2.0, 0.3, 0], [4.0, 1.4, 2]])
    np.testing.assert_array_equal(data.landmark_index([5, 1, 2]), [2, 0, 1])
    with pytest.raises(ValueError, match=r"\[7\]"):
        data.landmark_index([7])


@pytest.mark.parametrize(
    "sensor, match",
    [
        ("SENSOR 1 2.0 0.3\n", "before the first ODOMETRY"),
        ("ODOMETRY 0.1 0.2\n", "needs 3 fields"),
        ("ODOMETRY 0.1 0.2 x\n", ":1:"),
        ("ODOMETRY 0 0 0\nSENSOR 9 1 0\n", r"\[9\]"),
        ("ODOMETRY 0 0 0\nSENSOR 1.5 1 0\n", "integer"),
        ("ODOMETRY 0 0 0\nSENSOR 1 -1 0\n", ">= 0"),
        ("ODOMETRY 0 0 nan\n", "finite"),
        ("LASER 1 2 3\n", "unknown line type"),
    ],
)
def test_freiburg_malformed_files_raise_naming_the_problem(tmp_path, sensor, match):
    with pytest.raises(FreiburgError, match=match):
        read_freiburg(_freiburg(tmp_path, sensor=sensor))


def test_freiburg_repeated_world_ids_raise(tmp_path):
    with pytest.raises(FreiburgError, match="repeat"):
        read_freiburg(_freiburg(tmp_path, world="1 0 0\n1 1 1\n"))


@pytest.mark.skipif(not FREIBURG.is_dir(), reason="../shared/data/freiburg_course not present")
def test_freiburg_real_data_reads_and_its_observations_fit_dead_reckoning():
    data = read_freiburg(FREIBURG)
    assert len(data) == 331 and data.landmarks.shape == (9, 2)
    assert sum(len(o) for o in data.observations) > 300
    # dead reckoning with the odometry model, started at the origin (the course's start),
    # projects the first observations onto their landmarks
    pose, errs = np.zeros(3), []
    for i in range(10):
        r1, t, r2 = data.odometry[i]
        pose = np.array(
            [
                pose[0] + t * np.cos(pose[2] + r1),
                pose[1] + t * np.sin(pose[2] + r1),
                wrap_angle(pose[2] + r1 + r2),
            ]
        )
        for r, b, j in data.indexed_observations(i):
            seen = pose[:2] + r * np.array([np.cos(pose[2] + b), np.sin(pose[2] + b)])
            errs.append(np.hypot(*(seen - data.landmarks[int(j)])))
    assert np.median(errs) < 0.3


# ------------------------------------------------------------------------------- MRCLAM
LM = {6: (1.0, 2.0), 7: (3.0, -1.0), 8: (-2.0, 0.5)}
BARCODES = {1: 5, 2: 14, 3: 41, 4: 32, 5: 23, 6: 72, 7: 27, 8: 54}


def _truth(t):
    """A circle of radius 1 around the origin, 0.5 rad/s."""
    return np.column_stack([np.cos(0.5 * t), np.sin(0.5 * t), wrap_angle(0.5 * t + np.pi / 2)])


def _mrclam(folder: Path) -> Path:
    header = "# Subject #    Barcode #\n"
    (folder / "Barcodes.dat").write_text(
        header + "".join(f"{s} {b}\n" for s, b in BARCODES.items())
    )
    (folder / "Landmark_Groundtruth.dat").write_text(
        "# Subject # x [m] y [m] x std-dev [m] y std-dev [m]\n"
        + "".join(f"{s} {x} {y} 0.001 0.002\n" for s, (x, y) in LM.items())
    )
    tg = np.arange(0.0, 10.0001, 0.01) + 100.0
    gt = np.column_stack([tg, _truth(tg - 100.0)])
    (folder / "Robot1_Groundtruth.dat").write_text(
        "# Time [s] x [m] y [m] orientation [rad]\n"
        + "".join(" ".join(f"{v:.9f}" for v in r) + "\n" for r in gt)
    )
    to = np.arange(100.013, 109.9, 0.0333)
    v = np.where(to < 105.0, 0.5, 0.25)  # the command changes at 105 s
    (folder / "Robot1_Odometry.dat").write_text(
        "# Time [s] forward velocity [m/s] angular velocity[rad/s]\n"
        + "".join(f"{t:.6f} {vv} 0.5\n" for t, vv in zip(to, v, strict=True))
    )
    rows = []
    for t in np.arange(100.5, 109.5, 0.37):
        pose = _truth(np.array([t - 100.0]))[0]
        for s, code in ((6, 72), (7, 27), (2, 14), (9, 99)):
            target = LM.get(s, (0.3, 0.3))
            d = np.subtract(target, pose[:2])
            rows.append((t, code, np.hypot(*d), wrap_angle(np.arctan2(d[1], d[0]) - pose[2])))
    (folder / "Robot1_Measurement.dat").write_text(
        "# Time [s] Subject # range [m] bearing [rad]\n"
        + "".join(f"{t:.6f} {c} {r:.9f} {b:.9f}\n" for t, c, r, b in rows)
    )
    return folder


def test_mrclam_aligns_streams_and_maps_barcodes_to_landmarks(tmp_path):
    run = read_mrclam(_mrclam(tmp_path), robot=1)
    assert run.t[0] == pytest.approx(100.013)  # the later first sample (odometry)
    np.testing.assert_allclose(np.diff(run.t), 0.02)
    np.testing.assert_array_equal(run.landmark_subjects, [6, 7, 8])
    np.testing.assert_allclose(run.landmarks, [LM[6], LM[7], LM[8]])
    np.testing.assert_allclose(run.landmark_sd[0], [0.001, 0.002])
    assert run.barcodes[72] == 6
    # ground truth interpolated at the steps (a circle: linear interpolation errs < 1e-4 m)
    np.testing.assert_allclose(run.truth[:, :2], _truth(run.t - 100.0)[:, :2], atol=1e-4)
    # zero-order hold of the commands
    assert np.all(run.commands[run.t < 104.9, 0] == 0.5)
    assert np.all(run.commands[run.t > 105.1, 0] == 0.25)
    # only landmark measurements, rows 0/1 for subjects 6/7, assigned to the nearest step;
    # seen from the truth at that step they land on their landmark
    m = run.measurements
    assert set(m[:, 3].astype(int)) == {0, 1}
    assert np.all(np.diff(m[:, 0]) >= 0)
    for step, r, b, row in m:
        p = run.truth[int(step)]
        seen = p[:2] + r * np.array([np.cos(p[2] + b), np.sin(p[2] + b)])
        np.testing.assert_allclose(seen, run.landmarks[int(row)], atol=0.02)  # 0.01 s * 0.5 m/s
    # robot 2 (barcode 14) and the unknown barcode 99 are kept apart
    assert set(run.other_measurements[:, 3].astype(int)) == {14, 99}
    obs = run.observations(int(m[0, 0]))
    assert obs.shape[1] == 3 and len(obs) == 2


def test_mrclam_errors_name_the_file(tmp_path):
    folder = _mrclam(tmp_path)
    with pytest.raises(FileNotFoundError, match="Robot2_Groundtruth"):
        read_mrclam(folder, robot=2)
    (folder / "Barcodes.dat").write_text("1 5 7\n")
    with pytest.raises(MrclamError, match="Barcodes.dat:1"):
        read_mrclam(folder)
    _mrclam(folder)
    (folder / "Robot1_Odometry.dat").write_text("200.0 0.1 0.0\n201.0 0.1 0.0\n")
    with pytest.raises(MrclamError, match="overlap"):
        read_mrclam(folder)


# ------------------------------------------------------------------------------ ROS bags
@pytest.fixture(scope="module")
def truth_bag(tmp_path_factory):
    """A bag whose ground truth comes as PoseStamped, as TF and as Odometry, on /scan."""
    path = tmp_path_factory.mktemp("bags") / "real_like.bag"
    t = 1000.0 + np.arange(0.0, 5.0, 0.1)
    truth = np.column_stack([0.5 * np.cos(t), 0.5 * np.sin(t), wrap_angle(t)])
    odom_start = np.array([0.07, 0.17, 1.98])  # odometry does not start at the origin
    odom = compose(odom_start, relative(truth[0], truth))
    with BagWriter(path) as w:
        for k, s in enumerate(t):
            w.write_odometry("/odom", s, odom[k], frame_id="odom", child_frame_id="base_link")
            w.write_pose_stamped("/map_pose", s, truth[k], frame_id="map")
            w.write_odometry("/gt", s, truth[k], frame_id="map", child_frame_id="base_link")
            map_to_odom = compose(truth[k], relative(odom[k], np.zeros(3)))
            w.write_tf(
                s,
                [
                    ("map", "odom", map_to_odom),
                    ("odom", "base_link", odom[k]),
                    ("base_link", "laser", (0.1, 0.0, np.pi)),
                ],
            )
            w.write_scan(
                "/scan",
                s + 0.05,
                np.full(8, 2.0),
                angle_min=-np.pi,
                angle_increment=np.pi / 4,
                range_min=0.1,
                range_max=5.0,
                frame_id="laser",
            )
    return path, t, truth, odom


@pytest.mark.parametrize("source", ["/map_pose", "map_pose", "/gt", ("/tf", "map", "base_link")])
def test_every_kind_of_truth_source_gives_the_same_track(truth_bag, source):
    path, t, truth, _ = truth_bag
    from robolab.bag import BagReader

    with BagReader(path) as bag:
        track = read_track(bag, source)
    poses = track.at(t[1:-1])
    np.testing.assert_allclose(poses[:, :2], truth[1:-1, :2], atol=1e-9)
    np.testing.assert_allclose(angle_diff(poses[:, 2], truth[1:-1, 2]), 0, atol=1e-9)


def test_read_recording_with_configured_topics(truth_bag):
    path, t, truth, odom = truth_bag
    rec = read_recording(path, scan_topic="/scan", truth="/map_pose")
    assert len(rec) == len(t) - 1  # the last scan (after the last truth) is dropped
    np.testing.assert_allclose(rec.laser_pose, [0.1, 0.0, -np.pi])
    # truth interpolated at the scan stamps (0.05 s after the truth samples, on the circle)
    np.testing.assert_allclose(
        rec.truth[0, :2], 0.5 * np.array([np.cos(t[0] + 0.05), np.sin(t[0] + 0.05)]), atol=3e-3
    )
    same = read_recording(
        path,
        scan_topic="/scan",
        truth=("/tf", "map", "base_link"),
        odom=("/tf", "odom", "base_link"),
    )
    np.testing.assert_allclose(same.truth, rec.truth, atol=1e-9)
    np.testing.assert_allclose(same.odom, rec.odom, atol=1e-9)
    delayed = read_recording(path, scan_topic="/scan", truth="/map_pose", truth_delay=0.05)
    np.testing.assert_allclose(
        delayed.truth[:-1], read_track_at(path, rec.scans.stamps[:-1] + 0.05)
    )
    # late scans: odometry and truth are both read scan_delay before each scan's stamp
    late = read_recording(path, scan_topic="/scan", truth="/map_pose", scan_delay=0.05)
    stamps = late.scans.stamps
    assert stamps[0] >= rec.scans.stamps[0] and len(stamps) <= len(rec.scans.stamps)
    np.testing.assert_allclose(late.truth, read_track_at(path, stamps - 0.05))
    np.testing.assert_allclose(late.odom, read_track_at(path, stamps - 0.05, "/odom"))
    with pytest.raises(ValueError, match="scan_delay"):
        read_recording(path, scan_topic="/scan", truth="/map_pose", scan_delay=float("nan"))


def read_track_at(path, stamps, topic="/map_pose"):
    from robolab.bag import BagReader

    with BagReader(path) as bag:
        return read_track(bag, topic).at(stamps)


def test_read_recording_errors_name_what_is_wrong(truth_bag):
    path = truth_bag[0]
    with pytest.raises(BagError, match="/base_scan"):
        read_recording(path)  # the simulated bags' default topic is not in this bag
    with pytest.raises(BagError, match="pose source"):
        read_recording(path, scan_topic="/scan", truth="/scan")
    with pytest.raises(TypeError, match="pose source"):
        read_recording(path, scan_topic="/scan", truth=42)
    with pytest.raises(BagError):
        read_recording(path, scan_topic="/scan", truth=("/tf", "map", "nowhere"))


@pytest.mark.skipif(not OLIN.is_dir(), reason="../shared/data/olin_ac109_1 not present")
def test_load_localization_reads_the_real_neato_bag():
    from robolab.plotting.mcl import load_localization

    data = load_localization(
        OLIN / "ac109_1_demo.bag", OLIN / "ac109_1.yaml", scan_topic="/scan", truth="/map_pose"
    )
    assert data.ranges.shape[1] == 361 and len(data) > 500
    np.testing.assert_allclose(data.laser_pose, [-0.1016, 0.0, -np.pi], atol=1e-5)
    assert data.grid.resolution == pytest.approx(0.02)
    # the truth lies inside the mapped room
    assert np.all(data.grid.contains(data.truth[:, :2]))


# ------------------------------------------------------------------------------- fetch
def test_registry_pins_commits_and_sha256():
    for files in REGISTRY.values():
        for fname, remote in files.items():
            assert remote.url.endswith("/" + fname) and remote.url.startswith("https://")
            assert len(remote.sha256) == 64 and int(remote.sha256, 16) >= 0


@pytest.mark.parametrize("name", sorted(REGISTRY))
def test_registry_hashes_match_the_local_copies(name):
    import hashlib

    folder = SHARED / name
    if not folder.is_dir():
        pytest.skip(f"{folder} not present")
    for fname, remote in REGISTRY[name].items():
        assert hashlib.sha256((folder / fname).read_bytes()).hexdigest() == remote.sha256


def test_fetch_downloads_into_the_cache_with_the_pinned_hash(tmp_path, monkeypatch):
    import pooch

    calls = []

    def fake_retrieve(url, known_hash, fname, path, progressbar):
        calls.append((url, known_hash, fname, Path(path)))
        Path(path).mkdir(parents=True, exist_ok=True)
        (Path(path) / fname).write_text("x")
        return str(Path(path) / fname)

    monkeypatch.setenv("ROBOLAB_DATA_CACHE", str(tmp_path))
    monkeypatch.setattr(pooch, "retrieve", fake_retrieve)
    folder = fetch("freiburg_course")
    assert folder == tmp_path / "freiburg_course"
    assert {c[2] for c in calls} == {"world.dat", "sensor_data.dat"}
    for url, known, fname, path in calls:
        assert known == f"sha256:{REGISTRY['freiburg_course'][fname].sha256}"
        assert url == REGISTRY["freiburg_course"][fname].url and path == folder
    assert locate("freiburg_course", roots=[tmp_path / "elsewhere"]) == folder.resolve()


def test_fetch_offline_says_which_file_and_how_to_place_it(tmp_path, monkeypatch):
    import pooch
    import requests

    def offline(**kwargs):
        raise requests.exceptions.ConnectionError("Name or service not known")

    monkeypatch.setenv("ROBOLAB_DATA_CACHE", str(tmp_path))
    monkeypatch.setattr(pooch, "retrieve", offline)
    with pytest.raises(DataSetUnavailable) as info:
        fetch("intel_lab")
    msg = str(info.value)
    assert "intel-corrected.log.gz" in msg and "offline" in msg
    assert (
        str(tmp_path / "intel_lab") in msg
        and REGISTRY["intel_lab"]["intel-corrected.log.gz"].sha256 in msg
    )


def test_fetch_and_locate_reject_unknown_names(tmp_path, monkeypatch):
    monkeypatch.setenv("ROBOLAB_DATA_CACHE", str(tmp_path))
    with pytest.raises(ValueError, match="intel_lab"):
        fetch("nope")
    with pytest.raises(ValueError, match="known"):
        locate("nope")
    assert locate("intel_lab", roots=[tmp_path / "empty"]) is None


# -- files that are not what a reader expects (issue 25): one class each, every text reader ---


def _scan_lines(n: int, stamp_format: str) -> str:
    return "".join(
        f"FLASER 3 1 2 3 0 0 0 0 0 0 {1134860000 + 0.1 * i:{stamp_format}} h 0\n" for i in range(n)
    )


def _text_file_cases(tmp_path: Path, content: str) -> dict[str, tuple[Path, str]]:
    """The same bad inputs for any text reader: name -> (file, a word its error holds)."""
    cases = {}
    tmp_path.mkdir(parents=True, exist_ok=True)
    binary = tmp_path / "binary.dat"
    binary.write_bytes(bytes(range(256)) * 4)
    cases["binary"] = (binary, "not UTF-8")
    compressed = gzip.compress(content.encode())
    truncated = tmp_path / "truncated.dat.gz"
    truncated.write_bytes(compressed[: len(compressed) // 2])
    cases["truncated gzip"] = (truncated, "truncated or corrupt")
    corrupt = tmp_path / "corrupt.dat.gz"
    corrupt.write_bytes(compressed[:10] + b"\0" * 50 + compressed[60:])
    cases["corrupt gzip"] = (corrupt, "truncated or corrupt")
    folder = tmp_path / "folder.dat"
    folder.mkdir()
    cases["folder"] = (folder, "is a folder")
    return cases


def test_carmen_files_that_are_not_logs_raise_carmen_errors_naming_the_file(tmp_path):
    for name, (path, word) in _text_file_cases(tmp_path, _scan_lines(400, ".6f")).items():
        with pytest.raises(CarmenError, match=word) as info:
            read_carmen(path)
        assert str(path) in str(info.value), name


@pytest.mark.parametrize("content", ["", "\n\n", "# a comment\n# another\n", "PARAM a 1 h 0\n"])
def test_a_carmen_log_without_messages_is_an_error_not_an_empty_log(tmp_path, content):
    path = tmp_path / "empty.log"
    path.write_text(content)
    with pytest.raises(CarmenError, match="no CARMEN messages"):
        read_carmen(path)


def test_carmen_stamps_that_collapse_are_refused_and_full_precision_reads(tmp_path):
    # %g prints 1.13486e+09: 406 scans over 40 s share one or two stamps.
    collapsed = tmp_path / "g.log"
    collapsed.write_text(_scan_lines(406, "g"))
    with pytest.raises(CarmenError, match=r"406 FLASER messages have only \d distinct"):
        read_carmen(collapsed)
    full = tmp_path / "f.log"
    full.write_text(_scan_lines(406, ".6f"))
    stamps = read_carmen(full).laser().scans.stamps
    np.testing.assert_allclose(np.diff(stamps), 0.1, atol=1e-5)
    # Repeated stamps in pairs (two messages per stamp) are not a collapse.
    pairs = tmp_path / "p.log"
    pairs.write_text(
        "".join(f"ODOM 0 0 0 0 0 0 {100 + i // 2:.6f} h 0\n" for i in range(10))
        + _scan_lines(3, ".6f")
    )
    assert len(read_carmen(pairs).odometry.stamps) == 10


def test_freiburg_and_mrclam_files_that_are_not_text_data_raise_their_errors(tmp_path):
    for reader, error, files in (
        (read_freiburg, FreiburgError, ("world.dat", "sensor_data.dat")),
        (read_mrclam, MrclamError, ("Barcodes.dat", "Landmark_Groundtruth.dat")),
    ):
        for name, (bad, word) in _text_file_cases(tmp_path / reader.__name__, "1 2 3\n").items():
            if bad.is_dir():
                with pytest.raises(error, match="is a file|is a folder"):
                    reader(bad.parent / "binary.dat")  # a file given as the data folder
                continue
            folder = tmp_path / f"{reader.__name__}-{name.replace(' ', '_')}"
            folder.mkdir()
            for f in files:
                (folder / f).write_bytes(bad.read_bytes())
            with pytest.raises(error, match=word):
                reader(folder)


@pytest.mark.parametrize("content", ["", "# only a comment\n"])
def test_freiburg_files_without_data_are_errors_not_empty_runs(tmp_path, content):
    folder = tmp_path / "fb"
    folder.mkdir()
    (folder / "world.dat").write_text(content)
    (folder / "sensor_data.dat").write_text("ODOMETRY 0 0 0\n")
    with pytest.raises(FreiburgError, match="no landmarks"):
        read_freiburg(folder)
    (folder / "world.dat").write_text("1 0 0\n")
    (folder / "sensor_data.dat").write_text(content)
    with pytest.raises(FreiburgError, match="no ODOMETRY"):
        read_freiburg(folder)
