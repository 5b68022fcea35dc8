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
  safe jumps over those fields (no cap on the jump), six rays in flight at
  a time, each held in registers, with the next cell of each prefetched, so
  that their memory look-ups overlap.

The helpers of :func:`cast` are plain ``njit`` functions that LLVM inlines;
numba's own ``inline="always"`` gave the same speed but made the first compile
after an install take 19-23 s instead of about 5 (numba's IR passes grow with
every inlined copy).

The semantics, the safety argument and the references are in the docstring
of :mod:`robolab.raycast`.
"""

from __future__ import annotations

import math

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.core import cgutils
from numba.extending import intrinsic

#: Field codes are one byte: 0 marks an obstacle, ``v`` in 1..127 is the distance
#: ``D = v`` itself, and ``v`` in 128..255 stands for ``D >= 128 + 32 (v - 128)``
#: (rounded down: a shorter jump is always safe), up to :data:`FIELD_MAX` cells.
#: One byte per cell halves the fields' memory (they are read at random).
LINEAR, STEP = 128, 32
FIELD_MAX = LINEAR + STEP * (255 - LINEAR)
#: ``DECODE[v]``: the distance ``D`` (cells) that code ``v`` guarantees (whole numbers,
#: stored as floats: the kernel computes jump times with them).
DECODE = np.array(
    [v if v < LINEAR else LINEAR + STEP * (v - LINEAR) for v in range(256)], dtype=np.float64
)


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


@njit(cache=True, nogil=True)
def octant_fields(occ):  # pragma: no cover - compiled (run through the tests)
    """Column (or row) distances to the nearest obstacle a ray of each direction octant can reach.

    ``occ`` is the padded obstacle mask, shape ``(H, W)``. Octant
    ``q = [d_x < 0] + 2 [d_y < 0] + 4 [|d_y| > |d_x|]``, with ``sx, sy`` the signs of
    ``d``. From any point of cell ``(r, c)``, a *shallow* ray (``|d_y| <= |d_x|``) only
    reaches cells ``(r + sy a, c + sx b)`` of the wedge ``b >= 0, 0 <= a <= b + 1``
    (``|y - y_0| <= |x - x_0|`` along the ray, and the start lies within one cell), and

    ``E_q(r, c) = min b`` over the obstacle cells of that wedge,

    the number of whole columns between the cell and the first obstacle column the ray
    can meet; a steep ray the same with rows and columns swapped. The wedge of a cell is
    its own column's two cells ``(r, c), (r + sy, c)`` plus the wedges of ``(r, c + sx)``
    and ``(r + sy, c + sx)``, hence the recurrence ``E(r, c) = 0`` when one of those two
    cells is an obstacle, else ``1 + min(E(r, c + sx), E(r + sy, c + sx))`` (steep:
    ``(r, c), (r, c + sx)`` and ``(r + sy, c), (r + sy, c + sx)``), one raster pass per
    octant. A ray in cell ``(r, c)`` crosses column ``c + sx E`` no earlier than
    ``t_x + (E - 1) / |d_x|`` (``t_x``: when it leaves its cell's column), so no
    obstacle is entered before then: the jump of :func:`_step` with ``s = E`` (whose
    ``min`` with the row bound only shortens it). The quadrant's chessboard distance
    ``D`` (:func:`quadrant_fields`, computed in the same pass) bounds the same jump
    formula safely too, and the formula grows with ``s``, so the field stores
    ``s = max(E, D)``: ``E`` is limited only by the obstacles of a 45 degree wedge,
    ``D`` by those of the 90 degree quadrant but it lets a ray advance along both axes
    (``E`` is 0 or 1 next to an obstacle in the column beside the ray, where ``D`` may
    still allow a short jump).

    Returns
    -------
    numpy.ndarray of uint8, shape (8, H, W)
        0 on obstacles, else the code (:data:`DECODE`) of ``max(E_q, D_q, 1)``
        (1: an exact step).
    """
    h, w = occ.shape
    out = np.empty((8, h, w), np.uint8)
    big = 1 << 30
    prev = np.empty(w, np.int64)
    cur = np.empty(w, np.int64)
    dprev = np.empty(w, np.int64)
    dcur = np.empty(w, np.int64)
    for q in range(8):
        sx = -1 if q & 1 else 1
        sy = -1 if q & 2 else 1
        steep = q >= 4
        r0, r1 = (h - 1, -1) if sy > 0 else (0, h)
        c0, c1 = (w - 1, -1) if sx > 0 else (0, w)
        prev[:] = big  # the row beyond the map: free
        dprev[:] = big
        for r in range(r0, r1, -sy):
            rn = r + sy
            for c in range(c0, c1, -sx):
                cn = c + sx
                inside = 0 <= cn < w
                if steep:
                    blocked = occ[r, c] or (inside and occ[r, cn])
                    m = min(prev[c], prev[cn]) if inside else prev[c]
                else:
                    blocked = occ[r, c] or (0 <= rn < h and occ[rn, c])
                    m = min(cur[cn], prev[cn]) if inside else big
                cur[c] = 0 if blocked else min(m, big - 1) + 1
                # the quadrant's chessboard distance D (quadrant_fields' recurrence)
                dm = min(dprev[c], dcur[cn], dprev[cn]) if inside else dprev[c]
                dcur[c] = 0 if occ[r, c] else min(dm, big - 1) + 1
                if occ[r, c]:
                    out[q, r, c] = 0
                else:
                    out[q, r, c] = encode(max(cur[c], dcur[c], 1))
            prev, cur = cur, prev
            dprev, dcur = dcur, dprev
    return out


#: Rays traced together, each in registers: their field look-ups are independent,
#: so the processor overlaps their latencies (one ray alone is a chain of
#: dependent loads). Six lanes, written out in :func:`cast`: on benchmarks/raycast.py
#: (2026-12-01) three or four lost up to 30 % on the 2000 x 2000 map, where most
#: look-ups miss the caches, and eight lost 5-20 % on the small maps and the real one.
LANES = 6


@intrinsic
def _prefetch(typingctx, array, index):  # pragma: no cover - compiled
    """Ask the processor to load ``array[index]`` into its caches; no effect on results.

    Issued as soon as a ray's next cell is known, so that the look-up is in
    cache by the time the ray's lane comes round again (the large maps' fields
    do not fit in the caches, and each jump lands on an unrelated line).
    """

    def codegen(context, builder, signature, args):
        aryty = signature.args[0]
        ary = context.make_array(aryty)(context, builder, args[0])
        ptr = cgutils.get_item_pointer(context, builder, aryty, ary, [args[1]], wraparound=False)
        i8p, i32 = ir.IntType(8).as_pointer(), ir.IntType(32)
        fnty = ir.FunctionType(ir.VoidType(), [i8p, i32, i32, i32])
        fn = builder.module.declare_intrinsic("llvm.prefetch", [i8p], fnty)
        # read, high temporal locality, data cache
        builder.call(fn, [builder.bitcast(ptr, i8p), i32(0), i32(3), i32(1)])
        return context.get_dummy_value()

    return types.void(array, index), codegen


@njit(cache=True, nogil=True)
def cast(fields, poses, frame, angles, limit, h, w, res, zmax):  # pragma: no cover - compiled
    """Ranges in metres: ``min(t res, zmax)`` where a ray enters an obstacle, else ``zmax``.

    Parameters
    ----------
    fields : uint8 array, shape (4, h + 2, w + 2) or (8, h + 2, w + 2)
        :func:`quadrant_fields` or :func:`octant_fields` of the map padded by one free
        cell on every side (the step is the same for both).
    poses : float array, shape (N, 3)
        Sensor poses ``(x, y, theta)`` in the world frame (metres, radians).
    frame : tuple of 5 floats
        The map's origin ``(x, y)``, the cosine and sine of its yaw as
        :meth:`robolab.maps.OccupancyGrid.world_to_map` computes them, and the yaw:
        the poses are converted here, with that method's float operations in its
        order (the same map coordinates bit for bit, without its numpy temporaries,
        which cost about 5 % of a cast of 60 000 rays after other work).
    angles : float array, shape (B,)
        Beam angles relative to the heading.
    limit : float
        Range in cells (may be ``inf``).
    h, w : int
        The unpadded map's rows and columns.
    res, zmax : float
        Metres per cell; the range reported for a ray that hits nothing.

    Returns
    -------
    numpy.ndarray, shape (N, B)
    """
    n, b = poses.shape[0], angles.shape[0]
    total = n * b
    out = np.full(total + 1, zmax)
    if total == 0:
        return out[:0].reshape(n, b)
    uv, heading = _to_map(poses, frame, res)
    ca, sa = np.cos(angles), np.sin(angles)
    ch, sh = np.cos(heading), np.sin(heading)
    flat = fields.ravel()
    plane = fields.shape[1] * fields.shape[2]
    wp = fields.shape[2]
    octants = fields.shape[0] == 8
    geometry = (n, b, uv, ch, sh, ca, sa, limit, h, w, plane, wp, flat, octants)
    # One state tuple per lane (see _start); a lane whose ray index is `total` is idle.
    # The lanes are spelled out, not an array of states nor a helper per lane: that way
    # they stay in registers (measured: the array form 1.2-1.4x slower, numba-inlined
    # helpers per lane 3-4x).
    # First every ray of the poses on the map, six at a time; then the rays of the
    # poses off it (rare: a particle that strayed), one at a time.
    i, j = 0, 0
    s0, i, j = _start(i, j, geometry)
    s1, i, j = _start(i, j, geometry)
    s2, i, j = _start(i, j, geometry)
    s3, i, j = _start(i, j, geometry)
    s4, i, j = _start(i, j, geometry)
    s5, i, j = _start(i, j, geometry)
    live = LANES - (
        (s0[0] == total) + (s1[0] == total) + (s2[0] == total)
        + (s3[0] == total) + (s4[0] == total) + (s5[0] == total)
    )  # fmt: skip
    while live > 0:
        if s0[0] < total:
            s0, done, hit, t = _step(flat, wp, s0)
            if done:
                out[s0[0]] = min(t * res, zmax) if hit else zmax
                s0, i, j = _start(i, j, geometry)
                live -= s0[0] >= total
        if s1[0] < total:
            s1, done, hit, t = _step(flat, wp, s1)
            if done:
                out[s1[0]] = min(t * res, zmax) if hit else zmax
                s1, i, j = _start(i, j, geometry)
                live -= s1[0] >= total
        if s2[0] < total:
            s2, done, hit, t = _step(flat, wp, s2)
            if done:
                out[s2[0]] = min(t * res, zmax) if hit else zmax
                s2, i, j = _start(i, j, geometry)
                live -= s2[0] >= total
        if s3[0] < total:
            s3, done, hit, t = _step(flat, wp, s3)
            if done:
                out[s3[0]] = min(t * res, zmax) if hit else zmax
                s3, i, j = _start(i, j, geometry)
                live -= s3[0] >= total
        if s4[0] < total:
            s4, done, hit, t = _step(flat, wp, s4)
            if done:
                out[s4[0]] = min(t * res, zmax) if hit else zmax
                s4, i, j = _start(i, j, geometry)
                live -= s4[0] >= total
        if s5[0] < total:
            s5, done, hit, t = _step(flat, wp, s5)
            if done:
                out[s5[0]] = min(t * res, zmax) if hit else zmax
                s5, i, j = _start(i, j, geometry)
                live -= s5[0] >= total
    for i in range(n):
        if _on_map(uv[i, 0], uv[i, 1], h, w):
            continue
        for j in range(b):
            state, enters = _start_off_map(i, j, geometry)
            done = not enters
            while not done:
                state, done, hit, t = _step(flat, wp, state)
                if done and hit:
                    out[state[0]] = min(t * res, zmax)
    return out[:total].reshape(n, b)


@njit(nogil=True)
def _to_map(poses, frame, res):  # pragma: no cover - compiled
    """Map coordinates ``(N, 2)`` (cells) and headings ``(N,)`` of world ``poses``.

    :meth:`robolab.maps.OccupancyGrid.world_to_map` and ``theta - yaw``, operation for
    operation: ``u = (c dx + s dy) / res``, ``v = (-s dx + c dy) / res``.
    """
    ox, oy, c, s, yaw = frame
    n = poses.shape[0]
    uv = np.empty((n, 2))
    heading = np.empty(n)
    for i in range(n):
        dx = poses[i, 0] - ox
        dy = poses[i, 1] - oy
        uv[i, 0] = (c * dx + s * dy) / res
        uv[i, 1] = (-s * dx + c * dy) / res
        heading[i] = poses[i, 2] - yaw
    return uv, heading


@njit(nogil=True)
def _on_map(u0, v0, h, w):  # pragma: no cover - compiled
    """Whether the origin ``(u0, v0)`` (unpadded cells) lies on the map (half-open)."""
    return 0.0 <= u0 < w and 0.0 <= v0 < h


@njit(nogil=True)
def _start(i, j, geometry):  # pragma: no cover - compiled
    """The state of the next ray, from pose ``i``, beam ``j`` on, of a pose on the map; next i, j.

    The state is ``(m, t, t_end, ci, ri, koff, ax, ay, idx, idy, u0, v0, dx,
    dy)``: the ray's index, its time and end (cells), its cell (padded column,
    row), the offset of its quadrant's field, and constants of the ray (exit
    offsets, inverse direction, origin, direction). It is kept this short on
    purpose: the lanes of it live in registers, and every value more spills
    (the step signs and ``|1/d|`` are recomputed in :func:`_step` instead).
    Poses off the map are skipped (:func:`_start_off_map` starts their rays),
    and so are rays that leave the map at once (they keep ``zmax``); when no
    ray is left the state's index is ``n b`` (an idle lane).

    Every lane of :func:`cast` refills through it, so it holds only the usual
    case, a ray that starts at ``t = 0`` in its pose's cell (the general one,
    with slab tests against the map, is :func:`_start_off_map`).
    """
    n, b, uv, ch, sh, ca, sa, limit, h, w, plane, wp, flat, octants = geometry
    while i < n:
        u0, v0 = uv[i, 0], uv[i, 1]
        if not _on_map(u0, v0, h, w):
            i, j = i + 1, 0
            continue
        m = i * b + j
        # cos and sin of heading + angle by the sum formulas (no trig per ray)
        dx = ch[i] * ca[j] - sh[i] * sa[j]
        dy = sh[i] * ca[j] + ch[i] * sa[j]
        j += 1
        if j == b:
            i, j = i + 1, 0
        idx = math.inf if dx == 0.0 else 1.0 / dx
        idy = math.inf if dy == 0.0 else 1.0 / dy
        tx_out = ((w if dx > 0.0 else 0.0) - u0) * idx if dx != 0.0 else math.inf
        ty_out = ((h if dy > 0.0 else 0.0) - v0) * idy if dy != 0.0 else math.inf
        t_end = min(tx_out, ty_out, limit)
        if not 0.0 < t_end:  # on the map's lower or left edge, pointing out of it
            continue
        # padded coordinates: cell (0, 0) of the map is (1, 1)
        ci, ri = int(u0) + 1, int(v0) + 1
        state = _state(m, 0.0, t_end, ci, ri, u0 + 1.0, v0 + 1.0, dx, dy, idx, idy, plane, octants)
        _prefetch(flat, state[5] + ri * wp + ci)
        return state, i, j
    idle = (n * b, 0.0, 0.0, 1, 1, 0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 1.0, 1.0)
    return idle, i, j


@njit(nogil=True)
def _start_off_map(i, j, geometry):  # pragma: no cover - compiled
    """The state of ray ``(i, j)`` of a pose off the map where it enters it; ``(state, enters)``.

    ``enters`` is False for a ray that misses the map (it keeps ``zmax``).
    """
    n, b, uv, ch, sh, ca, sa, limit, h, w, plane, wp, flat, octants = geometry
    u0, v0 = uv[i, 0], uv[i, 1]
    dx = ch[i] * ca[j] - sh[i] * sa[j]
    dy = sh[i] * ca[j] + ch[i] * sa[j]
    idx = math.inf if dx == 0.0 else 1.0 / dx
    idy = math.inf if dy == 0.0 else 1.0 / dy
    tx_in, tx_out = _slab(u0, dx, idx, 0.0 <= u0 < w, w)
    ty_in, ty_out = _slab(v0, dy, idy, 0.0 <= v0 < h, h)
    t = max(tx_in, ty_in, 0.0)
    t_end = min(tx_out, ty_out, limit)
    u0 += 1.0
    v0 += 1.0
    enters = t < t_end
    if not enters:
        t = 0.0  # (the state is not traced)
    ci = int(min(max(math.floor(u0 + t * dx), 1.0), float(w)))
    ri = int(min(max(math.floor(v0 + t * dy), 1.0), float(h)))
    state = _state(i * b + j, t, t_end, ci, ri, u0, v0, dx, dy, idx, idy, plane, octants)
    return state, enters


@njit(nogil=True)
def _state(m, t, t_end, ci, ri, u0, v0, dx, dy, idx, idy, plane, octants):  # pragma: no cover
    """A lane's state (:func:`_start`) for ray ``m`` at ``t`` in padded cell ``(ci, ri)``.

    ``octants``: the fields are :func:`octant_fields` (else :func:`quadrant_fields`).
    """
    q = (1 if dx < 0 else 0) + (2 if dy < 0 else 0)
    koff = (q + (4 if octants and abs(dy) > abs(dx) else 0)) * plane
    ax = (1.0 if dx >= 0 else 0.0) - u0
    ay = (1.0 if dy >= 0 else 0.0) - v0
    return (m, t, t_end, ci, ri, koff, ax, ay, idx, idy, u0, v0, dx, dy)


@njit(nogil=True)
def _step(flat, wp, state):  # pragma: no cover - compiled
    """One iteration of a ray: ``(new state, done, hit, t)``, ``t`` the time it started from.

    The field code of the ray's cell bounds how far it may go: every obstacle
    ahead is at least ``s = DECODE[code]`` columns or rows away, so the ray
    reaches none before it has crossed ``s - 1`` more columns or rows than its
    cell's exit, ``min(t_x + (s - 1) / |d_x|, t_y + (s - 1) / |d_y|)``. The same
    formula is one exact Amanatides-Woo step into the next cell for ``s = 1``
    and does not advance for code 0 (the ray is in an obstacle: a hit at the
    ``t`` returned, the time the ray entered it). The axis that was crossed
    moves by ``s`` cells; the other one is recomputed from the position after a
    jump and kept after a step.

    Branch-free on purpose: which of those cases applies, and along which axis,
    changes from one iteration to the next without a pattern, and the
    mispredicted branches of an if/else version cost a third of the time. The
    choices are integer masks, and ``|1/d|`` is capped at 1e300 so that
    ``0 * |1/d|`` is 0, not NaN, for a ray along an axis (a smaller bound only
    shortens a jump).
    """
    m, t, t_end, ci, ri, koff, ax, ay, idx, idy, u0, v0, dx, dy = state
    sx = 1 if idx > 0.0 else -1  # idx = +inf for dx = 0: the sign _start used for koff, ax
    sy = 1 if idy > 0.0 else -1
    adx = min(abs(idx), 1e300)
    ady = min(abs(idy), 1e300)
    code = flat[koff + ri * wp + ci]
    s = DECODE[code]
    tx = (ci + ax) * idx  # when the ray leaves the cell's column / row
    ty = (ri + ay) * idy
    jx = tx + (s - 1.0) * adx
    jy = ty + (s - 1.0) * ady
    t_new = max(min(jx, jy), t)
    x_mask = -np.int64(jx <= jy)  # all ones: the ray crossed columns
    j_mask = -np.int64(code > 1)  # all ones: a jump (else a step, or a hit)
    step = np.int64(s)
    # padded positions are > 0 on the map, so int() is floor()
    c_at = np.int64(u0 + t_new * dx)
    r_at = np.int64(v0 + t_new * dy)
    c_side = (c_at & j_mask) | (ci & ~j_mask)
    r_side = (r_at & j_mask) | (ri & ~j_mask)
    ci_new = ((ci + sx * step) & x_mask) | (c_side & ~x_mask)
    ri_new = (r_side & x_mask) | ((ri + sy * step) & ~x_mask)
    hit = code == 0
    _prefetch(flat, koff + ri_new * wp + ci_new)
    done = hit | (t_new >= t_end)
    state = (m, t_new, t_end, ci_new, ri_new, koff, ax, ay, idx, idy, u0, v0, dx, dy)
    return state, done, hit, t


@njit(nogil=True)
def _slab(p, d, inv, inside, size):  # pragma: no cover - compiled
    """``(t_in, t_out)`` of one ray coordinate against the slab ``[0, size]`` (half-open)."""
    if d == 0.0:
        if inside:
            return -math.inf, math.inf
        return math.inf, -math.inf
    a0, a1 = -p * inv, (size - p) * inv
    return min(a0, a1), max(a0, a1)


@njit(cache=True, nogil=True)
def table_sum(flat, rows, cols, uv, c, s, qx, qy, out):  # pragma: no cover - compiled
    """``out[i] = sum_k flat[row * cols + col]`` at the endpoints of :mod:`robolab.fieldsum`.

    The float32 arithmetic of :func:`robolab.fieldsum.numpy_table_sum`, operation by
    operation (same endpoints, same cells), without (N, B) temporaries: per pose, one
    loop computes the B cell indices (branch-free, which LLVM vectorizes) and a second
    sums the table there, beam by beam in order.
    """
    hi_u = np.float32(cols - 1)
    hi_v = np.float32(rows - 1)
    zero = np.float32(0.0)
    n_beams = qx.shape[0]
    index = np.empty(n_beams, np.int64)
    for i in range(uv.shape[0]):
        ci, si, u0, v0 = c[i], s[i], uv[i, 0], uv[i, 1]
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
