"""The compiled ray-casting kernels of :mod:`robolab.raycast` (numba, one core).

Imported lazily by :mod:`robolab.raycast` the first time a grid is cast on
(``import numba`` and loading the kernels cost about a second, so ``import
robolab`` stays fast); when numba is missing or unusable, :mod:`robolab.raycast`
falls back to its pure-numpy path, which gives the same ranges.

Two kernels, both plain loops that numba compiles once (and caches on disk):

* :func:`quadrant_fields`: for each of the four direction quadrants, the
  chessboard distance from every cell to the nearest obstacle cell *ahead*,
  by the largest-empty-square recurrence (one raster pass per quadrant);
* :func:`cast`: every ray's exact Amanatides-Woo traversal, accelerated by
  safe jumps over those fields (no cap on the jump), eight rays in flight at
  a time so that their memory look-ups overlap.

The semantics, the safety argument and the references are in the docstring
of :mod:`robolab.raycast`.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

#: Field codes are one byte: 0 marks an obstacle, ``v`` in 1..127 is the distance
#: ``D = v`` itself, and ``v`` in 128..255 stands for ``D >= 128 + 32 (v - 128)``
#: (rounded down: a shorter jump is always safe), up to :data:`FIELD_MAX` cells.
#: One byte per cell halves the fields' memory (they are read at random).
LINEAR, STEP = 128, 32
FIELD_MAX = LINEAR + STEP * (255 - LINEAR)
#: ``DECODE[v]``: the distance ``D`` (cells) that code ``v`` guarantees.
DECODE = np.array([v if v < LINEAR else LINEAR + STEP * (v - LINEAR) for v in range(256)])


@njit(cache=True, nogil=True)
def encode(d):  # pragma: no cover - compiled
    """The code of distance ``d >= 0`` (the largest ``v`` with ``DECODE[v] <= d``)."""
    if d < LINEAR:
        return d
    return min(LINEAR + (d - LINEAR) // STEP, 255)


@njit(cache=True, nogil=True)
def quadrant_fields(occ):  # pragma: no cover - compiled (run through the tests)
    """Chessboard distances to the nearest obstacle ahead, one field per direction quadrant.

    ``occ`` is the padded obstacle mask, shape ``(H, W)``. Quadrant
    ``q = [d_x < 0] + 2 [d_y < 0]`` holds, for a free cell ``(r, c)``,

    ``D_q(r, c) = min max(sy (r' - r), sx (c' - c))`` over the obstacle cells
    ``(r', c')`` with ``sx (c' - c) >= 0`` and ``sy (r' - r) >= 0``,

    the side of the largest obstacle-free square with its corner at ``(r, c)``
    that extends along ``(sx, sy)``; 0 on obstacles (the map's outside counts as
    free). The recurrence ``D(r, c) = 1 + min(D(r + sy, c), D(r, c + sx),
    D(r + sy, c + sx))`` computes it in one pass, two rows at a time. The
    Euclidean distance between the squares of ``(r, c)`` and of such an
    obstacle is at least ``max(|dr|, |dc|) - 1``: a ray in that quadrant can
    safely advance ``D_q - 1`` cells (see :func:`cast` for the longer jump used).

    Returns
    -------
    numpy.ndarray of uint8, shape (4, H, W)
        The codes of ``D_q`` (:data:`DECODE`).
    """
    h, w = occ.shape
    out = np.empty((4, h, w), np.uint8)
    big = 1 << 30
    prev = np.empty(w, np.int64)
    cur = np.empty(w, np.int64)
    for q in range(4):
        sx = -1 if q & 1 else 1
        sy = -1 if q & 2 else 1
        r0, r1 = (h - 1, -1) if sy > 0 else (0, h)
        c0, c1 = (w - 1, -1) if sx > 0 else (0, w)
        prev[:] = big  # the row beyond the map: free
        for r in range(r0, r1, -sy):
            for c in range(c0, c1, -sx):
                if occ[r, c]:
                    cur[c] = 0
                else:
                    cn = c + sx
                    m = prev[c]
                    if 0 <= cn < w:
                        m = min(m, cur[cn], prev[cn])
                    cur[c] = min(m, big - 1) + 1
                out[q, r, c] = encode(cur[c])
            prev, cur = cur, prev
    return out


#: Rays traced together: their field look-ups are independent, so the processor
#: overlaps their cache misses (the loop is latency-bound, one ray at a time).
LANES = 8


@njit(cache=True, nogil=True)
def cast(fields, uv, heading, angles, limit, h, w):  # pragma: no cover - compiled
    """Distances in cells of every ray, or -1 where the ray hits nothing before ``limit``.

    Parameters
    ----------
    fields : uint8 array, shape (4, h + 2, w + 2)
        :func:`quadrant_fields` of the map padded by one free cell on every side.
    uv : float array, shape (N, 2)
        Ray origins in continuous map coordinates (cells, unpadded).
    heading : float array, shape (N,)
        Heading of each pose in the map frame (radians).
    angles : float array, shape (B,)
        Beam angles relative to the heading.
    limit : float
        Range in cells (may be ``inf``).
    h, w : int
        The unpadded map's rows and columns.

    Returns
    -------
    numpy.ndarray, shape (N, B)
    """
    n, b = uv.shape[0], angles.shape[0]
    out = np.full(n * b, -1.0)
    if n * b == 0:
        return out.reshape(n, b)
    ca, sa = np.cos(angles), np.sin(angles)
    ch, sh = np.cos(heading), np.sin(heading)
    flat = fields.ravel()
    plane = fields.shape[1] * fields.shape[2]
    wp = fields.shape[2]
    # per lane: origin, direction, inverse direction, exit offsets, t, t_end, cell, field offset
    fs = np.empty((12, LANES))
    ints = np.empty((5, LANES), np.int64)  # ci, ri, sx, sy, koff
    ray = np.full(LANES, -1, np.int64)
    nxt = 0
    live = 0
    # fill every lane with a ray that enters the map
    for k in range(LANES):
        nxt = _refill(k, nxt, n * b, b, uv, ch, sh, ca, sa, limit, h, w, plane, fs, ints, ray, out)
        if ray[k] >= 0:
            live += 1
    while live > 0:
        for k in range(LANES):
            m = ray[k]
            if m < 0:
                continue
            u0, v0, idx, idy, adx, ady, ax, ay, t, t_end, dx, dy = (
                fs[0, k],
                fs[1, k],
                fs[2, k],
                fs[3, k],
                fs[4, k],
                fs[5, k],
                fs[6, k],
                fs[7, k],
                fs[8, k],
                fs[9, k],
                fs[10, k],
                fs[11, k],
            )
            ci, ri, sx, sy, koff = ints[0, k], ints[1, k], ints[2, k], ints[3, k], ints[4, k]
            code = flat[koff + ri * wp + ci]
            s = int(DECODE[code])
            done = False
            if code == 0:
                out[m] = t
                done = True
            else:
                tx = (ci + ax) * idx  # when the ray leaves the cell's column / row
                ty = (ri + ay) * idy
                # Every obstacle ahead is >= s columns or >= s rows away: the ray reaches
                # none before it has crossed s - 1 more columns or rows (s = 1: one
                # exact Amanatides-Woo step into the next cell).
                jx, jy = tx, ty
                if s > 1:  # (not for s = 1: 0 * inf is NaN along an axis)
                    jx += (s - 1.0) * adx
                    jy += (s - 1.0) * ady
                # padded positions are > 0 on the map, so int() is floor()
                if jx <= jy:
                    t = max(jx, t)
                    ci += sx * s
                    if s > 1:
                        ri = int(v0 + t * dy)
                else:
                    t = max(jy, t)
                    ri += sy * s
                    if s > 1:
                        ci = int(u0 + t * dx)
                done = t >= t_end
            if done:
                nxt = _refill(
                    k, nxt, n * b, b, uv, ch, sh, ca, sa, limit, h, w, plane, fs, ints, ray, out
                )
                if ray[k] < 0:
                    live -= 1
            else:
                fs[8, k] = t
                ints[0, k] = ci
                ints[1, k] = ri
    return out.reshape(n, b)


@njit(inline="always")
def _refill(
    k, nxt, total, b, uv, ch, sh, ca, sa, limit, h, w, plane, fs, ints, ray, out
):  # pragma: no cover
    """Put the next ray that enters the map (from ray ``nxt`` on) into lane ``k``; the new ``nxt``.

    Rays that miss the map keep ``out = -1``; ``ray[k] = -1`` when none is left.
    """
    while nxt < total:
        m = nxt
        nxt += 1
        i, j = m // b, m % b
        u0, v0 = uv[i, 0], uv[i, 1]
        # cos and sin of heading + angle by the sum formulas (no trig per ray)
        dx = ch[i] * ca[j] - sh[i] * sa[j]
        dy = sh[i] * ca[j] + ch[i] * sa[j]
        idx = math.inf if dx == 0.0 else 1.0 / dx
        idy = math.inf if dy == 0.0 else 1.0 / dy
        tx_in, tx_out = _slab(u0, dx, idx, 0.0 <= u0 < w, w)
        ty_in, ty_out = _slab(v0, dy, idy, 0.0 <= v0 < h, h)
        t = max(tx_in, ty_in, 0.0)
        t_end = min(tx_out, ty_out, limit)
        if not t < t_end:
            continue
        # padded coordinates: cell (0, 0) of the map is (1, 1)
        u0 += 1.0
        v0 += 1.0
        ints[0, k] = int(min(max(math.floor(u0 + t * dx), 1.0), float(w)))
        ints[1, k] = int(min(max(math.floor(v0 + t * dy), 1.0), float(h)))
        ints[2, k] = 1 if dx >= 0 else -1
        ints[3, k] = 1 if dy >= 0 else -1
        ints[4, k] = ((1 if dx < 0 else 0) + (2 if dy < 0 else 0)) * plane
        fs[0, k], fs[1, k], fs[2, k], fs[3, k] = u0, v0, idx, idy
        fs[4, k], fs[5, k] = abs(idx), abs(idy)
        fs[6, k] = (1.0 if dx >= 0 else 0.0) - u0
        fs[7, k] = (1.0 if dy >= 0 else 0.0) - v0
        fs[8, k], fs[9, k], fs[10, k], fs[11, k] = t, t_end, dx, dy
        ray[k] = m
        return nxt
    ray[k] = -1
    return nxt


@njit(inline="always")
def _slab(p, d, inv, inside, size):  # pragma: no cover - compiled
    """``(t_in, t_out)`` of one ray coordinate against the slab ``[0, size]`` (half-open)."""
    if d == 0.0:
        if inside:
            return -math.inf, math.inf
        return math.inf, -math.inf
    a0, a1 = -p * inv, (size - p) * inv
    return min(a0, a1), max(a0, a1)
