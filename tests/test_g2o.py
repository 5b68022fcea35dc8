"""robolab.datasets.read_g2o / write_g2o / PoseGraph, and robolab.evaluation.graph_objective.

Small g2o files are written here with known content (the oracle); the real graphs of
../shared/data/graph_slam are read where present (skipped when absent).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from robolab.datasets import G2oError, PoseGraph, read_g2o, write_g2o
from robolab.evaluation import graph_objective
from robolab.geometry import compose, relative, transform_points

GRAPHS = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "graph_slam"
needs_graphs = pytest.mark.skipif(
    not GRAPHS.is_dir(), reason="../shared/data/graph_slam not present"
)

SMALL = """\
# ids neither 0..N-1 nor in order; a landmark between the poses
VERTEX_SE2 7 1.0 2.0 0.5
VERTEX_XY 3 4.0 -1.0
VERTEX_SE2 2 0.0 0.0 0.0

EDGE_SE2 2 7 1.1 1.9 0.4 10 1 2 20 3 30
EDGE_SE2_XY 7 3 2.0 -3.0 5 0.5 6
"""


def _write(tmp_path, text, name="g.g2o"):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_ids_become_sorted_rows_and_information_is_the_upper_triangle(tmp_path):
    """Rows sorted by id, edges as rows, I11 I12 I13 I22 I23 I33 filled row by row, symmetric."""
    g = read_g2o(_write(tmp_path, SMALL))
    np.testing.assert_array_equal(g.pose_ids, [2, 7])
    np.testing.assert_array_equal(g.landmark_ids, [3])
    np.testing.assert_allclose(g.poses, [[0, 0, 0], [1, 2, 0.5]])
    np.testing.assert_allclose(g.landmarks, [[4, -1]])
    np.testing.assert_array_equal(g.edges, [[0, 1]])
    np.testing.assert_allclose(g.measurements, [[1.1, 1.9, 0.4]])
    np.testing.assert_allclose(g.information[0], [[10, 1, 2], [1, 20, 3], [2, 3, 30]])
    np.testing.assert_array_equal(g.landmark_edges, [[1, 0]])
    np.testing.assert_allclose(g.landmark_measurements, [[2.0, -3.0]])
    np.testing.assert_allclose(g.landmark_information[0], [[5, 0.5], [0.5, 6]])
    assert g.n_poses == 2 and g.n_landmarks == 1 and g.state_size == 8


def test_write_then_read_gives_back_every_array(tmp_path):
    """write_g2o round-trips exactly (ids, FIX, floats to the last bit)."""
    rng = np.random.default_rng(3)
    a = rng.normal(size=(4, 3, 3))
    g = PoseGraph(
        poses=rng.normal(size=(3, 3)),
        edges=[[0, 1], [2, 0], [1, 2], [0, 1]],
        measurements=rng.normal(size=(4, 3)),
        information=a @ np.swapaxes(a, 1, 2),
        landmarks=rng.normal(size=(2, 2)),
        landmark_edges=[[2, 1], [0, 0]],
        landmark_measurements=rng.normal(size=(2, 2)),
        landmark_information=np.stack([np.eye(2), 2 * np.eye(2)]),
        pose_ids=[4, 10, 99],
        landmark_ids=[1, 5],
        fixed=[1],
    )
    back = read_g2o(write_g2o(g, tmp_path / "out.g2o"))
    for name in (
        "poses",
        "edges",
        "measurements",
        "landmark_edges",
        "landmark_measurements",
        "landmark_information",
        "landmarks",
        "fixed",
        "pose_ids",
        "landmark_ids",
    ):
        np.testing.assert_array_equal(getattr(back, name), getattr(g, name), err_msg=name)
    # the information is written as its upper triangle: exact up to the symmetrisation
    np.testing.assert_allclose(back.information, g.information, rtol=1e-15)
    assert graph_objective(back) == pytest.approx(graph_objective(g), rel=1e-12)


@pytest.mark.parametrize(
    "line, message",
    [
        ("VERTEX_SE2 9 1.0 2.0", "needs 4 fields, got 3"),
        ("VERTEX_SE2 9 1.0 2.0 0.1 7", "needs 4 fields, got 5"),
        ("VERTEX_XY 9 1.0 abc", "not a number"),
        ("VERTEX_SE2 9 1.0 nan 0.0", "must be finite"),
        ("VERTEX_SE2 9.5 1.0 2.0 0.0", "must be an integer"),
        ("VERTEX_SE2 -4 1.0 2.0 0.0", "must be >= 0"),
        ("VERTEX_SE2 7 1.0 2.0 0.0", "vertex id 7 is already defined (line 2"),
        ("VERTEX_XY 2 1.0 2.0", "vertex id 2 is already defined"),
        ("EDGE_SE2 2 8 1 0 0 1 0 0 1 0 1", "vertex 8 is not defined by any VERTEX_SE2"),
        ("EDGE_SE2 2 3 1 0 0 1 0 0 1 0 1", "vertex 3 is a VERTEX_XY, expected a VERTEX_SE2"),
        ("EDGE_SE2_XY 2 7 1 0 1 0 1", "vertex 7 is a VERTEX_SE2, expected a VERTEX_XY"),
        ("EDGE_SE2 2 7 1 0 0 1 0 0 -1 0 1", "not positive semi-definite"),
        ("EDGE_SE2 2 7 1 0 0 1 2 0 1 0 1", "not positive semi-definite"),  # a 2x2 minor < 0
        ("EDGE_SE2_XY 2 3 1 0 1 5 1", "not positive semi-definite"),
        ("EDGE_SE3:QUAT 1 2 0 0 0 0 0 0 1", "unsupported element type 'EDGE_SE3:QUAT'"),
        ("FIX 42", "vertex 42 is not defined"),
    ],
)
def test_each_malformed_line_is_refused_naming_file_and_line(tmp_path, line, message):
    """Every class of malformed line: G2oError with path:line and what is wrong."""
    lines = SMALL.splitlines()
    lines.insert(5, line)  # becomes line 6
    path = _write(tmp_path, "\n".join(lines) + "\n")
    with pytest.raises(G2oError) as info:
        read_g2o(path)
    text = str(info.value)
    assert f"{path}:6:" in text and message in text, text


def test_a_missing_file_is_a_file_not_found_error(tmp_path):
    with pytest.raises(FileNotFoundError, match="g2o file not found"):
        read_g2o(tmp_path / "nope.g2o")


def test_fix_lines_name_the_gauge(tmp_path):
    g = read_g2o(_write(tmp_path, SMALL + "FIX 7\n"))
    np.testing.assert_array_equal(g.fixed, [1])


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"poses": np.zeros((2, 2))}, "poses must have shape (N, 3)"),
        ({"edges": [[0, 2]]}, "edges[0] = [0, 2] is out of range"),
        ({"edges": [[0, 1.5]]}, "integer row indices"),
        ({"measurements": np.zeros((2, 3))}, "measurements must have shape (1, 3)"),
        (
            {"information": [np.diag([1.0, -1.0, 1.0])]},
            "information[0] is not positive semi-definite",
        ),
        (
            {"information": [[[1.0, 2.0, 0], [0, 1, 0], [0, 0, 1]]]},
            "information[0] is not symmetric",
        ),
        ({"poses": [[0, 0, np.inf], [0, 0, 0]]}, "poses must be finite"),
        ({"pose_ids": [1, 1]}, "pose_ids must be unique"),
        ({"fixed": [5]}, "fixed must hold rows of poses"),
    ],
)
def test_a_pose_graph_checks_its_arrays(kwargs, message):
    """PoseGraph refuses inconsistent arrays with a message naming the field."""
    base = {
        "poses": np.zeros((2, 3)),
        "edges": [[0, 1]],
        "measurements": [[1.0, 0, 0]],
        "information": [np.eye(3)],
    }
    with pytest.raises(G2oError) as info:
        PoseGraph(**(base | kwargs))
    assert message in str(info.value), str(info.value)


def test_a_pose_graph_owns_its_arrays_and_with_estimate_shares_none():
    poses = np.zeros((2, 3))
    g = PoseGraph(poses, [[0, 1]], [[1.0, 0, 0]], [np.eye(3)])
    poses[0, 0] = 5.0
    assert g.poses[0, 0] == 0.0, "the graph must copy the caller's arrays"
    h = g.with_estimate(np.ones((2, 3)))
    for name in ("poses", "edges", "information", "landmarks"):
        assert not np.shares_memory(getattr(h, name), getattr(g, name)), name
    np.testing.assert_array_equal(h.poses, np.ones((2, 3)))
    with pytest.raises(G2oError, match=r"poses must have shape \(2, 3\)"):
        g.with_estimate(np.ones((3, 3)))


# ------------------------------------------------------------------------- graph_objective


def _random_graph(rng, n=6, n_lm=3, n_edges=10, n_lm_edges=8):
    a = rng.normal(size=(n_edges, 3, 3))
    b = rng.normal(size=(n_lm_edges, 2, 2))
    return PoseGraph(
        poses=np.column_stack([rng.normal(0, 3, (n, 2)), rng.uniform(-np.pi, np.pi, n)]),
        edges=rng.integers(0, n, (n_edges, 2)),
        measurements=np.column_stack([rng.normal(0, 2, (n_edges, 2)), rng.uniform(-3, 3, n_edges)]),
        information=a @ np.swapaxes(a, 1, 2),
        landmarks=rng.normal(0, 3, (n_lm, 2)),
        landmark_edges=np.column_stack(
            [rng.integers(0, n, n_lm_edges), rng.integers(0, n_lm, n_lm_edges)]
        ),
        landmark_measurements=rng.normal(0, 2, (n_lm_edges, 2)),
        landmark_information=b @ np.swapaxes(b, 1, 2),
    )


def test_the_objective_is_zero_on_measurements_that_agree_and_a_hand_value_otherwise():
    """Two poses, one edge, one landmark: the objective by hand."""
    x0, x1, lm = np.array([1.0, 2.0, 0.3]), np.array([2.0, 1.0, -0.4]), np.array([0.5, 4.0])
    z = relative(x0, x1)  # exactly right
    zl = transform_points(lm[None], relative(x1, np.zeros(3)))[0]  # lm in the frame of x1
    info = np.diag([2.0, 3.0, 5.0])
    g = PoseGraph(
        np.stack([x0, x1]),
        [[0, 1]],
        [z],
        [info],
        landmarks=[lm],
        landmark_edges=[[1, 0]],
        landmark_measurements=[zl],
        landmark_information=[np.eye(2)],
    )
    assert graph_objective(g) == pytest.approx(0.0, abs=1e-20)
    # the measurement says pose 1 is 0.1 m further along x and 0.2 rad more turned:
    # e = t2v(Z^-1 X0^-1 X1) = t2v(Z^-1 Z') with Z' = Z (+) (-0.1, 0, -0.2) in Z's frame
    wrong = compose(z, [0.1, 0.0, 0.2])
    g2 = PoseGraph(
        g.poses,
        [[0, 1]],
        [wrong],
        [info],
        landmarks=[lm + [0.0, 0.0]],
        landmark_edges=[[1, 0]],
        landmark_measurements=[zl + [0.3, -0.4]],
        landmark_information=[np.diag([1.0, 2.0])],
    )
    e = relative(wrong, z)
    expected = e @ info @ e + (0.3**2 * 1.0 + 0.4**2 * 2.0)
    assert graph_objective(g2) == pytest.approx(expected, rel=1e-12)


def test_the_objective_ignores_a_global_rigid_motion_and_wraps_angles():
    """Moving every pose and landmark by one SE(2) motion leaves F unchanged; 2 pi turns too."""
    rng = np.random.default_rng(7)
    g = _random_graph(rng)
    f = graph_objective(g)
    motion = np.array([3.0, -2.0, 2.5])
    moved = g.with_estimate(compose(motion, g.poses), transform_points(g.landmarks, motion))
    assert graph_objective(moved) == pytest.approx(f, rel=1e-10)
    spun = g.with_estimate(g.poses + [0.0, 0.0, 2 * np.pi])
    assert graph_objective(spun) == pytest.approx(f, rel=1e-10)
    assert f > 0


def test_the_objective_refuses_what_is_not_a_graph():
    with pytest.raises(TypeError, match="PoseGraph"):
        graph_objective({"poses": np.zeros((1, 3))})


@needs_graphs
@pytest.mark.parametrize(
    "name, shape, objective",
    [
        # objectives of each file's own initial guess, as GTSAM 4.3 evaluates them with this error
        ("intel.g2o", (1728, 4830, 0, 0), 1.795e6),
        ("input_M3500_g2o.g2o", (3500, 5453, 0, 0), 2.567e6),
        ("simulation-pose-pose.g2o", (400, 1773, 0, 0), None),
        ("simulation-pose-landmark.g2o", (41, 40, 36, 257), None),
    ],
)
def test_the_real_graphs_read_with_their_documented_sizes(name, shape, objective):
    g = read_g2o(GRAPHS / name)
    assert (g.n_poses, len(g.edges), g.n_landmarks, len(g.landmark_edges)) == shape
    f = graph_objective(g)
    assert np.isfinite(f) and f > 0
    if objective is not None:
        assert f == pytest.approx(objective, rel=5e-4)
