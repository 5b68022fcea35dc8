"""The cyclic landmark world of lab 03: ``cWorld`` and ``cRobot``.

A robot lives on a cyclic (toroidal) ``size`` x ``size`` square, 100 x 100 by
default: leaving the square on one side brings it back on the opposite side.
Four point landmarks sit in the world; the robot measures the Euclidean range
to every one of them with additive Gaussian noise.

robolab uses the
classic layout of this exercise, :data:`LANDMARKS`
``[[20, 20], [80, 80], [20, 80], [80, 20]]``.

Conventions and deliberate departures from the MATLAB original
--------------------------------------------------------------
- Headings are wrapped to ``[-pi, pi)`` with :func:`robolab.geometry.wrap_angle`
  (robolab's convention); the MATLAB version keeps them in ``[0, 2 pi)``. Both describe the
  same direction, so positions and ranges are unchanged.
- Positions are wrapped to ``[0, size)`` with :func:`wrap_position`; the MATLAB
  version subtracts or adds ``size`` once, which leaves ``x == size`` possible and fails
  for moves longer than ``size``.
- :meth:`cRobot.move` draws **one** forward-noise sample per move. The MATLAB version
  draws two independent samples, one for x and one for y, so its robot no longer
  moves along its heading (the displacement's direction is random even with
  ``turn_noise = 0``). That is a bug, not a model.
- Ranges are plain Euclidean distances, **without** the cyclic wrap (as in the
  MATLAB version): a robot at x = 95 is 75 (not 25) away from a landmark at x = 20.

The class names keep the MATLAB camelCase (``cWorld``, ``cRobot``) because the
lab's text refers to them by these names.
"""

from __future__ import annotations

import numpy as np

from robolab.geometry import wrap_angle
from robolab.validation import as_array, check_finite, check_positive, check_rng

__all__ = ["LANDMARKS", "WORLD_SIZE", "cWorld", "cRobot", "wrap_position", "landmark_ranges"]

#: Side of the square cyclic world (same unit as the ranges).
WORLD_SIZE = 100.0

#: The exercise's four landmarks (x, y), one per row (the classic layout of
#: this exercise).
LANDMARKS = np.array([[20.0, 20.0], [80.0, 80.0], [20.0, 80.0], [80.0, 20.0]])


def wrap_position(values, size: float = WORLD_SIZE):
    """Wrap coordinates onto the cyclic world ``[0, size)``.

    Parameters
    ----------
    values : array_like
        Coordinates (any shape).
    size : float
        Side of the world, > 0.

    Returns
    -------
    numpy.ndarray or float
        ``values mod size`` in ``[0, size)``. A tiny negative value such as
        ``-1e-17``, which floating-point ``mod`` rounds up to ``size`` itself, is
        mapped to 0 so the result never equals ``size``.
    """
    size = check_positive("size", size)
    v = np.asarray(values, dtype=float)
    w = v - size * np.floor(v / size)  # = v mod size, about twice as fast as np.mod
    # Rounding can land exactly on size (v = -1e-17) or a hair below 0: both mean 0.
    w = np.where((w >= size) | (w < 0.0), 0.0, w)
    return float(w) if w.ndim == 0 else w


def landmark_ranges(xy, landmarks) -> np.ndarray:
    """Euclidean ranges from positions to landmarks (no cyclic wrap).

    Parameters
    ----------
    xy : array_like, shape (2,) or (N, 2)
        Position(s) ``(x, y)``.
    landmarks : array_like, shape (K, 2)
        Landmark positions.

    Returns
    -------
    numpy.ndarray, shape (K,) for one position, (N, K) for N positions
        ``sqrt((x - l_x)^2 + (y - l_y)^2)``.
    """
    lm = as_array("landmarks", landmarks, ndim=2, finite=True)
    if lm.shape[1] != 2:
        raise ValueError(f"landmarks must have shape (K, 2), got {lm.shape}")
    p = as_array("xy", xy, ndim=(1, 2), finite=True)
    if p.shape[-1] != 2:
        raise ValueError(f"xy must have shape (2,) or (N, 2), got {p.shape}")
    d = p[..., None, :] - lm
    return np.hypot(d[..., 0], d[..., 1])


class cWorld:  # noqa: N801 - the name the lab uses throughout
    """The cyclic landmark world of lab 03.

    Parameters
    ----------
    landmarks : array_like, shape (K, 2), optional
        Landmark positions; default :data:`LANDMARKS`
        ``[[20, 20], [80, 80], [20, 80], [80, 20]]``.
    size : float, optional
        Side of the square world (default 100). Every landmark must lie in
        ``[0, size)``.

    Attributes
    ----------
    landmarks : numpy.ndarray, shape (K, 2)
        A private copy of the landmark positions.
    size : float
        Side of the world.

    Examples
    --------
    >>> world = cWorld()
    >>> world.landmarks.shape
    (4, 2)
    """

    def __init__(self, landmarks=None, size: float = WORLD_SIZE):
        self.size = check_positive("size", size)
        lm = LANDMARKS if landmarks is None else landmarks
        lm = as_array("landmarks", lm, ndim=2, finite=True).copy()
        if lm.shape[1] != 2 or lm.shape[0] == 0:
            raise ValueError(f"landmarks must have shape (K, 2) with K >= 1, got {lm.shape}")
        if np.any(lm < 0) or np.any(lm >= self.size):
            raise ValueError(
                f"landmarks must lie in [0, size) = [0, {self.size:g}), got {lm.tolist()}"
            )
        self.landmarks = lm

    def __repr__(self) -> str:
        return f"cWorld(size={self.size:g}, landmarks={self.landmarks.tolist()})"

    def plot(self, ax=None):
        """Draw the world's square and its landmarks.

        Parameters
        ----------
        ax : matplotlib.axes.Axes, optional
            Axes to draw on; a new square figure when omitted.

        Returns
        -------
        matplotlib.axes.Axes
        """
        from robolab.plotting.core import new_axes, plot_landmarks

        if ax is None:
            ax = new_axes("cWorld: the cyclic landmark world", figsize=(6.0, 6.0))
        plot_landmarks(self.landmarks, ax, color="tab:red", label="landmarks")
        ax.set_xlim(0, self.size)
        ax.set_ylim(0, self.size)
        ax.set_aspect("equal", adjustable="box")
        if not ax.get_xlabel():
            ax.set_xlabel("x [m]")
        if not ax.get_ylabel():
            ax.set_ylabel("y [m]")
        return ax


class cRobot:  # noqa: N801 - the name the lab uses throughout
    """A robot in :class:`cWorld` with noisy motion and a noisy range sensor.

    The robot starts at a uniformly random pose (as in the MATLAB constructor)
    and without noise; use :meth:`set` and :meth:`set_noise`.

    Parameters
    ----------
    rng : numpy.random.Generator, optional
        Source of every random number the robot draws (initial pose, motion
        and sensor noise). Default ``np.random.default_rng()`` (unseeded).
    size : float, optional
        Side of the cyclic world (default 100); must match the world it senses.

    Attributes
    ----------
    x, y : float
        Position in ``[0, size)``.
    theta : float
        Heading in ``[-pi, pi)`` (robolab's convention; the MATLAB version uses ``[0, 2 pi)``).
    forward_noise, turn_noise, sense_noise : float
        Standard deviations of the translation, rotation and range noise.
    """

    def __init__(self, rng: np.random.Generator | None = None, size: float = WORLD_SIZE):
        if rng is None:
            rng = np.random.default_rng()
        self.rng = check_rng(rng)
        self.size = check_positive("size", size)
        self.x = float(rng.uniform(0.0, self.size))
        self.y = float(rng.uniform(0.0, self.size))
        self.theta = wrap_angle(rng.uniform(-np.pi, np.pi))
        self.forward_noise = 0.0
        self.turn_noise = 0.0
        self.sense_noise = 0.0

    def __repr__(self) -> str:
        return f"cRobot(x={self.x:.3f}, y={self.y:.3f}, theta={self.theta:.4f})"

    @property
    def pose(self) -> np.ndarray:
        """The pose ``(x, y, theta)`` as a new float array of shape (3,)."""
        return np.array([self.x, self.y, self.theta])

    def set(self, x, y, theta):
        """Place the robot.

        Parameters
        ----------
        x, y : float
            Position, each in ``[0, size)``.
        theta : float
            Heading in radians (any finite value; stored wrapped to ``[-pi, pi)``).

        Returns
        -------
        cRobot
            ``self``, so calls can be chained.

        Raises
        ------
        ValueError
            When ``x`` or ``y`` is outside ``[0, size)`` or a value is not finite.
        """
        vals = {}
        for name, v in (("x", x), ("y", y), ("theta", theta)):
            vals[name] = check_finite(name, v)
        for name in ("x", "y"):
            if not 0.0 <= vals[name] < self.size:
                raise ValueError(f"{name} must be in [0, {self.size:g}), got {vals[name]!r}")
        self.x, self.y = vals["x"], vals["y"]
        self.theta = wrap_angle(vals["theta"])
        return self

    def set_noise(self, forward_noise, turn_noise, sense_noise):
        """Set the noise standard deviations (each finite and >= 0).

        Parameters
        ----------
        forward_noise : float
            Standard deviation of the translation noise.
        turn_noise : float
            Standard deviation of the rotation noise [rad].
        sense_noise : float
            Standard deviation of each range measurement.

        Returns
        -------
        cRobot
            ``self``.
        """
        self.forward_noise = check_positive("forward_noise", forward_noise, allow_zero=True)
        self.turn_noise = check_positive("turn_noise", turn_noise, allow_zero=True)
        self.sense_noise = check_positive("sense_noise", sense_noise, allow_zero=True)
        return self

    def move(self, u_rotation, u_translation):
        """Rotate, then translate along the new heading, with noise (lab 03, section b).

        .. math::

            \\theta' &= \\mathrm{wrap}(\\theta + u_{rot} + \\varepsilon_\\theta),
                \\quad \\varepsilon_\\theta \\sim \\mathcal N(0, \\sigma_{turn}^2) \\\\
            d &= u_{trans} + \\varepsilon_d,
                \\quad \\varepsilon_d \\sim \\mathcal N(0, \\sigma_{fwd}^2) \\\\
            x' &= (x + d \\cos\\theta') \\bmod \\text{size}, \\qquad
            y' = (y + d \\sin\\theta') \\bmod \\text{size}

        A single forward-noise sample ``eps_d`` moves the robot along its heading.
        The MATLAB version draws two (one for x, one for y), which moves it off its
        heading: robolab fixes that. The turn noise is drawn first, then the
        forward noise, both from ``self.rng``.

        Parameters
        ----------
        u_rotation : float
            Commanded rotation [rad].
        u_translation : float
            Commanded forward translation.

        Returns
        -------
        cRobot
            ``self``.
        """
        u_rot = check_finite("u_rotation", u_rotation)
        u_trans = check_finite("u_translation", u_translation)
        theta = wrap_angle(self.theta + u_rot + self.rng.normal(0.0, self.turn_noise))
        d = u_trans + self.rng.normal(0.0, self.forward_noise)
        self.theta = theta
        self.x = wrap_position(self.x + d * np.cos(theta), self.size)
        self.y = wrap_position(self.y + d * np.sin(theta), self.size)
        return self

    def sense(self, world: cWorld) -> np.ndarray:
        """Noisy ranges to every landmark of ``world`` (lab 03, section c).

        .. math:: z_k = \\sqrt{(x - l_{k,x})^2 + (y - l_{k,y})^2} + \\varepsilon_k,
                  \\quad \\varepsilon_k \\sim \\mathcal N(0, \\sigma_{sense}^2) \\text{ i.i.d.}

        Distances are plain Euclidean, without the cyclic wrap.

        Parameters
        ----------
        world : cWorld
            The world whose landmarks are measured.

        Returns
        -------
        numpy.ndarray, shape (K,)
            One range per landmark, in the order of ``world.landmarks``.
        """
        lm = _landmarks_of(world)
        r = landmark_ranges([self.x, self.y], lm)
        return r + self.rng.normal(0.0, self.sense_noise, size=r.shape)

    def measurement_probability(self, measured, world: cWorld) -> float:
        """Likelihood of measured ranges at this robot's pose (lab 03, section d).

        .. math:: p(z \\mid x, m) = \\prod_k \\mathcal N(z_k;\\ \\hat r_k(x), \\sigma_{sense}^2)

        with ``r_hat_k`` the Euclidean range to landmark ``k`` (Probabilistic
        Robotics, Table 6.4's landmark model restricted to range; the
        measurements are independent given the pose, so their joint density is
        the product).

        Parameters
        ----------
        measured : array_like, shape (K,)
            Measured ranges, one per landmark of ``world``.
        world : cWorld
            The world whose landmarks were measured.

        Returns
        -------
        float
            The density; requires ``sense_noise > 0``.
        """
        lm = _landmarks_of(world)
        z = as_array("measured", measured, shape=(lm.shape[0],), finite=True)
        sigma = check_positive("sense_noise", self.sense_noise)
        err = landmark_ranges([self.x, self.y], lm) - z
        dens = np.exp(-0.5 * (err / sigma) ** 2) / (np.sqrt(2.0 * np.pi) * sigma)
        return float(np.prod(dens))

    def plot(self, ax=None, color="tab:blue", label=None, length: float = 6.0):
        """Draw the robot as a circle with a line along its heading.

        Parameters
        ----------
        ax : matplotlib.axes.Axes, optional
            Axes to draw on; a new figure when omitted.
        color : str
            Matplotlib colour.
        label : str, optional
            Legend label.
        length : float
            Length of the heading line.

        Returns
        -------
        matplotlib.axes.Axes
        """
        from robolab.plotting.core import new_axes

        if ax is None:
            ax = new_axes("cRobot", figsize=(6.0, 6.0))
        ax.plot(
            [self.x], [self.y], "o", color=color, markersize=10, markerfacecolor="none", label=label
        )
        ax.plot(
            [self.x, self.x + length * np.cos(self.theta)],
            [self.y, self.y + length * np.sin(self.theta)],
            "-",
            color=color,
            linewidth=2,
        )
        return ax




def _landmarks_of(world) -> np.ndarray:
    if not isinstance(world, cWorld):
        raise TypeError(f"world must be a cWorld, got {type(world).__name__}")
    return world.landmarks
