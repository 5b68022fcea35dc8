"""robolab.fieldsum: the table sums at beam endpoints behind the likelihood-field model."""

from __future__ import annotations

import numpy as np
import pytest

from robolab import fieldsum, raycast

f32 = np.float32


def brute_force(table, uv, c, s, qx, qy):
    """One endpoint at a time, float32 scalars in the documented order of operations."""
    rows, cols = table.shape
    out = np.zeros(len(uv))
    for i in range(len(uv)):
        for k in range(len(qx)):
            u = f32(f32(f32(c[i] * qx[k]) - f32(s[i] * qy[k])) + uv[i, 0])
            v = f32(f32(f32(s[i] * qx[k]) + f32(c[i] * qy[k])) + uv[i, 1])
            col = int(min(max(u, f32(0)), f32(cols - 1)))
            row = int(min(max(v, f32(0)), f32(rows - 1)))
            out[i] += float(table[row, col])
    return out


def problem(n, b=13, seed=0):
    rng = np.random.default_rng(seed)
    table = rng.normal(size=(17, 23)).astype(f32)
    uv = rng.uniform(-5, 30, (n, 2)).astype(f32)  # some endpoints off the table: clipped
    phi = rng.uniform(-np.pi, np.pi, n)
    qx, qy = (rng.uniform(-9, 9, (2, b))).astype(f32)
    return table, uv, np.cos(phi).astype(f32), np.sin(phi).astype(f32), qx, qy


@pytest.mark.parametrize("n", [1, 5, 40])
def test_numpy_path_matches_the_endpoint_by_endpoint_loop(n, monkeypatch):
    monkeypatch.setattr(fieldsum, "BLOCK", 3 * 13)  # several blocks, the last one partial
    args = problem(n)
    # the same cells, added in beam order in float64 like the loop: the same bits
    np.testing.assert_array_equal(fieldsum.numpy_table_sum(*args), brute_force(*args))


@pytest.mark.skipif(raycast._jit() is None, reason="numba unavailable")
@pytest.mark.parametrize("n", [1, 7, 3000])
def test_compiled_and_numpy_paths_give_the_same_bits(n):
    args = problem(n, b=60, seed=n)
    compiled = fieldsum.table_sum(*args, backend="numba")
    np.testing.assert_array_equal(compiled, fieldsum.table_sum(*args, backend="numpy"))
    if n <= 7:
        np.testing.assert_array_equal(compiled, brute_force(*args))


@pytest.mark.parametrize("backend", ["cuda", "auto"])
def test_unknown_backend_is_refused(backend):
    with pytest.raises(ValueError, match="backend"):
        fieldsum.table_sum(*problem(2), backend=backend)
    with pytest.raises(ValueError, match="backend"):
        fieldsum.pose_table_sum(*pose_problem(2), backend=backend)


# -- pose_table_sum: from the robots' poses ------------------------------------------------------
def pose_problem(n, seed=0):
    from robolab.maps import OccupancyGrid

    rng = np.random.default_rng(seed)
    table = rng.normal(size=(21, 27)).astype(f32)
    # a rotated, shifted map: world_to_map's rotation is exercised
    geometry = OccupancyGrid(np.zeros((19, 25)), 0.1, (-0.7, 0.4, 0.3))
    poses = np.column_stack([rng.uniform(-1.5, 3.5, (n, 2)), rng.uniform(-np.pi, np.pi, n)])
    poses[::5, 2] += 40.0  # headings many turns away: wrap_angle's general path
    laser = np.array([0.12, -0.03, 0.2])
    qx, qy = (rng.uniform(-12, 12, (2, 9))).astype(f32)
    return table, poses, laser, geometry, qx, qy


def pose_brute_force(table, poses, laser, geometry, qx, qy):
    """compose and world_to_map per pose, then the endpoint-by-endpoint loop."""
    from robolab.geometry import compose

    lp = compose(poses, laser)
    uv = geometry.world_to_map(lp[:, :2]).astype(f32) + f32(1)
    phi = lp[:, 2] - geometry.origin[2]
    return brute_force(table, uv, np.cos(phi).astype(f32), np.sin(phi).astype(f32), qx, qy)


@pytest.mark.parametrize("n", [1, 40])
def test_pose_table_sum_numpy_path_matches_the_loop(n):
    args = pose_problem(n, seed=n)
    np.testing.assert_array_equal(
        fieldsum.pose_table_sum(*args, backend="numpy"), pose_brute_force(*args)
    )


@pytest.mark.parametrize("turned", [True, False])
def test_laser_cells_are_compose_then_world_to_map_bit_for_bit(turned):
    """The numpy path's in-place laser poses: compose's and world_to_map's bits, also for
    poses at the float limits and NaN (their endpoints must land where the kernel's do).
    Not turned: a laser and a map of yaw 0 and wrapped headings (with +-0), where the
    heading's cosine and sine are reused."""
    from robolab.geometry import compose, wrap_angle
    from robolab.maps import OccupancyGrid

    _, poses, laser, geometry, _, _ = pose_problem(300, seed=8)
    if not turned:
        laser[2] = 0.0
        geometry = OccupancyGrid(np.zeros((1, 1)), 0.1, (-0.7, 0.4, 0.0))
        poses[:, 2] = wrap_angle(poses[:, 2])
        poses[4:6, 2] = [0.0, -0.0]
    poses[0, :2] = 1.7e308
    poses[1] = [1e308, -1e308, 1e300]
    poses[2, 0] = poses[3, 2] = np.nan
    with np.errstate(all="ignore"):
        lp = compose(poses, laser)
        uv = geometry.world_to_map(lp[:, :2]).astype(f32) + f32(1)
        phi = lp[:, 2] - geometry.origin[2]
        got = fieldsum._laser_cells(poses, laser, geometry)
        if not turned:  # without the NaN heading and the -0 (-0 + 0 is +0): the shortcut
            heading = poses[6:, 2]
            assert np.array_equal(wrap_angle(heading + 0.0).view(np.int64), heading.view(np.int64))
            fast = fieldsum._laser_cells(poses[6:], laser, geometry)
            for want, have in zip(got, fast, strict=True):
                np.testing.assert_array_equal(want[6:].view(np.int32), have.view(np.int32))
    for want, have in zip((uv, np.cos(phi).astype(f32), np.sin(phi).astype(f32)), got, strict=True):
        assert have.dtype == want.dtype
        np.testing.assert_array_equal(have.view(np.int32), want.view(np.int32))  # the bits


def test_pose_table_sum_numpy_path_in_chunks_of_poses(monkeypatch):
    args = pose_problem(40, seed=4)
    whole = fieldsum.pose_table_sum(*args, backend="numpy")
    monkeypatch.setattr(fieldsum, "BLOCK", 2 * 9)  # 2 poses of 9 beams per block
    monkeypatch.setattr(fieldsum, "POSE_BLOCKS", 3)  # chunks of 6 poses, the last one partial
    chunked = fieldsum.pose_table_sum(*args, backend="numpy")
    np.testing.assert_array_equal(chunked, whole)
    np.testing.assert_array_equal(chunked, pose_brute_force(*args))


@pytest.mark.skipif(raycast._jit() is None, reason="numba unavailable")
@pytest.mark.parametrize("n", [1, 40, 3000])
def test_fused_kernel_gives_the_numpy_paths_bits(n):
    import math

    args = pose_problem(n, seed=n)
    fused = fieldsum.pose_table_sum(*args, backend="numba")
    reference = fieldsum.pose_table_sum(*args, backend="numpy")
    phi = args[1][:, 2]
    if np.array_equal(np.cos(phi), [math.cos(x) for x in phi]):  # numpy's cos is libm's
        np.testing.assert_array_equal(fused, reference)
    else:  # numpy's own SIMD cos: an endpoint on a cell boundary may change cells
        assert np.mean(fused == reference) >= 0.99
    if n <= 40:
        np.testing.assert_array_equal(reference, pose_brute_force(*args))


@pytest.mark.parametrize("backend", ["numpy", "numba"])
def test_poses_at_the_float_limits_stay_inside_the_table(backend):
    """Poses near +-1e308 (infinite endpoints) and NaN poses (outside the contract, but
    memory safety does not depend on it): both paths read cells of the table (a NaN
    endpoint reads cell 0), never memory outside it (the compiled kernel checks no bounds)."""
    if backend == "numba" and raycast._jit() is None:
        pytest.skip("numba unavailable")
    table, poses, laser, geometry, qx, qy = pose_problem(6, seed=3)
    poses[0, :2] = 1.7e308
    poses[1, :2] = -1.7e308
    poses[2] = [1e308, -1e308, 1e300]
    poses[3, 0] = np.nan
    poses[4, 2] = np.nan
    table[0, 0] = 1000.0  # a NaN endpoint's cell: visible in the sum
    with np.errstate(all="ignore"):  # numpy's overflow warnings are right here
        got = fieldsum.pose_table_sum(table, poses, laser, geometry, qx, qy, backend=backend)
        reference = fieldsum.pose_table_sum(
            table, poses, laser, geometry, qx, qy, backend="numpy"
        )
    assert np.all(np.isfinite(got))
    np.testing.assert_array_equal(got, reference)
    assert np.all(np.abs(got) <= len(qx) * np.abs(table).max())  # a sum of table cells


@pytest.mark.skipif(raycast._jit() is None, reason="numba unavailable")
def test_nan_endpoints_read_cell_zero_on_both_paths():
    """The map-frame kernel too: NaN or infinite positions stay inside the table."""
    table, uv, c, s, qx, qy = problem(6, seed=5)
    uv[0, 0] = np.nan
    uv[1, 1] = np.nan
    uv[2] = [np.inf, -np.inf]
    c[3] = np.nan
    table[0, 0] = 1000.0
    with np.errstate(all="ignore"):
        compiled = fieldsum.table_sum(table, uv, c, s, qx, qy, backend="numba")
        reference = fieldsum.table_sum(table, uv, c, s, qx, qy, backend="numpy")
    np.testing.assert_array_equal(compiled, reference)
    assert np.all(np.isfinite(compiled))


@pytest.mark.skipif(raycast._jit() is None, reason="numba unavailable")
def test_pose_table_sum_loads_only_its_kernel_in_one_signature():
    """MCL's default path loads the fused kernel alone (not the ray casters, whose
    compilation with an empty numba cache costs seconds) and compiles it once, whatever
    the flags of the caller's arrays (writeable or read-only table, poses, beams)."""
    import subprocess
    import sys
    from pathlib import Path

    code = (
        "import sys, numpy as np\n"
        "from robolab import fieldsum\n"
        "from robolab.maps import OccupancyGrid\n"
        "rng = np.random.default_rng(0)\n"
        "table = rng.normal(size=(21, 27)).astype(np.float32)\n"
        "geometry = OccupancyGrid(np.zeros((19, 25)), 0.1, (-0.7, 0.4, 0.3))\n"
        "poses = rng.uniform(-1.5, 3.5, (5, 3))\n"
        "laser = np.array([0.12, -0.03, 0.2])\n"
        "qx, qy = rng.uniform(-12, 12, (2, 9)).astype(np.float32)\n"
        "first = fieldsum.pose_table_sum(table, poses, laser, geometry, qx, qy)\n"
        "for a in (table, poses, laser, qx, qy):\n"
        "    a.flags.writeable = False\n"
        "again = fieldsum.pose_table_sum(table, poses, laser, geometry, qx, qy)\n"
        "assert np.array_equal(first, again)\n"
        "print(len(fieldsum._fused().signatures), 'robolab._raycast_jit' in sys.modules)\n"
    )
    root = Path(__file__).resolve().parents[1]
    run = subprocess.run([sys.executable, "-c", code], cwd=root, capture_output=True,
                         text=True, check=True)
    assert run.stdout.split() == ["1", "False"]
