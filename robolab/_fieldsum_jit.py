"""The compiled kernel of :func:`robolab.fieldsum.pose_table_sum` (numba, one core).

Imported lazily by :mod:`robolab.fieldsum` on its own, without the ray casters of
:mod:`robolab._raycast_jit` (``ROBOLAB_RAYCAST=numpy`` keeps numba out here too).

One pass per pose, with no (N, B) and no (N,) temporaries: the laser's pose
(:func:`robolab.geometry.compose`), its map coordinates
(:meth:`robolab.maps.OccupancyGrid.world_to_map`), the cosine and sine of its
heading in the map, then the table sum of :func:`robolab._raycast_jit.table_sum`.
Every step is the numpy path's operation, in its order and precision (float64
up to the map coordinates, float32 from the endpoints on; numba contracts no
``a * b + c`` into a fused multiply-add without fastmath), and ``math.cos`` /
``math.sin`` are the C library's, which numpy's float64 ``cos`` / ``sin`` call
on x86-64 without AVX-512: there the two paths give the same bits (tested).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, types

TWO_PI = 2.0 * np.pi


def _readonly(dtype, ndim):
    return types.Array(dtype, ndim, "C", readonly=True)


#: The one signature of :func:`pose_table_sum`: its inputs typed read-only, so that
#: writeable and read-only arrays (the likelihood table is frozen) both convert to it. Left
#: to numba, each combination of flags compiled its own version (two in lab 05: 0.3 s of
#: CPU each with an empty cache) and read-only views cost a slow type look-up per call.
SIGNATURE = types.void(
    _readonly(types.float32, 1), types.int64, types.int64, _readonly(types.float64, 2),
    _readonly(types.float64, 1), _readonly(types.float64, 1), _readonly(types.float64, 1),
    types.float64, _readonly(types.float32, 1), _readonly(types.float32, 1),
    types.Array(types.float64, 1, "C"),
)


@njit(cache=True, nogil=True)
def _wrap(a):  # pragma: no cover - compiled
    """:func:`robolab.geometry.wrap_angle` of a finite float, bit for bit."""
    x = a + math.pi
    if -TWO_PI <= x < 2.0 * TWO_PI:  # numpy's remainder on this range (see wrap_angle)
        if x >= TWO_PI:
            x = x - TWO_PI
        elif x < 0.0:
            x = x + TWO_PI
    else:
        x = x % TWO_PI  # numba's float % is CPython's: fmod, sign fixed, as numpy's remainder
    x = x - math.pi
    if x >= math.pi:
        x = x - TWO_PI
    return x


@njit(SIGNATURE, cache=True, nogil=True)
def pose_table_sum(  # pragma: no cover - compiled
    flat, rows, cols, poses, laser, origin, rot, res, qx, qy, out
):
    """``out[i]``: the table sum at the beam endpoints of the laser on pose ``poses[i]``.

    ``laser`` is the laser's pose on the robot, ``origin`` the map's origin,
    ``rot`` = ``(cos, sin)`` of the origin's yaw as numpy computes them, ``res``
    the resolution; ``qx, qy`` the beam endpoints in the laser frame (cells,
    float32). The table has a one-cell border, hence the ``+ 1``.
    """
    hi_u = np.float32(cols - 1)
    hi_v = np.float32(rows - 1)
    zero = np.float32(0.0)
    one = np.float32(1.0)
    lx, ly, lt = laser[0], laser[1], laser[2]
    ox, oy, oyaw = origin[0], origin[1], origin[2]
    co, so = rot[0], rot[1]
    n_beams = qx.shape[0]
    index = np.empty(n_beams, np.int64)
    for i in range(poses.shape[0]):
        px, py, pt = poses[i, 0], poses[i, 1], poses[i, 2]
        # compose(pose, laser)
        c = math.cos(pt)
        s = math.sin(pt)
        x = px + c * lx - s * ly
        y = py + s * lx + c * ly
        heading = _wrap(pt + lt)
        # world_to_map, then float32 and the border
        dx = x - ox
        dy = y - oy
        u0 = np.float32((co * dx + so * dy) / res) + one
        v0 = np.float32((-so * dx + co * dy) / res) + one
        phi = heading - oyaw
        ci = np.float32(math.cos(phi))
        si = np.float32(math.sin(phi))
        # The loops of _raycast_jit.table_sum, written out again on purpose: one shared
        # njit helper made this kernel 7-11 % slower (interleaved, 5000 poses x 60 beams).
        for k in range(n_beams):
            u = ci * qx[k]
            u = u - si * qy[k]
            u = u + u0
            v = si * qx[k]
            v = v + ci * qy[k]
            v = v + v0
            # min/max by selects that send NaN to 0 (an int32 of NaN would index outside
            # the table: poses at +-1e308 or NaN); a NaN endpoint reads cell 0, as numpy's
            # clipped take does. Branch-free, so LLVM still vectorizes the loop.
            nan = (u != u) | (v != v)
            u = u if u > zero else zero
            u = u if u < hi_u else hi_u
            v = v if v > zero else zero
            v = v if v < hi_v else hi_v
            cell = np.int64(np.int32(v)) * cols + np.int64(np.int32(u))
            index[k] = 0 if nan else cell
        acc = 0.0
        for k in range(n_beams):
            acc += flat[index[k]]
        out[i] = acc
