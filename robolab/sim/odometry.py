"""Simulated wheel odometry: noise parameters and drifting odometry from the true path."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robolab.geometry import relative, wrap_angle
from robolab.validation import as_poses, check_positive


@dataclass(frozen=True)
class OdometryNoise:
    """Drift of wheel odometry: random motion-model noise plus calibration bias.

    Random part (Table 5.6 of Probabilistic Robotics, applied to the reported
    motion of each odometry step, ``1 / odom_rate`` seconds), with variances

    - ``rot1``: ``alpha1 * rot1**2 + alpha2 * trans**2``
    - ``trans``: ``alpha3 * trans**2 + alpha4 * (rot1**2 + rot2**2)``
    - ``rot2``: ``alpha1 * rot2**2 + alpha2 * trans**2``

    Systematic part: the odometry integrates wheel travel with wrong wheel
    radii and a wrong wheel base. With true wheel travel ``d_l, d_r`` the
    encoders report ``scale_left * d_l`` and ``scale_right * d_r``, and the
    heading change is computed with the wheel base ``wheel_base * wheel_base_scale``.
    ``scale_right != scale_left`` bends straight lines (a slow heading drift);
    ``wheel_base_scale != 1`` over- or under-states every turn.

    Parameters
    ----------
    alpha1, alpha2, alpha3, alpha4 : float
        Motion-model noise (rad^2/rad^2, rad^2/m^2, m^2/m^2, m^2/rad^2).
    wheel_base : float
        Distance between the wheels, metres.
    scale_left, scale_right : float
        Reported / true travel of each wheel.
    wheel_base_scale : float
        Wheel base assumed by the odometry / true wheel base.
    """

    alpha1: float = 0.02
    alpha2: float = 0.01
    alpha3: float = 0.02
    alpha4: float = 0.005
    wheel_base: float = 0.35
    scale_left: float = 1.0
    scale_right: float = 1.002
    wheel_base_scale: float = 0.99

    def __post_init__(self):
        for name in ("alpha1", "alpha2", "alpha3", "alpha4"):
            check_positive(name, getattr(self, name), allow_zero=True)
        for name in ("wheel_base", "scale_left", "scale_right", "wheel_base_scale"):
            check_positive(name, getattr(self, name))


def odometry_from_truth(true_poses, noise: OdometryNoise, rng: np.random.Generator) -> np.ndarray:
    """Wheel odometry that drifts away from a true trajectory.

    The true relative motion between consecutive samples, decomposed as
    ``(rot1, trans, rot2)`` (Table 5.5), is distorted by the wheel calibration
    errors of ``noise`` and then perturbed with the motion-model noise of
    Table 5.6; the distorted steps are chained from ``(0, 0, 0)``.

    Parameters
    ----------
    true_poses : array_like (K, 3)
        Ground-truth poses at the odometry rate.
    noise : OdometryNoise
        Noise and bias parameters (per step).
    rng : numpy.random.Generator
        Source of the noise; ``3 (K - 1)`` standard normals are drawn in one
        call, so a shorter run reproduces the start of a longer one.

    Returns
    -------
    ndarray (K, 3)
        Odometry poses ``odom -> base_link``; the first is ``(0, 0, 0)``.
    """
    p = as_poses("true_poses", true_poses)
    if not isinstance(noise, OdometryNoise):
        raise TypeError(f"noise must be an OdometryNoise, got {type(noise).__name__}")
    rel = relative(p[:-1], p[1:])
    trans = np.hypot(rel[:, 0], rel[:, 1])
    rot1 = np.where(trans > 1e-9, np.arctan2(rel[:, 1], rel[:, 0]), 0.0)
    dth = rel[:, 2]
    rot2 = wrap_angle(dth - rot1)
    # systematic: wheel travel measured with wrong radii, heading with a wrong wheel base
    half_b = 0.5 * noise.wheel_base
    d_r = noise.scale_right * (trans + dth * half_b)
    d_l = noise.scale_left * (trans - dth * half_b)
    trans_b = 0.5 * (d_r + d_l)
    dth_b = (d_r - d_l) / (noise.wheel_base * noise.wheel_base_scale)
    rot1_b = rot1 + 0.5 * (dth_b - dth)
    rot2_b = rot2 + 0.5 * (dth_b - dth)
    # random: Table 5.6 variances
    e = rng.standard_normal((len(rel), 3))
    a1, a2, a3, a4 = noise.alpha1, noise.alpha2, noise.alpha3, noise.alpha4
    r1 = rot1_b + e[:, 0] * np.sqrt(a1 * rot1_b**2 + a2 * trans_b**2)
    tr = trans_b + e[:, 1] * np.sqrt(a3 * trans_b**2 + a4 * (rot1_b**2 + rot2_b**2))
    r2 = rot2_b + e[:, 2] * np.sqrt(a1 * rot2_b**2 + a2 * trans_b**2)
    # chain the steps from the origin (vectorized: headings are a cumulative sum)
    heading = np.concatenate([[0.0], np.cumsum(r1 + r2)])
    out = np.zeros((len(p), 3))
    out[1:, 0] = np.cumsum(tr * np.cos(heading[:-1] + r1))
    out[1:, 1] = np.cumsum(tr * np.sin(heading[:-1] + r1))
    out[:, 2] = wrap_angle(heading)
    return out
