"""The numpy path's jump fields of :mod:`robolab.raycast`: Euclidean quadrant distances.

Split from :mod:`robolab.raycast` (which re-exports these names); the semantics and
the safety argument are in that module's docstring.
"""

from __future__ import annotations

import numpy as np

# Jumps are capped at this many cells (the cost of building the fields grows with it).
_CAP = 63
# Field codes (uint8): quarter cells 0..4 * _CAP, and _OBSTACLE. _LUT maps a
# code to the jump in cells, and an obstacle to -2 (tested as s < -1).
_OBSTACLE = 255
_LUT = np.arange(256) / 4.0
_LUT[_OBSTACLE] = -2.0


def _quadrant_field(occ: np.ndarray, cap: int = _CAP) -> np.ndarray:
    """Jump codes for rays going up and right (``d_x >= 0``, ``d_y >= 0``).

    ``floor(4 * min(s, cap))`` as uint8, where ``s(r, c)`` is the smallest
    ``hypot(max(r' - r - 1, 0), max(c' - c - 1, 0))`` over obstacles ``occ[r', c']``
    with ``r' >= r`` and ``c' >= c`` (the distance between the two cell squares).
    The other quadrants are this on the flipped map. Exact integer arithmetic:
    squared distances are small integers, and ``floor(sqrt(m))`` of an integer
    ``m < 2**52`` computed with the correctly rounded float sqrt is exact.
    """
    h, w = occ.shape
    col = np.arange(w, dtype=np.int32)
    # g: free cells between c and the next obstacle at column >= c in the row (capped).
    nxt = np.minimum.accumulate(np.where(occ, col, np.int32(w + cap + 1))[:, ::-1], axis=1)[:, ::-1]
    g = np.clip(nxt - col - 1, 0, cap).astype(np.int16)
    g *= g  # <= cap**2
    s2 = g.copy()
    # s2(r) = min(g(r), min_{k >= 0} k**2 + g(r + 1 + k)): the row term max(r' - r - 1, 0)
    # is 0 for r' = r and r' = r + 1, then k for r' = r + 1 + k. Column strips stay
    # in cache and stop early once k**2 exceeds every value (<= cap**2) in the strip.
    strip = 256
    tmp = np.empty((h, strip), np.int16)
    for c0 in range(0, w, strip):
        gs = np.ascontiguousarray(g[:, c0 : c0 + strip])
        ss = s2[:, c0 : c0 + strip]
        k = 0
        while k < h - 1 and k * k < int(ss.max()):
            n = h - 1 - k
            t = tmp[:n, : gs.shape[1]]
            np.add(gs[1 + k :], np.int16(k * k), out=t)  # <= 2 cap**2 < 2**15
            np.minimum(ss[:n], t, out=ss[:n])
            k += 1
    code = np.floor(np.sqrt(16.0 * s2)).astype(np.uint8)  # floor(4 s) <= 4 cap < 255
    code[occ] = _OBSTACLE
    return code
