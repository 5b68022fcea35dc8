"""Central difference divided by delta instead of 2 delta.

Derivative.

class: formula
"""

import numpy as np

from robolab.geometry import wrap_angle
from robolab.raycast import cast_rays
from robolab.validation import as_array, check_positive
from solutions.ekf_mapping import JACOBIAN_STEPS, MAX_RANGE, N_BEAMS, _as_grid, _beam_angles, _state


def measurement_jacobian(state, grid, n_beams=N_BEAMS, max_range=MAX_RANGE, steps=JACOBIAN_STEPS):
    """Jacobian ``H = dh/dx`` of :func:`measurement_function` by central differences.

    .. math::

        H_{kj} \\approx \\frac{h_k(x + \\delta_j e_j) - h_k(x - \\delta_j e_j)}{2 \\delta_j},
        \\qquad j \\in \\{x, y, \\theta\\}

    (Probabilistic Robotics, Table 3.3 line 4 needs ``H_t``; the seed lets
    MATLAB's ``trackingEKF`` approximate it numerically in the same way).
    All six perturbed poses are ray-cast in one :func:`cast_rays` call.

    A ray-cast range is only *piecewise* differentiable: while a beam ends on
    one straight face of an obstacle, its range is linear in ``x`` and ``y``
    and smooth in ``theta``, so any step inside that piece gives the exact
    slope (up to ``O(delta^2)`` in ``theta``). Where the beam slides off a
    corner onto another obstacle, or starts or stops reaching ``max_range``,
    the range jumps; a difference straddling the jump returns
    ``jump / (2 delta)``, not a derivative. The default steps, 0.1 cell in
    position and 0.01 rad in heading (0.2 cell across at a range of 20), keep
    most beams inside one piece while staying far above round-off; smaller
    steps make the (rare) straddling entries larger, larger steps make them
    more frequent.

    Parameters
    ----------
    state, grid, n_beams, max_range
        As in :func:`measurement_function`.
    steps : (float, float, float)
        Half-widths ``delta`` for x, y (units) and theta (rad), each > 0.

    Returns
    -------
    numpy.ndarray, shape (n_beams, 3)
    """
    s = _state(state)
    g = _as_grid(grid)
    d = as_array("steps", steps, shape=(3,), finite=True)
    if np.any(d <= 0):
        raise ValueError(f"steps must be three positive numbers, got {d}")
    poses = np.repeat(s[None, :], 6, axis=0)
    poses[0::2] += np.diag(d)  # +delta_j e_j for j = 0, 1, 2
    poses[1::2] -= np.diag(d)
    poses[:, 2] = wrap_angle(poses[:, 2])
    r = cast_rays(g, poses, _beam_angles(n_beams), check_positive("max_range", max_range))
    return ((r[0::2] - r[1::2]) / d[:, None]).T
