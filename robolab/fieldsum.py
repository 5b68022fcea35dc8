"""Sums of a per-cell table at the beam endpoints of many poses: the inner loop of MCL.

:func:`table_sum` serves the likelihood-field model (Probabilistic Robotics, Table 6.3):
each particle ``i`` puts the endpoint of beam ``k`` at the map coordinates (cells,
column ``u`` and row ``v``)

.. math::

    u_{ik} = u_i + c_i q^x_k - s_i q^y_k, \\qquad v_{ik} = v_i + s_i q^x_k + c_i q^y_k

(``c, s``: cosine and sine of the particle's heading in the map, ``q``: the beam's
endpoint in the laser frame, in cells), clipped into the table, and the result is
:math:`\\sum_k T[\\lfloor v_{ik} \\rfloor, \\lfloor u_{ik} \\rfloor]`.

:func:`pose_table_sum` starts one step earlier, from the robots' poses: the laser's
pose, its map coordinates and its heading's cosine and sine are computed per pose
too (in numpy: :func:`robolab.geometry.compose` and
:meth:`robolab.maps.OccupancyGrid.world_to_map`; compiled: the same operations
fused into the kernel, :mod:`robolab._fieldsum_jit`).

Two paths, chosen like :mod:`robolab.raycast`'s backends (``ROBOLAB_RAYCAST=numpy``
forces numpy): a compiled kernel (:func:`robolab._raycast_jit.table_sum`, one fused
pass) and numpy in cache-sized blocks of particles. Both compute the endpoints in
float32 with the same operations, so they look up the same cells, and both add the
B values in beam order in float64: the two paths give the same bits.

:func:`pose_table_sum` (MCL's likelihood field) needs only its own kernel
(:mod:`robolab._fieldsum_jit`): its default path asks whether that kernel loads, not
:func:`robolab.raycast.default_backend`, which would also load (or, with an empty
numba cache, compile: about 3.4 s of CPU) the ray casters, which MCL never calls.
The kernel has one explicit signature with read-only inputs
(:data:`robolab._fieldsum_jit.SIGNATURE`), so numba compiles (and caches) one version
whatever the flags of the caller's arrays.
"""

from __future__ import annotations

import os
import warnings

import numpy as np

from robolab import raycast
from robolab.geometry import wrap_angle

__all__ = ["table_sum", "numpy_table_sum", "pose_table_sum"]

#: numpy_table_sum looks up about this many endpoints at a time: whole (N, B) temporaries
#: would spill out of the core's cache once N is large, and the time would grow faster than N.
BLOCK = 1 << 16

#: pose_table_sum's numpy path computes the laser poses, cells and headings of this many
#: blocks' particles at a time: compose and world_to_map make about twenty (N,) float64
#: temporaries, which at 100 000 particles (800 KB each) left the cache and were
#: page-faulted afresh on every call (30-60 % more time per particle than at 5 000).
POSE_BLOCKS = 8


#: The sums' paths (no "auto": a sum is one pass, compiled or not, chosen by the caller).
FIELDSUM_BACKENDS = ("numba", "numpy")

def table_sum(table, uv, c, s, qx, qy, backend=None):
    """Per pose, the sum over beams of ``table`` at the beam endpoints (float64).

    Parameters
    ----------
    table : numpy.ndarray, shape (H, W), float32
        The per-cell values (its border holds the value for endpoints off the table).
    uv : numpy.ndarray, shape (N, 2), float32
        Each pose's origin in table coordinates (column, row), cells.
    c, s : numpy.ndarray, shape (N,), float32
        Cosine and sine of each pose's heading in the table's frame.
    qx, qy : numpy.ndarray, shape (B,), float32
        The beam endpoints in the pose's frame, cells.
    backend : {"numba", "numpy"}, optional
        Default: :func:`robolab.raycast.default_backend`.

    Returns
    -------
    numpy.ndarray, shape (N,)
    """
    backend = backend or raycast.default_backend()
    if backend not in FIELDSUM_BACKENDS:
        raise ValueError(f"backend must be one of {FIELDSUM_BACKENDS}, got {backend!r}")
    arrays = [np.ascontiguousarray(a, dtype=np.float32) for a in (table, uv, c, s, qx, qy)]
    if backend == "numba" and raycast._jit() is not None:
        table, uv, c, s, qx, qy = arrays
        out = np.empty(uv.shape[0])
        raycast._jit().table_sum(table.ravel(), *table.shape, uv, c, s, qx, qy, out)
        return out
    return numpy_table_sum(*arrays)


def numpy_table_sum(table, uv, c, s, qx, qy):
    """:func:`table_sum` in numpy, in blocks of about :data:`BLOCK` endpoints.

    The temporaries are (beams, particles): every operation runs along the particles
    (long contiguous rows, one scalar per beam) and the sum over the beams adds row
    after row in beam order into float64, as the compiled kernel does: the two paths
    give the same bits.
    """
    rows, cols = table.shape
    flat = table.ravel()
    n, b = uv.shape[0], qx.shape[0]
    per = _particles_per_block(b)
    out = np.empty(n)
    u0, v0 = np.ascontiguousarray(uv[:, 0]), np.ascontiguousarray(uv[:, 1])
    qx, qy = qx[:, None], qy[:, None]
    hi_u, hi_v = np.float32(cols - 1), np.float32(rows - 1)
    size = b * min(per, n)
    u, v, tmp = (np.empty(size, np.float32) for _ in range(3))
    index = np.empty(size, np.int32)
    with np.errstate():  # restores numpy's buffer size on the way out
        # numpy (2.4 measured) runs a product of a row of particles by a column of beams,
        # (k,) x (b, 1), 3-4x slower when its buffer holds three rows or more (0.4 ns per
        # endpoint instead of 0.1): a buffer of at most one row keeps the fast loop
        np.setbufsize(min(8192, max(16, min(per, n) // 16 * 16)))
        for i in range(0, n, per):
            k = min(per, n - i)
            uu, vv, tt = (a[: b * k].reshape(b, k) for a in (u, v, tmp))
            ii, cc = index[: b * k].reshape(b, k), tt.view(np.int32)
            cs, ss = c[i : i + k], s[i : i + k]
            np.multiply(cs, qx, out=uu)
            np.multiply(ss, qy, out=tt)
            uu -= tt
            uu += u0[i : i + k]
            np.multiply(ss, qx, out=vv)
            np.multiply(cs, qy, out=tt)
            vv += tt
            vv += v0[i : i + k]
            # clip into the border; floor == truncation for u >= 0 (the method: np.clip's
            # wrappers cost twice its call)
            uu.clip(0, hi_u, out=uu)
            vv.clip(0, hi_v, out=vv)
            np.copyto(ii, vv, casting="unsafe")
            ii *= np.int32(cols)
            np.copyto(cc, uu, casting="unsafe")  # tt is free: its bytes hold the columns
            ii += cc
            np.take(flat, ii, out=uu, mode="clip")  # in range already; "raise" would buffer
            np.add.reduce(uu, axis=0, dtype=np.float64, out=out[i : i + k])
    return out


def _particles_per_block(beams):
    """Particles per block of :func:`numpy_table_sum` (about :data:`BLOCK` endpoints)."""
    return max(1, BLOCK // max(beams, 1))


def pose_table_sum(table, poses, laser, geometry, qx, qy, backend=None):
    """Per pose, the sum over beams of ``table`` at the endpoints of a laser on that pose.

    The endpoints of :func:`table_sum`, with ``uv, c, s`` those of the laser at
    ``compose(pose, laser)``: ``uv`` its map coordinates in float32 plus one (the
    table's border), ``c, s`` the cosine and sine of its heading minus the map's yaw.

    Parameters
    ----------
    table : numpy.ndarray, shape (H + 2, W + 2), float32
        Per-cell values of the map with a one-cell border (endpoints off the map).
    poses : numpy.ndarray, shape (N, 3), float64
        Robot poses ``(x, y, theta)`` in the map frame, finite.
    laser : numpy.ndarray, shape (3,)
        The laser's pose on the robot.
    geometry : robolab.maps.OccupancyGrid
        A grid with the map's resolution and origin (its cells are not read).
    qx, qy : numpy.ndarray, shape (B,), float32
        The beam endpoints in the laser frame, cells.
    backend : {"numba", "numpy"}, optional
        Default: ``"numba"`` when the fused kernel loads (``ROBOLAB_RAYCAST`` as for
        :func:`robolab.raycast.default_backend`: ``numpy`` forces numpy, ``numba``
        requires numba), else ``"numpy"``. The ray casters are not loaded.

    Returns
    -------
    numpy.ndarray, shape (N,)
        The same bits on both paths where numpy's float64 ``cos`` and ``sin`` are the
        C library's (x86-64 without AVX-512; tested): elsewhere an endpoint within a
        rounding of a cell boundary may fall in the neighbouring cell.
    """
    backend = backend or _pose_default_backend()
    if backend not in FIELDSUM_BACKENDS:
        raise ValueError(f"backend must be one of {FIELDSUM_BACKENDS}, got {backend!r}")
    poses = np.ascontiguousarray(poses, dtype=float)
    laser = np.ascontiguousarray(laser, dtype=float)
    kernel = _fused() if backend == "numba" else None
    if kernel is None:
        out = np.empty(poses.shape[0])
        chunk = _particles_per_block(np.shape(qx)[0]) * POSE_BLOCKS
        for i in range(0, poses.shape[0], chunk):
            uv, c, s = _laser_cells(poses[i : i + chunk], laser, geometry)
            out[i : i + chunk] = table_sum(table, uv, c, s, qx, qy, backend=backend)
        return out
    table = np.ascontiguousarray(table, dtype=np.float32)
    origin = np.ascontiguousarray(geometry.origin, dtype=float)
    rot = np.array([np.cos(origin[2]), np.sin(origin[2])])  # as world_to_map computes them
    out = np.empty(poses.shape[0])
    kernel(
        table.ravel(), *table.shape, poses, laser, origin, rot, float(geometry.resolution),
        np.ascontiguousarray(qx, dtype=np.float32), np.ascontiguousarray(qy, dtype=np.float32),
        out,
    )
    return out


def _laser_cells(poses, laser, geometry):
    """The laser's map coordinates plus one (float32, (N, 2)) and its heading's cosine and
    sine in the map (float32), for poses ``(N, 3)``.

    :func:`robolab.geometry.compose`, then ``world_to_map``, as the fused kernel does
    them: every float64 operation of theirs in their order (so the same bits), written
    in place into three (N,) arrays instead of their twenty-odd temporaries and stacks.
    """
    lx, ly, lt = laser
    ox, oy, oyaw = geometry.origin
    co, so = np.cos(oyaw), np.sin(oyaw)  # as world_to_map computes them
    heading = poses[:, 2]
    c, s = np.cos(heading), np.sin(heading)
    phi = wrap_angle(heading + lt)  # compose's heading, then minus the map's yaw
    phi -= oyaw
    if np.array_equal(phi.view(np.int64), heading.view(np.int64)):
        # The same angles, bit for bit (a laser and a map not turned, headings wrapped
        # already, as the motion model leaves them): the same cosines, two fewer per
        # pose (the C library's, 10-12 ns each)
        cos_phi, sin_phi = c.astype(np.float32), s.astype(np.float32)
    else:
        cos_phi, sin_phi = np.cos(phi).astype(np.float32), np.sin(phi).astype(np.float32)
    x, y, tmp = np.multiply(c, lx), np.multiply(s, lx), np.multiply(s, ly)
    x += poses[:, 0]  # compose: x + c lx - s ly, y + s lx + c ly
    x -= tmp
    y += poses[:, 1]
    y += np.multiply(c, ly, out=tmp)
    x -= ox  # world_to_map: (c dx + s dy) / res, (-s dx + c dy) / res
    y -= oy
    with np.errstate(invalid="ignore"):  # as world_to_map: inf * 0 is NaN, no warning
        u = np.multiply(x, co, out=c)
        u += np.multiply(y, so, out=tmp)
        u /= geometry.resolution
        v = np.multiply(x, -so, out=s)
        v += np.multiply(y, co, out=tmp)
        v /= geometry.resolution
    uv = np.empty((poses.shape[0], 2), np.float32)
    uv[:, 0], uv[:, 1] = u, v
    uv += np.float32(1.0)  # the border
    return uv, cos_phi, sin_phi


def _pose_default_backend() -> str:
    """:func:`pose_table_sum`'s default: ``"numba"`` when its fused kernel loads.

    ``ROBOLAB_RAYCAST`` as :func:`robolab.raycast.default_backend` reads it, without
    loading the ray casters.
    """
    return raycast.compiled_or_numpy(_fused)


_FUSED = []


def _fused():
    """The compiled :func:`robolab._fieldsum_jit.pose_table_sum`, or None without numba.

    Only this kernel: the ray casters (:func:`robolab.raycast._jit`) stay unloaded.
    ``ROBOLAB_RAYCAST=numpy`` keeps numba out, as it does for the casters.
    """
    if not _FUSED:
        kernel = None
        if raycast._JIT is not None and (  # None: numba was tried and is unusable
            os.environ.get("ROBOLAB_RAYCAST", "").strip().lower() != "numpy"
        ):
            try:
                from robolab import _fieldsum_jit

                kernel = _fieldsum_jit.pose_table_sum
                # compiled (or loaded from numba's cache) by the import, for its one
                # signature; run it on a tiny table, so that a broken numba falls back
                # here and not in the middle of a filter
                one, out = np.ones(1, np.float32), np.empty(1)
                kernel(one, 1, 1, np.zeros((1, 3)), np.zeros(3), np.zeros(3), np.array([1.0, 0.0]),
                       1.0, one, one, out)
            except Exception as exc:  # noqa: BLE001 - any failure of numba means: the numpy path
                warnings.warn(
                    f"robolab.fieldsum: the fused kernel is unavailable ({exc!r}); "
                    "using the numpy path (same sums, slower)",
                    stacklevel=3,
                )
                kernel = None
        _FUSED.append(kernel)
    return _FUSED[0]
