"""Sums of a per-cell table at the beam endpoints of many poses: the inner loop of MCL.

:func:`table_sum` serves the likelihood-field model (Probabilistic Robotics, Table 6.3):
each particle ``i`` puts the endpoint of beam ``k`` at the map coordinates (cells,
column ``u`` and row ``v``)

.. math::

    u_{ik} = u_i + c_i q^x_k - s_i q^y_k, \\qquad v_{ik} = v_i + s_i q^x_k + c_i q^y_k

(``c, s``: cosine and sine of the particle's heading in the map, ``q``: the beam's
endpoint in the laser frame, in cells), clipped into the table, and the result is
:math:`\\sum_k T[\\lfloor v_{ik} \\rfloor, \\lfloor u_{ik} \\rfloor]`.

Two paths, chosen like :mod:`robolab.raycast`'s backends (``ROBOLAB_RAYCAST=numpy``
forces numpy): a compiled kernel (:func:`robolab._raycast_jit.table_sum`, one fused
pass) and numpy in cache-sized blocks of particles. Both compute the endpoints in
float32 with the same operations, so they look up the same cells, and both add the
B values in beam order in float64: the two paths give the same bits.
"""

from __future__ import annotations

import numpy as np

from robolab import raycast

__all__ = ["table_sum", "numpy_table_sum"]

#: numpy_table_sum looks up about this many endpoints at a time: whole (N, B) temporaries
#: would spill out of the core's cache once N is large, and the time would grow faster than N.
BLOCK = 1 << 15


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
    if backend not in raycast.BACKENDS:
        raise ValueError(f"backend must be one of {raycast.BACKENDS}, got {backend!r}")
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
    per = max(1, BLOCK // max(b, 1))
    out = np.empty(n)
    u0, v0 = np.ascontiguousarray(uv[:, 0]), np.ascontiguousarray(uv[:, 1])
    qx, qy = qx[:, None], qy[:, None]
    hi_u, hi_v = np.float32(cols - 1), np.float32(rows - 1)
    shape = (b, min(per, n))
    u, v, tmp = (np.empty(shape, np.float32) for _ in range(3))
    index, col = np.empty(shape, np.int32), np.empty(shape, np.int32)
    for i in range(0, n, per):
        k = min(per, n - i)
        cs, ss = c[i : i + k], s[i : i + k]
        uu, vv, tt, ii, cc = u[:, :k], v[:, :k], tmp[:, :k], index[:, :k], col[:, :k]
        np.multiply(cs, qx, out=uu)
        np.multiply(ss, qy, out=tt)
        uu -= tt
        uu += u0[i : i + k]
        np.multiply(ss, qx, out=vv)
        np.multiply(cs, qy, out=tt)
        vv += tt
        vv += v0[i : i + k]
        # clip into the border; floor == truncation for u >= 0
        np.clip(uu, 0, hi_u, out=uu)
        np.clip(vv, 0, hi_v, out=vv)
        np.copyto(ii, vv, casting="unsafe")
        ii *= np.int32(cols)
        np.copyto(cc, uu, casting="unsafe")
        ii += cc
        np.take(flat, ii, out=tt, mode="clip")  # in range already; "raise" would buffer
        np.add.reduce(tt, axis=0, dtype=np.float64, out=out[i : i + k])
    return out
