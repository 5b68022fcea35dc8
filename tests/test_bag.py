"""Tests for robolab.bag: round trips through ROS1 and ROS2 bags, typed views, TF, bad input."""

from __future__ import annotations

import sqlite3

import numpy as np
import pytest

from robolab.bag import (
    BagError,
    BagReader,
    BagWriter,
    PoseTrack,
    Scans,
    TfTree,
    TopicInfo,
    laser_pose_in_base,
)
from robolab.geometry import angle_diff, compose, inverse

T0 = 1486503133.25  # epoch-sized stamps, as in real bags: exercises float64 precision
DT = 0.1
N = 6
B = 8
ANGLE_MIN, ANGLE_INC = -np.pi / 2, np.pi / 7
RANGE_MIN, RANGE_MAX = 0.05, 4.0
MOUNT = np.array([-0.1, 0.02, -np.pi])  # a laser mounted backwards and offset, like the Olin Neato
STAMP_ATOL = 1e-6  # float64 resolution at 1.5e9 s is 2.4e-7 s; stamps go through integer ns


def _expected():
    rng = np.random.default_rng(3)
    ranges = rng.uniform(0.5, 3.5, (N, B)).astype(np.float32)
    ranges[0, 1] = 0.0  # Neato: no return
    ranges[1, 2] = np.inf  # other drivers: no return
    ranges[2, 3] = np.nan
    ranges[3, 4] = 4.5  # beyond range_max
    ranges[4, 5] = 0.01  # below range_min
    stamps = T0 + DT * np.arange(N)
    theta = np.array([3.0, 3.1, -3.1, -3.0, 2.0, 0.5])  # crosses +-pi between samples 1 and 2
    odom = np.column_stack([np.linspace(0, 1, N), np.linspace(0, -0.5, N), theta])
    truth = odom + np.array([1.0, 2.0, 0.0])
    truth[:, 2] = angle_diff(truth[:, 2], 0.0)
    tag = np.column_stack([np.full(N, 2.0), np.arange(N) * 0.1, np.zeros(N)])
    return {"ranges": ranges, "stamps": stamps, "odom": odom, "truth": truth, "tag": tag}


def _write_bag(path, exp, compression=None):
    with BagWriter(path, compression=compression) as bag:
        bag.write_tf(exp["stamps"][0], [("base_link", "laser", MOUNT)], topic="/tf_static")
        for k, t in enumerate(exp["stamps"]):
            bag.write_tf(
                t, [("odom", "base_link", exp["odom"][k]), ("camera", "tag", exp["tag"][k])]
            )
            bag.write_odometry(
                "/odom",
                t,
                exp["odom"][k],
                frame_id="odom",
                child_frame_id="base_link",
                twist=(0.3, -0.1),
            )
            bag.write_scan(
                "/base_scan",
                t + 0.01,
                exp["ranges"][k],
                angle_min=ANGLE_MIN,
                angle_increment=ANGLE_INC,
                range_min=RANGE_MIN,
                range_max=RANGE_MAX,
                frame_id="laser",
                scan_time=0.1,
            )
            bag.write_pose_stamped("/ground_truth", t, exp["truth"][k], frame_id="map")
    return path


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    exp = _expected()
    path = _write_bag(tmp_path_factory.mktemp("bag") / "sim.bag", exp)
    with BagReader(path) as bag:
        views = {
            "topics": bag.topics,
            "scans": bag.scans("/base_scan"),
            "odom": bag.odometry("/odom"),
            "truth": bag.poses("/ground_truth"),
            "tf": bag.tf(),
        }
    return path, exp, views


# -- writing and reading back --------------------------------------------------------------
@pytest.mark.parametrize("compression", ["lz4", "bz2"])
def test_compressed_bags_read_back_identical(tmp_path, written, compression):
    path, exp, views = written
    small = _write_bag(tmp_path / f"{compression}.bag", exp, compression=compression)
    assert small.read_bytes()[:12] == b"#ROSBAG V2.0"
    with BagReader(small) as bag:
        scans, odom = bag.scans("/base_scan"), bag.odometry("/odom")
    np.testing.assert_array_equal(scans.ranges, views["scans"].ranges)
    np.testing.assert_array_equal(odom.poses, views["odom"].poses)


def test_unknown_compression_is_refused(tmp_path):
    with pytest.raises(ValueError, match="compression"):
        BagWriter(tmp_path / "x.bag", compression="zip")


def test_written_bag_is_ros1_v2(written):
    path, _, _ = written
    assert path.read_bytes()[:12] == b"#ROSBAG V2.0"


def test_topics_list_types_and_counts(written):
    _, _, views = written
    assert views["topics"] == {
        "/base_scan": TopicInfo("/base_scan", "sensor_msgs/msg/LaserScan", N),
        "/ground_truth": TopicInfo("/ground_truth", "geometry_msgs/msg/PoseStamped", N),
        "/odom": TopicInfo("/odom", "nav_msgs/msg/Odometry", N),
        "/tf": TopicInfo("/tf", "tf2_msgs/msg/TFMessage", N),
        "/tf_static": TopicInfo("/tf_static", "tf2_msgs/msg/TFMessage", 1),
    }


def test_scans_round_trip(written):
    _, exp, views = written
    scans = views["scans"]
    assert isinstance(scans, Scans) and len(scans) == N and scans.beams == B
    np.testing.assert_allclose(scans.stamps, exp["stamps"] + 0.01, rtol=0, atol=STAMP_ATOL)
    np.testing.assert_array_equal(scans.ranges, exp["ranges"])  # NaN == NaN here
    assert scans.ranges.dtype == np.float64 and scans.stamps.dtype == np.float64
    # angles come from float32 fields: equal to float32 precision
    np.testing.assert_allclose(scans.angles, ANGLE_MIN + ANGLE_INC * np.arange(B), atol=1e-6)
    assert scans.range_min == pytest.approx(RANGE_MIN)
    assert scans.range_max == pytest.approx(RANGE_MAX)
    assert scans.frame_id == "laser"


def test_scans_valid_rejects_no_return_and_out_of_range(written):
    _, exp, views = written
    expected = np.ones((N, B), dtype=bool)
    for k, j in [(0, 1), (1, 2), (2, 3), (3, 4), (4, 5)]:
        expected[k, j] = False
    np.testing.assert_array_equal(views["scans"].valid, expected)


def test_scan_endpoints_in_laser_and_world_frame(written):
    _, exp, views = written
    scans = views["scans"]
    local = scans.endpoints(0)
    ok = np.arange(B) != 1
    r = exp["ranges"][0, ok].astype(float)
    a = scans.angles[ok]
    np.testing.assert_allclose(local, np.column_stack([r * np.cos(a), r * np.sin(a)]), atol=1e-12)
    # Laser mounted backwards: a beam at angle 0 points along the robot's -x.
    robot = np.array([1.0, 2.0, np.pi / 2])
    world = scans.endpoints(0, compose(robot, MOUNT))
    assert world.shape == (B - 1, 2)
    expected = local @ np.array([[-1.0, 0.0], [0.0, -1.0]]).T  # rotate by -pi
    expected = expected + MOUNT[:2]
    c, s = np.cos(robot[2]), np.sin(robot[2])
    expected = expected @ np.array([[c, -s], [s, c]]).T + robot[:2]
    np.testing.assert_allclose(world, expected, atol=1e-12)
    with pytest.raises(IndexError, match="scan index"):
        scans.endpoints(N)


def test_odometry_round_trip(written):
    _, exp, views = written
    odom = views["odom"]
    assert (odom.frame_id, odom.child_frame_id) == ("odom", "base_link")
    np.testing.assert_allclose(odom.stamps, exp["stamps"], rtol=0, atol=STAMP_ATOL)
    np.testing.assert_allclose(odom.poses[:, :2], exp["odom"][:, :2], atol=1e-12)
    np.testing.assert_allclose(angle_diff(odom.theta, exp["odom"][:, 2]), 0, atol=1e-12)


def test_pose_stamped_round_trip(written):
    _, exp, views = written
    truth = views["truth"]
    assert truth.frame_id == "map"
    np.testing.assert_allclose(truth.poses[:, :2], exp["truth"][:, :2], atol=1e-12)
    np.testing.assert_allclose(angle_diff(truth.theta, exp["truth"][:, 2]), 0, atol=1e-12)


def test_tf_edges_static_and_several_trees(written):
    _, exp, views = written
    tf = views["tf"]
    assert set(tf.edges) == {("odom", "base_link"), ("camera", "tag"), ("base_link", "laser")}
    assert tf.static == {("base_link", "laser")}
    np.testing.assert_allclose(tf.edges[("camera", "tag")].poses, exp["tag"], atol=1e-12)
    with pytest.raises(BagError, match="different trees"):
        tf.lookup("odom", "tag", exp["stamps"][1])
    with pytest.raises(BagError, match="base_link.*camera|camera.*base_link"):
        tf.lookup("odom", "nowhere", exp["stamps"][1])


def test_laser_pose_in_base_from_static_tf(written):
    _, _, views = written
    mount = laser_pose_in_base(views["tf"], "laser")
    np.testing.assert_allclose(mount[:2], MOUNT[:2], atol=1e-12)
    assert angle_diff(mount[2], MOUNT[2]) == pytest.approx(0, abs=1e-12)
    assert -np.pi <= mount[2] < np.pi


def test_tf_lookup_chains_and_inverts(written):
    _, exp, views = written
    tf = views["tf"]
    t = exp["stamps"][1] + 0.5 * DT  # halfway, across the +-pi wrap of theta
    odom_base = tf.lookup("odom", "base_link", t)
    mid = 0.5 * (exp["odom"][1] + exp["odom"][2])
    np.testing.assert_allclose(odom_base[:2], mid[:2], atol=1e-6)
    assert abs(angle_diff(odom_base[2], -np.pi)) < 1e-6  # 3.1 and -3.1 meet at pi, not 0
    odom_laser = tf.lookup("odom", "/laser", t)  # tf2 ignores a leading slash
    np.testing.assert_allclose(odom_laser, compose(odom_base, MOUNT), atol=1e-9)
    laser_odom = tf.lookup("laser", "odom", t)
    np.testing.assert_allclose(compose(laser_odom, odom_laser), 0, atol=1e-9)
    many = tf.lookup("odom", "laser", exp["stamps"][:3])
    assert many.shape == (3, 3)
    with pytest.raises(BagError, match="outside the time range"):
        tf.lookup("odom", "laser", exp["stamps"][-1] + 1.0)
    with pytest.raises(BagError, match="changes over time"):
        tf.lookup("odom", "laser")  # t=None asks for a rigid transform


def test_messages_in_time_order_like_process_bag(written):
    path, exp, _ = written
    with BagReader(path) as bag:
        seen = list(bag.messages(["/tf", "base_scan"]))  # processBag spells it without a slash
    assert [topic for topic, _, _ in seen] == ["/tf", "/base_scan"] * N
    stamps = np.array([s for _, s, _ in seen])
    assert np.all(np.diff(stamps) >= 0)
    np.testing.assert_allclose(stamps[1::2], exp["stamps"] + 0.01, atol=STAMP_ATOL)
    scan_msg = seen[1][2]
    np.testing.assert_array_equal(scan_msg.ranges, exp["ranges"][0])
    assert [tr.child_frame_id for tr in seen[0][2].transforms] == ["base_link", "tag"]


def test_preload_reads_once_for_all_views(written, monkeypatch):
    path, exp, views = written
    with BagReader(path) as bag:
        assert bag.preload() is bag

        def no_second_pass(*args):
            raise AssertionError("typed view read the file again after preload()")

        monkeypatch.setattr(bag, "_iterate", no_second_pass)
        np.testing.assert_array_equal(bag.scans("/base_scan").ranges, exp["ranges"])
        np.testing.assert_array_equal(bag.odometry("odom").poses, views["odom"].poses)
        assert set(bag.tf().edges) == set(views["tf"].edges)


def test_progress_bar_when_asked(written, capsys):
    path, _, _ = written
    with BagReader(path, progress=True) as bag:
        bag.odometry("/odom")
    assert "sim.bag" in capsys.readouterr().err


# -- PoseTrack -------------------------------------------------------------------------------
def test_pose_track_interpolates_shortest_arc():
    track = PoseTrack([0.0, 1.0, 2.0], [[0, 0, 3.0], [2, 4, -3.0], [2, 4, -3.0]], "a", "b")
    np.testing.assert_allclose(track.at(0.5)[:2], [1, 2])
    assert abs(angle_diff(track.at(0.5)[2], np.pi)) < 1e-12
    out = track.at([0.0, 0.25, 2.0])
    assert out.shape == (3, 3)
    np.testing.assert_allclose(out[1, :2], [0.5, 1.0])
    np.testing.assert_allclose(track.pose_at(2.0), [2, 4, -3.0])


def test_pose_track_refuses_to_extrapolate():
    track = PoseTrack([1.0, 2.0], np.zeros((2, 3)))
    with pytest.raises(ValueError, match="outside the time range"):
        track.at(0.999)
    with pytest.raises(ValueError, match="outside the time range"):
        track.at([1.5, 2.5])


def test_pose_track_averages_duplicate_stamps():
    # two poses at t=1 (like the Olin /map_pose), one across the +-pi seam
    track = PoseTrack(
        [0.0, 1.0, 1.0, 2.0],
        [[0, 0, 0], [1.0, 0.0, 3.1], [1.02, 0.02, -3.1], [2, 0, np.pi]],
    )
    np.testing.assert_allclose(track.at(1.0)[:2], [1.01, 0.01])
    assert abs(angle_diff(track.at(1.0)[2], np.pi)) < 1e-12
    assert len(track) == 4  # the raw samples are kept


def test_pose_track_sorts_unsorted_stamps():
    track = PoseTrack([2.0, 0.0], [[2, 0, 0], [0, 0, 0]])
    np.testing.assert_allclose(track.at(0.5), [0.5, 0, 0])


def test_pose_track_validates():
    with pytest.raises(ValueError, match="poses must have shape"):
        PoseTrack([0.0, 1.0], np.zeros((3, 3)))
    with pytest.raises(ValueError, match="at least one"):
        PoseTrack([], np.zeros((0, 3)))
    with pytest.raises(ValueError, match="finite"):
        PoseTrack([0.0, np.nan], np.zeros((2, 3)))


def test_scans_validates_shapes():
    with pytest.raises(ValueError, match="ranges must have shape"):
        Scans(np.zeros(2), np.ones((2, 3)), np.zeros(4), 0.1, 5.0, "laser")
    with pytest.raises(ValueError, match="range_min"):
        Scans(np.zeros(2), np.ones((2, 3)), np.zeros(3), 5.0, 1.0, "laser")


def test_tf_tree_single_sample_edge_is_static():
    tree = TfTree(
        {
            ("map", "odom"): PoseTrack([5.0], [[1, 0, 0]]),
            ("odom", "base"): PoseTrack([0.0, 10.0], [[0, 0, 0], [10, 0, 0]]),
        }
    )
    np.testing.assert_allclose(tree.lookup("map", "base", 2.0), [3, 0, 0])
    np.testing.assert_allclose(tree.lookup("base", "map", 2.0), inverse([3, 0, 0]))
    np.testing.assert_allclose(tree.lookup("map", "map", 2.0), [0, 0, 0])


# -- writer ------------------------------------------------------------------------------------
def test_writer_replaces_only_on_success(tmp_path):
    path = tmp_path / "a.bag"
    with BagWriter(path) as bag:
        bag.write_pose_stamped("/p", 1.0, (1, 2, 3), frame_id="map")
    original = path.read_bytes()
    with pytest.raises(RuntimeError, match="boom"):
        with BagWriter(path) as bag:
            bag.write_pose_stamped("/p", 1.0, (9, 9, 0), frame_id="map")
            raise RuntimeError("boom")
    assert path.read_bytes() == original
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.bag"]  # no temporary left over
    with BagWriter(path) as bag:
        bag.write_pose_stamped("/q", 1.0, (4, 5, 0), frame_id="map")
    with BagReader(path) as reader:
        assert list(reader.topics) == ["/q"]
    with pytest.raises(FileExistsError, match="a.bag"):
        BagWriter(path, overwrite=False)


def test_writer_rejects_bad_arguments(tmp_path):
    with pytest.raises(ValueError, match=r"\.bag"):
        BagWriter(tmp_path / "a.db3")
    with BagWriter(tmp_path / "b.bag") as bag:
        with pytest.raises(ValueError, match="pose must have shape"):
            bag.write_pose_stamped("/p", 0.0, (1, 2), frame_id="map")
        with pytest.raises(ValueError, match="stamp"):
            bag.write_pose_stamped("/p", -1.0, (1, 2, 0), frame_id="map")
        with pytest.raises(ValueError, match="range_min"):
            bag.write_scan(
                "/s", 0.0, [1.0], angle_min=0, angle_increment=0.1, range_min=2, range_max=1,
                frame_id="laser",
            )  # fmt: skip
        bag.write_pose_stamped("/p", 0.0, (1, 2, 0), frame_id="map")
        with pytest.raises(ValueError, match="already carries"):
            bag.write_odometry("/p", 0.1, (0, 0, 0), frame_id="odom", child_frame_id="base")


# -- ROS2 --------------------------------------------------------------------------------------
@pytest.mark.parametrize("plugin", ["SQLITE3", "MCAP"])
def test_ros2_bag_round_trip(tmp_path, plugin):
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    exp = _expected()
    store = get_typestore(Stores.ROS2_HUMBLE)
    T = store.types

    def header(t, frame):
        sec = int(np.floor(t))
        stamp = T["builtin_interfaces/msg/Time"](sec=sec, nanosec=round((t - sec) * 1e9))
        return T["std_msgs/msg/Header"](stamp=stamp, frame_id=frame)

    def pose(p):
        return T["geometry_msgs/msg/Pose"](
            position=T["geometry_msgs/msg/Point"](x=p[0], y=p[1], z=0.0),
            orientation=T["geometry_msgs/msg/Quaternion"](
                x=0.0, y=0.0, z=np.sin(p[2] / 2), w=np.cos(p[2] / 2)
            ),
        )

    path = tmp_path / "ros2bag"
    with Writer(path, version=9, storage_plugin=getattr(StoragePlugin, plugin)) as w:
        scan_c = w.add_connection("/scan", "sensor_msgs/msg/LaserScan", typestore=store)
        odom_c = w.add_connection("/odom", "nav_msgs/msg/Odometry", typestore=store)
        for k, t in enumerate(exp["stamps"]):
            ns = int(round(t * 1e9))
            scan = T["sensor_msgs/msg/LaserScan"](
                header=header(t, "laser"), angle_min=ANGLE_MIN, angle_max=0.0,
                angle_increment=ANGLE_INC, time_increment=0.0, scan_time=0.0,
                range_min=RANGE_MIN, range_max=RANGE_MAX, ranges=exp["ranges"][k],
                intensities=np.zeros(0, np.float32),
            )  # fmt: skip
            w.write(scan_c, ns, store.serialize_cdr(scan, "sensor_msgs/msg/LaserScan"))
            odom = T["nav_msgs/msg/Odometry"](
                header=header(t, "odom"),
                child_frame_id="base_link",
                pose=T["geometry_msgs/msg/PoseWithCovariance"](
                    pose=pose(exp["odom"][k]), covariance=np.zeros(36)
                ),
                twist=T["geometry_msgs/msg/TwistWithCovariance"](
                    twist=T["geometry_msgs/msg/Twist"](
                        linear=T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0),
                        angular=T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0),
                    ),
                    covariance=np.zeros(36),
                ),
            )
            w.write(odom_c, ns, store.serialize_cdr(odom, "nav_msgs/msg/Odometry"))
    storage_file = next(p for p in path.iterdir() if p.suffix in (".db3", ".mcap"))
    for source in (path, storage_file):  # the folder, or the storage file on its own
        with BagReader(source) as bag:
            assert bag.topics["/scan"] == TopicInfo("/scan", "sensor_msgs/msg/LaserScan", N)
            scans = bag.scans("/scan")
            odom = bag.odometry("odom")
        np.testing.assert_array_equal(scans.ranges, exp["ranges"])
        np.testing.assert_allclose(scans.stamps, exp["stamps"], atol=STAMP_ATOL)
        np.testing.assert_allclose(odom.poses[:, :2], exp["odom"][:, :2], atol=1e-12)
        np.testing.assert_allclose(angle_diff(odom.theta, exp["odom"][:, 2]), 0, atol=1e-12)


def _ros2_pose_stamped(types, sec, x, y):
    """A ROS2 ``geometry_msgs/msg/PoseStamped`` at ``(x, y)``, heading 0, stamped ``sec``."""
    T = types
    return T["geometry_msgs/msg/PoseStamped"](
        header=T["std_msgs/msg/Header"](
            stamp=T["builtin_interfaces/msg/Time"](sec=sec, nanosec=0), frame_id="map"
        ),
        pose=T["geometry_msgs/msg/Pose"](
            position=T["geometry_msgs/msg/Point"](x=x, y=y, z=0.0),
            orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
        ),
    )


def _drop_definitions(path, where=""):
    """Delete message definitions (those matching SQL ``where``) from a ROS2 bag's database."""
    db = sqlite3.connect(next(path.glob("*.db3")))
    db.execute(f"DELETE FROM message_definitions {where}")
    db.commit()
    db.close()


def test_unsupported_type_warns_and_is_skipped(tmp_path):
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    store.register(get_types_from_msg("float64 value", "robolab_test/msg/Thing"))
    T = store.types
    path = tmp_path / "custom"
    with Writer(path, version=9) as w:
        thing = w.add_connection("/thing", "robolab_test/msg/Thing", typestore=store)
        pose = w.add_connection("/pose", "geometry_msgs/msg/PoseStamped", typestore=store)
        for k in range(3):
            w.write(
                thing, k, store.serialize_cdr(T["robolab_test/msg/Thing"](value=k), thing.msgtype)
            )
            msg = _ros2_pose_stamped(T, k, float(k), 0.0)
            w.write(pose, k, store.serialize_cdr(msg, pose.msgtype))
    # A bag whose recorder did not store the custom type's definition.
    _drop_definitions(path, "WHERE topic_type = 'robolab_test/msg/Thing'")
    with BagReader(path) as bag:
        with pytest.warns(UserWarning, match="robolab_test/msg/Thing"):
            seen = list(bag.messages(["/thing", "/pose"]))
        assert [topic for topic, _, _ in seen] == ["/pose"] * 3
        np.testing.assert_allclose(bag.poses("/pose").x, [0, 1, 2])


# -- bad input ---------------------------------------------------------------------------------
def test_missing_file(tmp_path):
    with pytest.raises(FileNotFoundError, match="nope.bag"):
        BagReader(tmp_path / "nope.bag")


@pytest.mark.parametrize("fraction", [0.5, 0.9, 0.999])
def test_truncated_bag_raises_naming_the_file(written, tmp_path, fraction):
    path, _, _ = written
    data = path.read_bytes()
    cut = tmp_path / "cut.bag"
    cut.write_bytes(data[: int(len(data) * fraction)])
    with pytest.raises(BagError, match="cut.bag"):
        with BagReader(cut) as bag:
            bag.scans("/base_scan")


def test_truncated_ros2_bag_raises(tmp_path):
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    path = tmp_path / "r2"
    with Writer(path, version=9) as w:
        conn = w.add_connection("/clock", "rosgraph_msgs/msg/Clock", typestore=store)
        for k in range(200):
            clock = store.types["rosgraph_msgs/msg/Clock"](
                clock=store.types["builtin_interfaces/msg/Time"](sec=k, nanosec=0)
            )
            w.write(conn, k, store.serialize_cdr(clock, conn.msgtype))
    db = next(path.glob("*.db3"))
    db.write_bytes(db.read_bytes()[: db.stat().st_size // 2])
    with pytest.raises(BagError, match="r2"):
        with BagReader(path) as bag:
            list(bag.messages("/clock"))


def test_corrupt_header_raises_naming_the_file(written, tmp_path):
    path, _, _ = written
    bad = tmp_path / "bad.bag"
    bad.write_bytes(b"#ROSBAG V9.9\n" + path.read_bytes()[13:])
    with pytest.raises(BagError, match="bad.bag"):
        BagReader(bad)
    notabag = tmp_path / "notes.bag"
    notabag.write_text("hello")
    with pytest.raises(BagError, match="notes.bag"):
        BagReader(notabag)


def test_ros1_bag_with_wrong_suffix_gets_a_hint(written, tmp_path):
    path, _, _ = written
    renamed = tmp_path / "sim.rosbag"
    renamed.write_bytes(path.read_bytes())
    with pytest.raises(BagError, match=r"must end in \.bag"):
        BagReader(renamed)


def test_missing_topic_lists_existing_topics(written):
    path, _, _ = written
    with BagReader(path) as bag:
        with pytest.raises(BagError, match=r"'/scan'.*/base_scan, /ground_truth, /odom, /tf"):
            bag.scans("/scan")
        with pytest.raises(BagError, match="/base_scan"):
            bag.messages(["/tf", "/nothing"])  # raised at the call, before any reading


def test_wrong_message_type_is_named(written):
    path, _, _ = written
    with BagReader(path) as bag:
        with pytest.raises(BagError, match="nav_msgs/msg/Odometry.*LaserScan"):
            bag.scans("/odom")


def test_bag_with_no_scans(tmp_path):
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    path = tmp_path / "empty.bag"
    with Writer(path) as w:  # a scan topic was advertised but never published
        w.add_connection(
            "/scan", "sensor_msgs/msg/LaserScan", typestore=get_typestore(Stores.ROS1_NOETIC)
        )
    with BagReader(path) as bag:
        assert bag.topics["/scan"].count == 0
        with pytest.raises(BagError, match="no scans"):
            bag.scans("/scan")


def test_scans_of_mismatched_lengths(tmp_path):
    path = tmp_path / "mixed.bag"
    with BagWriter(path) as bag:
        for k, beams in enumerate([5, 5, 4]):
            bag.write_scan(
                "/scan", float(k), np.ones(beams), angle_min=0.0, angle_increment=0.1,
                range_min=0.1, range_max=2.0, frame_id="laser",
            )  # fmt: skip
    with BagReader(path) as bag:
        with pytest.raises(BagError, match=r"mismatched lengths.*scan 2 has 4"):
            bag.scans("/scan")


def test_closed_reader_refuses(written):
    path, _, _ = written
    bag = BagReader(path)
    bag.close()
    bag.close()  # idempotent
    with pytest.raises(BagError, match="closed"):
        bag.odometry("/odom")


def test_a_folder_that_is_not_a_ros2_bag_names_what_is_missing(tmp_path):
    # Issue 25: rosbags' FileNotFoundError named the folder, not the missing metadata.yaml.
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(BagError, match="empty folder.*metadata.yaml"):
        BagReader(empty)
    storage = tmp_path / "storage_only"
    storage.mkdir()
    (storage / "run_0.db3").write_bytes(b"")
    with pytest.raises(BagError, match="no metadata.yaml.*run_0.db3"):
        BagReader(storage)
    other = tmp_path / "other"
    other.mkdir()
    (other / "notes.txt").write_text("x")
    with pytest.raises(BagError, match="no metadata.yaml.*no .db3 or .mcap"):
        BagReader(other)


@pytest.mark.parametrize(
    "content", [b"", b"\xff\xfe random bytes" * 10, b"#ROSBAG V2.0\n\x00\x01", b"yaml: [\n"]
)
def test_a_file_that_is_not_a_bag_raises_one_line_bag_error(tmp_path, content):
    path = tmp_path / "x.bag"
    path.write_bytes(content)
    with pytest.raises(BagError) as info:
        BagReader(path)
    assert str(path) in str(info.value) and "\n" not in str(info.value)
    bad_yaml = tmp_path / "bad"
    bad_yaml.mkdir()
    (bad_yaml / "metadata.yaml").write_bytes(content or b"{{{")
    with pytest.raises(BagError) as info:
        BagReader(bad_yaml)
    assert "\n" not in str(info.value)


def test_a_bag_without_message_definitions_reads_with_the_latest_typestore(tmp_path):
    """The default typestore (rosbags' latest ROS2 one, built only when a bag needs it)
    decodes a ROS2 bag whose recorder stored no message definitions."""
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore

    from robolab.bag.ros1 import LatestTypestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    T = store.types
    path = tmp_path / "nodefs"
    with Writer(path, version=9) as w:
        pose = w.add_connection("/pose", "geometry_msgs/msg/PoseStamped", typestore=store)
        for k in range(3):
            msg = _ros2_pose_stamped(T, k, float(k), 0.5)
            w.write(pose, k, store.serialize_cdr(msg, pose.msgtype))
    _drop_definitions(path)  # the recorder stored none
    with BagReader(path) as bag:
        track = bag.poses("/pose")
    np.testing.assert_allclose(track.x, [0, 1, 2])
    np.testing.assert_allclose(track.y, [0.5, 0.5, 0.5])
    assert LatestTypestore().fielddefs == get_typestore(Stores.LATEST).fielddefs
