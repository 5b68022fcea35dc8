"""The simulated laser: beam-model parameters and scan noise."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robolab.validation import as_array, check_positive


@dataclass(frozen=True)
class LaserModel:
    """A planar laser scanner and the noise of the beam model (Table 6.1).

    Each reading comes from one of four causes, drawn per beam with
    probabilities ``z_hit, z_short, z_max, z_rand`` (normalized to sum 1):

    - hit: the ray-cast range plus Gaussian noise ``N(0, sigma_hit**2)``,
      clipped to ``[range_min, range_max]``;
    - short: an unexpected obstacle, exponential with rate ``lambda_short``
      truncated to ``[0, z*]`` (``z*`` the true range, or ``range_max`` when
      nothing is in range); a short reading may fall below ``range_min`` and
      must then be discarded, as sensor_msgs/LaserScan says;
    - max: a sensor failure (glass, black surfaces), reported as exactly
      ``range_max``: the point mass ``p_max`` of the beam model;
    - rand: uniform on ``[0, range_max)``.

    A beam whose ray meets no obstacle within ``range_max`` and whose cause is
    a hit reports ``+inf`` (REP-117: "no object detected in range"). So "no
    return" appears in two encodings, ``range_max`` (failures) and ``inf``
    (nothing in range), and readers must handle both explicitly.

    Parameters
    ----------
    n_beams : int
        Number of beams; beam ``i`` points at ``angle_min + i * angle_increment``
        relative to the laser's heading, with ``angle_increment = 2 pi / n_beams``
        when ``fov`` is the full circle.
    angle_min : float
        Angle of the first beam, radians.
    fov : float
        Angular span covered by the beams, radians (``2 pi``: full circle).
    range_min, range_max : float
        Valid range interval, metres.
    sigma_hit, lambda_short : float
        Hit noise standard deviation (m) and short-reading rate (1/m).
    z_hit, z_short, z_max, z_rand : float
        Mixing weights of the four causes.
    offset : (x, y, theta)
        Pose of ``base_laser_link`` in ``base_link``.
    """

    n_beams: int = 360
    angle_min: float = -np.pi
    fov: float = 2.0 * np.pi
    range_min: float = 0.05
    range_max: float = 8.0
    sigma_hit: float = 0.02
    lambda_short: float = 0.5
    z_hit: float = 0.91
    z_short: float = 0.04
    z_max: float = 0.03
    z_rand: float = 0.02
    offset: tuple[float, float, float] = (0.10, 0.0, 0.0)

    def __post_init__(self):
        if int(self.n_beams) != self.n_beams or self.n_beams < 1:
            raise ValueError(f"n_beams must be a positive integer, got {self.n_beams!r}")
        check_positive("range_max", self.range_max)
        check_positive("range_min", self.range_min, allow_zero=True)
        if self.range_min >= self.range_max:
            raise ValueError(f"range_min ({self.range_min}) must be < range_max ({self.range_max})")
        check_positive("fov", self.fov)
        check_positive("sigma_hit", self.sigma_hit, allow_zero=True)
        check_positive("lambda_short", self.lambda_short)
        weights = np.array([self.z_hit, self.z_short, self.z_max, self.z_rand], dtype=float)
        if np.any(weights < 0) or weights.sum() <= 0:
            raise ValueError(
                f"z_hit, z_short, z_max, z_rand must be >= 0 with a positive sum, got {weights}"
            )
        as_array("offset", self.offset, shape=(3,), finite=True)

    @property
    def angle_increment(self) -> float:
        """Angle between neighbouring beams, radians."""
        full = np.isclose(self.fov, 2.0 * np.pi)
        return float(self.fov / (self.n_beams if full or self.n_beams == 1 else self.n_beams - 1))

    @property
    def angles(self) -> np.ndarray:
        """Beam angles relative to the laser's heading, shape ``(n_beams,)``."""
        return self.angle_min + self.angle_increment * np.arange(self.n_beams)

    @property
    def weights(self) -> np.ndarray:
        """``(z_hit, z_short, z_max, z_rand)`` normalized to sum 1."""
        w = np.array([self.z_hit, self.z_short, self.z_max, self.z_rand], dtype=float)
        return w / w.sum()


def scan_noise(
    true_ranges, laser: LaserModel, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """Apply the beam-model noise of :class:`LaserModel` to ray-cast ranges.

    Parameters
    ----------
    true_ranges : array_like (T, B)
        Noise-free ranges; values ``>= laser.range_max`` mean nothing in range.
    laser : LaserModel
        The noise parameters.
    rng : numpy.random.Generator
        Four independent streams are spawned from it (cause, hit noise, short
        readings, random readings), each drawn as one ``(T, B)`` block, so a
        shorter run reproduces the start of a longer one.

    Returns
    -------
    ranges : ndarray (T, B) float32
        Noisy readings: finite values, ``range_max`` (failures) or ``+inf``
        (nothing in range).
    kind : ndarray (T, B) int8
        0 hit, 1 short, 2 max-range failure, 3 random.
    """
    z = as_array("true_ranges", true_ranges, ndim=2, nonnegative=True)
    r_max = laser.range_max
    g_kind, g_hit, g_short, g_rand = rng.spawn(4)
    u = g_kind.random(z.shape)
    kind = np.searchsorted(np.cumsum(laser.weights)[:-1], u, side="right").astype(np.int8)
    nothing = z >= r_max
    zc = np.minimum(z, r_max)
    hit = np.clip(zc + laser.sigma_hit * g_hit.standard_normal(z.shape), laser.range_min, r_max)
    hit[nothing] = np.inf
    # exponential truncated to [0, z*] by inverting its CDF
    lam = laser.lambda_short
    short = -np.log1p(-g_short.random(z.shape) * -np.expm1(-lam * zc)) / lam
    rand = g_rand.random(z.shape) * r_max
    out = np.choose(kind, [hit, short, np.full(z.shape, r_max), rand])
    return out.astype(np.float32), kind
