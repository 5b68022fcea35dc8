r"""Lab 02, beam model: the measurement model of a range finder, and the maze challenge.

Reference solutions for ``notebooks/02_beam_model.ipynb`` (seed 001, the
measurement-model lab; seed 000, section 2.2, AMCL's ``BeamModel``;
Probabilistic Robotics, section 6.3, Table 6.1).

One beam ``k`` of a scan reports a range :math:`z^k \in [0, z_{max}]`. Given the
pose :math:`x_t` and the map :math:`m`, ray casting predicts the true range
:math:`z^{k*}` (:func:`robolab.raycast.cast_rays`), and the beam model explains
the reading as a mixture of four sources of error (eq. 6.12):

.. math::

    p(z^k \mid x_t, m) = w_{hit}\, p_{hit} + w_{short}\, p_{short}
                        + w_{max}\, p_{max} + w_{rand}\, p_{rand},
    \qquad w_{hit} + w_{short} + w_{max} + w_{rand} = 1,

where the book writes the weights :math:`z_{hit}, z_{short}, z_{max}, z_{rand}`.
Beams are assumed independent given the pose, so a scan's likelihood is the
product over beams (Table 6.1, line 7), best computed as a sum of logs.

The parameter dictionary
------------------------
The book uses :math:`z_{max}` both for the sensor's range and for the weight of
the max-range component. Here the ``params`` dict keeps the book's names for
the four **weights** and names the range ``"max_range"``:

==================  =========================================================
key                 meaning
==================  =========================================================
``"z_hit"``         weight of :func:`p_hit` (>= 0)
``"z_short"``       weight of :func:`p_short` (>= 0)
``"z_max"``         weight of :func:`p_max` (>= 0) -- a weight, not a range
``"z_rand"``        weight of :func:`p_rand` (>= 0)
``"sigma_hit"``     standard deviation of the measurement noise, metres (> 0)
``"lambda_short"``  rate of the exponential of unexpected objects, 1/metres (> 0)
``"max_range"``     the sensor's maximum range :math:`z_{max}`, metres (> 0)
==================  =========================================================

The four weights must sum to 1 (within 1e-9). The density functions
:func:`p_hit`, :func:`p_max` and :func:`p_rand` take the *range* as their
``z_max`` argument, as in the seed.

Max-range readings
------------------
:func:`p_max` is a point mass at exactly :math:`z_{max}`. A real sensor reports
"no return" as ``inf``, ``NaN``, 0 or a value ``>= range_max``
(sensor_msgs/LaserScan); such readings must be mapped to exactly ``max_range``
before they reach the model. Non-finite readings raise ValueError here: they
are never silently turned into hits.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import NamedTuple

import numpy as np
from scipy.special import erf

from robolab.geometry import wrap_angle
from robolab.maps import OccupancyGrid
from robolab.raycast import cast_rays
from robolab.validation import as_array, check_positive

__all__ = [
    "p_hit",
    "p_short",
    "p_max",
    "p_rand",
    "beam_range_finder_model",
    "pose_likelihood_map",
]

#: The keys of a beam model ``params`` dict: the four mixture weights ...
WEIGHT_KEYS = ("z_hit", "z_short", "z_max", "z_rand")
#: ... and the three other parameters.
SHAPE_KEYS = ("sigma_hit", "lambda_short", "max_range")
#: The mixture weights must sum to 1 within this tolerance.
WEIGHT_SUM_ATOL = 1e-9
#: Beam directions closer than this (radians) are cast once in pose_likelihood_map.
ANGLE_QUANTUM = 1e-9
#: beam_range_finder_model(log=True) recomputes a beam in log space when its mixture is below this.
LOG_SPACE_BELOW = 1e-280
#: erf(x) rounds to exactly 1.0 in float64 for x >= this (scipy: from 5.93 on).
ERF_IS_ONE = 6.0
#: A hit term below ``HIT_NEGLIGIBLE`` times the reading's own terms (``z_max p_max + z_rand
#: p_rand``) is lost when they are added, even divided by its normalizer (>= 0.5 there):
#: twice it is below half a unit in the last place of the sum.
HIT_NEGLIGIBLE = 2.0**-56
#: beam_range_finder_model evaluates about this many beams at a time (temporaries of 64 KiB).
#: Larger blocks run the model alone up to 10 % faster, but after a ray cast of as many beams
#: the heap then grows past malloc's trim threshold and is handed back on every call: 2^15
#: page-faulted 632 times per cast + model of 152 500 beams (11 with 2^13), 1.1x slower.
BLOCK_BEAMS = 1 << 13
#: pose_likelihood_map evaluates about this many beams at a time (bounds memory).
CHUNK_BEAMS = 1 << 20


def _ranges(name: str, value) -> np.ndarray:
    """``value`` as a finite float array (any shape); non-finite readings are refused."""
    arr = as_array(name, value)
    if not np.all(np.isfinite(arr)):
        raise ValueError(
            f"{name} must be finite: map 'no return' readings (inf, NaN) to exactly the "
            "maximum range before evaluating the model"
        )
    return arr


def _broadcast(z: np.ndarray, z_star: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Broadcast readings and expected ranges against each other, or say why not."""
    try:
        return np.broadcast_arrays(z, z_star)
    except ValueError:
        raise ValueError(
            f"z and z_star must have broadcastable shapes, got {z.shape} and {z_star.shape}"
        ) from None


def _check_expected(z_star: np.ndarray, z_max: float, name: str = "z_star") -> None:
    """Expected ranges come from ray casting: they lie in [0, z_max]."""
    if np.any((z_star < 0) | (z_star > z_max)):
        raise ValueError(
            f"{name} must lie in [0, z_max] = [0, {z_max:g}] (a ray-cast range), "
            f"got values in [{z_star.min():g}, {z_star.max():g}]"
        )


def _out(arr: np.ndarray):
    """A 0-d result as a Python float, anything else unchanged."""
    return float(arr) if arr.ndim == 0 else arr


def _hit_mass(z_star: np.ndarray, z_max: float, sigma: float) -> np.ndarray:
    """``Phi((z_max - z*) / sigma) - Phi(-z* / sigma)``, accurate for any sigma.

    As ``(erf(b / sqrt 2) + erf(a / sqrt 2)) / 2`` with ``a = z* / sigma >= 0`` and
    ``b = (z_max - z*) / sigma >= 0``: the terms never cancel, even when
    ``sigma >> z_max`` makes both tiny (``ndtr(b) - ndtr(-a)`` would round to 0 there,
    and the normalizer to inf). ``erf`` is the costly part of the whole model and rounds
    to exactly 1.0 from ``ERF_IS_ONE`` on, so it is evaluated only for the ranges
    within ``ERF_IS_ONE * sqrt(2) * sigma`` of 0 or of ``z_max``.
    """
    scale = sigma * np.sqrt(2.0)
    halves = []
    for arg in (z_star / scale, (z_max - z_star) / scale):
        e = np.ones(np.shape(arg))
        near = arg < ERF_IS_ONE
        e[near] = erf(arg[near])
        halves.append(e)
    return 0.5 * (halves[0] + halves[1])


def p_hit(z, z_star, z_max, sigma_hit):
    r"""Correct range with local measurement noise: a Gaussian truncated to :math:`[0, z_{max}]`.

    Probabilistic Robotics, eq. 6.4-6.6:

    .. math::

        p_{hit}(z \mid x_t, m) =
        \begin{cases}
            \eta\, \mathcal{N}(z;\, z^*,\, \sigma_{hit}^2) & 0 \le z \le z_{max}\\
            0 & \text{otherwise}
        \end{cases}
        \qquad
        \mathcal{N}(z; z^*, \sigma^2) = \frac{1}{\sqrt{2\pi\sigma^2}}
            e^{-\frac{(z - z^*)^2}{2\sigma^2}},

    with the normalizer computed exactly through the standard normal CDF
    :math:`\Phi`:

    .. math::

        \eta^{-1} = \int_0^{z_{max}} \mathcal{N}(z; z^*, \sigma_{hit}^2)\, dz
                  = \Phi\!\left(\frac{z_{max} - z^*}{\sigma_{hit}}\right)
                    - \Phi\!\left(\frac{-z^*}{\sigma_{hit}}\right).

    Since :math:`z^* \in [0, z_{max}]`, :math:`\eta^{-1} > 0`, so the result is
    finite; it integrates to 1 over :math:`[0, z_{max}]`.

    Parameters
    ----------
    z : float or array_like
        Measured range(s), metres; finite. Readings outside :math:`[0, z_{max}]`
        get density 0.
    z_star : float or array_like
        Expected range(s) from ray casting, metres, in :math:`[0, z_{max}]`;
        broadcasts against ``z``.
    z_max : float
        The sensor's maximum range, metres (> 0).
    sigma_hit : float
        Standard deviation of the measurement noise, metres (> 0).

    Returns
    -------
    float or numpy.ndarray
        The density (1/metres), with the broadcast shape of ``z`` and ``z_star``
        (a float for scalar input).

    Raises
    ------
    ValueError
        ``z_max`` or ``sigma_hit`` not finite and > 0, ``z``/``z_star`` not
        finite, ``z_star`` outside :math:`[0, z_{max}]`, shapes that do not broadcast.
    TypeError
        A non-numeric argument.
    """
    z_max = check_positive("z_max", z_max)
    sigma_hit = check_positive("sigma_hit", sigma_hit)
    z, z_star = _broadcast(_ranges("z", z), _ranges("z_star", z_star))
    _check_expected(z_star, z_max)
    mass = _hit_mass(z_star, z_max, sigma_hit)
    u = (z - z_star) / sigma_hit
    with np.errstate(over="ignore", divide="ignore"):
        gauss = np.exp(-0.5 * u * u) / (sigma_hit * np.sqrt(2.0 * np.pi))
        out = np.where((z >= 0.0) & (z <= z_max), gauss / mass, 0.0)
    if not np.all(np.isfinite(out)):
        raise ValueError(
            f"sigma_hit={sigma_hit!r} is too small: the Gaussian density overflows float64"
        )
    return _out(out)


def _short_mass(z_star: np.ndarray, lambda_short: float) -> tuple[np.ndarray, np.ndarray]:
    """``1 - exp(-lambda z*)`` and where it is usable: ``eta * lambda`` stays finite."""
    mass = -np.expm1(-lambda_short * z_star)  # accurate for small lambda z*
    return mass, mass > lambda_short / np.finfo(float).max


def p_short(z, z_star, lambda_short):
    r"""Unexpected objects in front of the expected one: an exponential on :math:`[0, z^*]`.

    Probabilistic Robotics, eq. 6.7-6.9:

    .. math::

        p_{short}(z \mid x_t, m) =
        \begin{cases}
            \eta\, \lambda_{short}\, e^{-\lambda_{short} z} & 0 \le z \le z^*\\
            0 & \text{otherwise}
        \end{cases}
        \qquad
        \eta = \frac{1}{1 - e^{-\lambda_{short} z^*}},

    since :math:`\int_0^{z^*} \lambda e^{-\lambda z} dz = 1 - e^{-\lambda z^*}`.
    The normalizer is evaluated as ``-1 / expm1(-lambda_short * z_star)``, which
    is accurate for small :math:`\lambda_{short} z^*`.

    **The limit** :math:`z^* = 0`: the sensor touches the obstacle (ray casting
    returns 0 for a pose inside an obstacle) and there is no room for an
    unexpected object in front of it. The interval :math:`[0, z^*]` is a single
    point, and ``p_short`` is defined to be 0 for every ``z`` (the pointwise
    limit of the density for every :math:`z > 0`), never NaN. The same holds
    whenever :math:`z^*` is so small (about 1e-308 m) that the density
    :math:`\eta \lambda_{short}` would overflow to infinity.

    Parameters
    ----------
    z : float or array_like
        Measured range(s), metres; finite.
    z_star : float or array_like
        Expected range(s), metres (>= 0); broadcasts against ``z``.
    lambda_short : float
        Rate of the exponential, 1/metres (> 0).

    Returns
    -------
    float or numpy.ndarray
        The density (1/metres), with the broadcast shape of ``z`` and ``z_star``.

    Raises
    ------
    ValueError
        ``lambda_short`` not finite and > 0, ``z``/``z_star`` not finite,
        ``z_star`` negative, shapes that do not broadcast.
    TypeError
        A non-numeric argument.
    """
    lambda_short = check_positive("lambda_short", lambda_short)
    z, z_star = _broadcast(_ranges("z", z), _ranges("z_star", z_star))
    if np.any(z_star < 0):
        raise ValueError(f"z_star must be >= 0 (a ray-cast range), got minimum {z_star.min():g}")
    mass, ok = _short_mass(z_star, lambda_short)
    eta = np.divide(1.0, mass, out=np.zeros_like(mass), where=ok)
    inside = ok & (z >= 0.0) & (z <= z_star)
    return _out(np.where(inside, eta * lambda_short * np.exp(-lambda_short * z), 0.0))


def p_max(z, z_max):
    r"""Failures reported as a max-range reading: the point mass at :math:`z_{max}`.

    Probabilistic Robotics, eq. 6.10:

    .. math::

        p_{max}(z \mid x_t, m) = I(z = z_{max}) =
        \begin{cases} 1 & z = z_{max}\\ 0 & \text{otherwise.} \end{cases}

    This is a probability (of the discrete event "the reading is exactly
    :math:`z_{max}`"), not a density. The comparison is **exact**: a real
    sensor's "no return" readings (``inf``, ``NaN``, values ``>= range_max``)
    must be mapped to exactly ``z_max`` beforehand; a reading of
    ``z_max - 1e-12`` is not a max-range reading.

    Parameters
    ----------
    z : float or array_like
        Measured range(s), metres; finite.
    z_max : float
        The sensor's maximum range, metres (> 0).

    Returns
    -------
    float or numpy.ndarray
        1.0 where ``z == z_max``, else 0.0; the shape of ``z``.

    Raises
    ------
    ValueError
        ``z`` not finite, ``z_max`` not finite and > 0.
    TypeError
        A non-numeric argument.
    """
    z_max = check_positive("z_max", z_max)
    z = _ranges("z", z)
    return _out((z == z_max).astype(float))


def p_rand(z, z_max):
    r"""Random, unexplained measurements: uniform on :math:`[0, z_{max})`.

    Probabilistic Robotics, eq. 6.11:

    .. math::

        p_{rand}(z \mid x_t, m) =
        \begin{cases} \dfrac{1}{z_{max}} & 0 \le z < z_{max}\\ 0 & \text{otherwise.} \end{cases}

    The interval is half-open: the reading :math:`z_{max}` itself belongs to
    :func:`p_max`.

    Parameters
    ----------
    z : float or array_like
        Measured range(s), metres; finite.
    z_max : float
        The sensor's maximum range, metres (> 0).

    Returns
    -------
    float or numpy.ndarray
        The density (1/metres), the shape of ``z``.

    Raises
    ------
    ValueError
        ``z`` not finite, ``z_max`` not finite and > 0.
    TypeError
        A non-numeric argument.
    """
    z_max = check_positive("z_max", z_max)
    z = _ranges("z", z)
    return _out(np.where((z >= 0.0) & (z < z_max), 1.0 / z_max, 0.0))


def _check_params(params) -> dict[str, float]:
    """Validate a beam model ``params`` dict (see the module docstring) and return it as floats."""
    if not isinstance(params, Mapping):
        raise TypeError(
            f"params must be a dict with keys {WEIGHT_KEYS + SHAPE_KEYS}, "
            f"got {type(params).__name__}"
        )
    keys = set(params)
    missing = [k for k in WEIGHT_KEYS + SHAPE_KEYS if k not in keys]
    unknown = sorted(str(k) for k in keys - set(WEIGHT_KEYS + SHAPE_KEYS))
    if missing or unknown:
        raise ValueError(
            f"params must have exactly the keys {list(WEIGHT_KEYS + SHAPE_KEYS)}"
            + (f"; missing {missing}" if missing else "")
            + (f"; unknown {unknown}" if unknown else "")
        )
    out = {k: check_positive(f"params['{k}']", params[k], allow_zero=True) for k in WEIGHT_KEYS}
    total = sum(out[k] for k in WEIGHT_KEYS)
    if abs(total - 1.0) > WEIGHT_SUM_ATOL:
        raise ValueError(
            "the mixture weights params['z_hit'] + ['z_short'] + ['z_max'] + ['z_rand'] "
            f"must sum to 1, got {total!r}"
        )
    for k in SHAPE_KEYS:
        out[k] = check_positive(f"params['{k}']", params[k])
    return out


def _log_mixture(z: np.ndarray, z_star: np.ndarray, prm: dict[str, float]) -> np.ndarray:
    r"""Per-beam :math:`\log p(z \mid z^*)` of the mixture, computed from log-components.

    :math:`\log \sum_k w_k p_k = m + \log \sum_k e^{\log w_k + \log p_k - m}` with
    :math:`m` the largest term (log-sum-exp), so that even a Gaussian term that
    underflows in linear space (readings many sigma away) keeps its exact log.
    """
    zmax, sigma, lam = prm["max_range"], prm["sigma_hit"], prm["lambda_short"]
    neg_inf = -np.inf
    with np.errstate(divide="ignore"):
        log_w = {k: np.log(prm[k]) for k in WEIGHT_KEYS}
        # log p_hit: log eta - log(sigma sqrt(2 pi)) - u^2 / 2 on [0, zmax].
        log_norm = np.log(_hit_mass(z_star, zmax, sigma))
        u = (z - z_star) / sigma
        in_range = (z >= 0.0) & (z <= zmax)
        hit = np.where(
            in_range, -0.5 * u * u - log_norm - np.log(sigma * np.sqrt(2.0 * np.pi)), neg_inf
        )
        # log p_short: log eta + log lambda - lambda z on [0, z*], none when z* = 0.
        mass, ok = _short_mass(z_star, lam)
        short_ok = ok & (z >= 0.0) & (z <= z_star)
        short = np.where(short_ok, np.log(lam) - lam * z - np.log(np.where(ok, mass, 1.0)), neg_inf)
        terms = np.stack(
            [
                hit + log_w["z_hit"],
                short + log_w["z_short"],
                np.where(z == zmax, log_w["z_max"], neg_inf),
                np.where((z >= 0.0) & (z < zmax), log_w["z_rand"] - np.log(zmax), neg_inf),
            ]
        )
    top = terms.max(axis=0)
    shift = np.where(np.isfinite(top), top, 0.0)
    with np.errstate(divide="ignore"):
        return shift + np.log(np.exp(terms - shift).sum(axis=0))


def _erf_window(z_max: float, sigma: float) -> tuple[float, float]:
    """``(lo, hi)`` such that :func:`_hit_mass` is exactly 1 for every ``lo <= z* <= hi``.

    Both arguments of its ``erf``, ``z* / (sigma sqrt 2)`` and ``(z_max - z*) / (sigma sqrt 2)``,
    are then ``>= ERF_IS_ONE`` in float64: rounding is monotonic, and the ends are moved
    until their own arguments are. Empty (``lo > hi``) when sigma is large next to ``z_max``.
    """
    scale = sigma * np.sqrt(2.0)
    lo = ERF_IS_ONE * scale
    with np.errstate(over="ignore", invalid="ignore"):  # inf and NaN end the loops
        while lo / scale < ERF_IS_ONE:  # (false for NaN: scale = inf leaves lo = inf)
            lo = np.nextafter(lo, np.inf)
        hi = z_max - lo
        while (z_max - hi) / scale < ERF_IS_ONE:
            hi = np.nextafter(hi, -np.inf)
    return float(lo), float(hi)


def _reading_terms(z: np.ndarray, prm: dict[str, float]) -> tuple[np.ndarray, ...]:
    """The mixture's terms that depend on the reading alone.

    ``flat = z_max p_max + z_rand p_rand``, ``flat * HIT_NEGLIGIBLE``, and ``z_short``
    times the numerator ``lambda e^{-lambda z}`` of ``p_short``.
    """
    zmax, lam = prm["max_range"], prm["lambda_short"]
    flat = np.where(z == zmax, prm["z_max"], 0.0)
    flat = flat + np.where(z < zmax, prm["z_rand"] / zmax, 0.0)
    return flat, flat * HIT_NEGLIGIBLE, prm["z_short"] * lam * np.exp(-lam * z)


class _Shared(NamedTuple):
    """What every block of poses of one :func:`beam_range_finder_model` call shares."""

    #: ``z_hit / (sigma_hit sqrt(2 pi))``, the weighted Gaussian's peak.
    peak: float
    #: :func:`_erf_window`: the hit mass is 1 for ``lo <= z* <= hi``.
    lo: float
    hi: float
    #: When all poses share one scan: the scan and its :func:`_reading_terms`, repeated over
    #: the rows of a block (C-contiguous, so that no operation broadcasts); else None.
    tiles: tuple[np.ndarray, ...] | None
    #: A block's worth of memory for the mixture, reused by every block (not allocated afresh).
    scratch: np.ndarray


def _divide_by_hit_mass(p, z_star, z_max: float, sigma: float, lo: float, hi: float, floor):
    """``p /= _hit_mass(z_star, z_max, sigma)`` on flat arrays, with erf only where it matters.

    The mass is exactly 1 for ``lo <= z* <= hi`` (:func:`_erf_window`), so only the beams
    outside are divided. When those two ranges do not overlap (``lo <= hi``), a beam
    needs at most one of the two erf, the other being 1.0: ``0.5 (erf(a) + 1.0)``, the
    same operations on the same numbers as :func:`_hit_mass`. That mass is at least 0.5,
    so a beam with ``p < floor`` (the reading's own terms times ``HIT_NEGLIGIBLE``,
    added to ``p`` next) gives the same sum divided or not, and is left as it is.
    """
    if lo > hi:  # sigma large next to z_max: every beam may need both, the mass be tiny
        p /= _hit_mass(z_star, z_max, sigma)
        return
    scale = sigma * np.sqrt(2.0)
    matters = p >= floor
    low = np.flatnonzero((z_star < lo) & matters)
    high = np.flatnonzero((z_star > hi) & matters)
    for near, arg in ((low, z_star.take(low) / scale), (high, (z_max - z_star.take(high)) / scale)):
        mass = erf(arg, out=arg)
        mass += 1.0
        mass *= 0.5
        np.divide.at(p, near, mass)  # p[near] /= mass, without a gathered copy of p[near]


def _mixture(z: np.ndarray, z_star: np.ndarray, prm: dict[str, float], shared: _Shared):
    r"""Per-beam mixture :math:`p^k` (Table 6.1, lines 5-6) of validated, broadcast (N, B) arrays.

    The same sum as ``z_hit * p_hit + z_short * p_short + z_max * p_max + z_rand * p_rand``,
    arranged for speed (it is the inner loop of localization), with the same float
    operations on every beam: terms that depend on the reading alone (``p_max``,
    ``p_rand``, the exponential of ``p_short``) are computed once per reading, not once
    per pose; the ``p_hit`` normalizer only where it is not exactly 1 (``z*`` within
    ``ERF_IS_ONE sqrt(2) sigma`` of 0 or of ``z_max``), and the ``p_short`` one only where
    ``z <= z*`` (elsewhere the term is 0); everything else in place, on one array.
    """
    zmax, sigma, lam = prm["max_range"], prm["sigma_hit"], prm["lambda_short"]
    if shared.tiles is not None:
        z, flat, floor, short_coef = (tile[: len(z_star)] for tile in shared.tiles)
    else:
        flat, floor, short_coef = _reading_terms(z, prm)
    p = np.subtract(z, z_star, out=shared.scratch[: z_star.size].reshape(z_star.shape))
    p /= sigma
    p *= p
    p *= -0.5
    np.exp(p, out=p)
    p *= shared.peak
    flat_p = p.reshape(-1)  # the scratch is C-contiguous: a view
    zs = z_star.reshape(-1)
    _divide_by_hit_mass(flat_p, zs, zmax, sigma, shared.lo, shared.hi, floor.reshape(-1))
    p += flat
    # p_short: its normalizer 1 / (1 - e^{-lambda z*}) only where the reading is short.
    short = np.flatnonzero(z <= z_star)
    mass, ok = _short_mass(zs.take(short), lam)
    coef = short_coef.reshape(-1).take(short)
    term = coef / mass if ok.all() else np.where(ok, coef / np.where(ok, mass, 1.0), 0.0)
    np.add.at(flat_p, short, term)
    return p


def _check_scan_shapes(z: np.ndarray, z_star: np.ndarray) -> None:
    if z.ndim not in (1, 2) or z_star.ndim not in (1, 2):
        raise ValueError(
            "z must have shape (B,) or (N, B) and z_star (B,) or (N, B), "
            f"got {z.shape} and {z_star.shape}"
        )
    if z.shape[-1] != z_star.shape[-1] or (
        z.ndim == 2 and z_star.ndim == 2 and z.shape != z_star.shape
    ):
        raise ValueError(
            "z and z_star must have the same number of beams (and poses): "
            f"got shapes {z.shape} and {z_star.shape}"
        )


def beam_range_finder_model(z, z_star, params, log=False):
    r"""Likelihood of a whole scan under the beam model (Probabilistic Robotics, Table 6.1).

    For each beam :math:`k` (Table 6.1, lines 5-6)

    .. math::

        p^k = z_{hit}\, p_{hit}(z^k) + z_{short}\, p_{short}(z^k)
            + z_{max}\, p_{max}(z^k) + z_{rand}\, p_{rand}(z^k),

    and, beams being independent given the pose (line 7),

    .. math::

        q = \prod_{k=1}^{K} p^k, \qquad \log q = \sum_{k=1}^{K} \log p^k.

    Each :math:`p^k` is a density (per metre): above 1 near a good match
    (up to :math:`z_{hit} / (\sigma_{hit}\sqrt{2\pi})`), far below 1 a few
    :math:`\sigma_{hit}` off. The product of a few hundred of them leaves the
    range of doubles (:math:`10^{-308}` to :math:`10^{308}`) and becomes 0.0 or
    inf; ``log=True`` returns :math:`\log q` as a sum of per-beam logs, so it
    stays finite and exact for any number of beams. A beam whose mixture itself
    is near underflow (below about :math:`10^{-280}`: possible only with
    :math:`z_{rand} = 0`, a reading far out in the Gaussian's tail) is
    recomputed with log-sum-exp from the log of each component, so even its
    log is exact rather than ``-inf``.

    Parameters
    ----------
    z : array_like, shape (B,) or (N, B)
        Measured ranges, metres, in :math:`[0, \text{max\_range}]`; max-range
        readings exactly ``params["max_range"]`` (see the module docstring).
    z_star : array_like, shape (B,) or (N, B)
        Expected ranges from ray casting, metres, in :math:`[0, \text{max\_range}]`;
        ``(N, B)`` evaluates one scan ``z`` (B,) against N poses, or N scans
        against N poses when ``z`` is ``(N, B)`` too.
    params : dict
        ``{"z_hit", "z_short", "z_max", "z_rand"}``: mixture weights, each
        >= 0, summing to 1; ``"sigma_hit"`` (m), ``"lambda_short"`` (1/m),
        ``"max_range"`` (m), each > 0. Exactly these keys.
    log : bool
        Return :math:`\log q` instead of :math:`q`.

    Returns
    -------
    float or numpy.ndarray, shape (N,)
        :math:`q` (or :math:`\log q`), a float for a single pose. It is 0
        (``-inf`` in log form) only when some beam is impossible under the
        model, e.g. with ``z_rand = 0``; never NaN.

    Raises
    ------
    ValueError
        Bad ``params`` (missing/unknown keys, negative weights, weights not
        summing to 1, non-positive sigma/lambda/range), ``z``/``z_star`` not
        finite or outside :math:`[0, \text{max\_range}]`, shapes other than
        ``(B,)``/``(N, B)`` or with different numbers of beams or poses.
    TypeError
        ``params`` not a dict, non-numeric input.
    """
    prm = _check_params(params)
    zmax = prm["max_range"]
    # The checks of _ranges and _check_expected, by two reductions when the input passes
    # them (NaN fails a comparison with its min or max); else run to raise their errors.
    z = as_array("z", z)
    z_ok = _within(z, zmax)
    if not z_ok:
        z = _ranges("z", z)
    z_star = as_array("z_star", z_star)
    z_star_ok = _within(z_star, zmax)
    if not z_star_ok:
        z_star = _ranges("z_star", z_star)
    _check_scan_shapes(z, z_star)
    if not z_ok and np.any((z < 0) | (z > zmax)):
        raise ValueError(
            f"z must lie in [0, max_range] = [0, {zmax:g}]: map 'no return' readings to exactly "
            f"max_range, got values in [{z.min():g}, {z.max():g}]"
        )
    if not z_star_ok:
        _check_expected(z_star, zmax)
    sigma = prm["sigma_hit"]
    if not np.isfinite(1.0 / (sigma * np.sqrt(2.0 * np.pi))):
        raise ValueError(
            f"sigma_hit={sigma!r} is too small: the Gaussian density overflows float64"
        )
    z, z_star = np.broadcast_arrays(z, z_star)
    single = z.ndim == 1
    if single:
        z, z_star = z[None], z_star[None]
    n, b = z.shape
    # Blocks of poses: temporaries small enough to be reused from the heap, not mapped
    # afresh (and page-faulted in) for every operation.
    per = max(1, BLOCK_BEAMS // max(1, b))
    shared = _Shared(
        prm["z_hit"] / (sigma * np.sqrt(2.0 * np.pi)),
        *_erf_window(zmax, sigma),
        # A reading shared by all poses is a stride-0 view: its own terms are computed once.
        _tiles(z[:per], prm) if z.strides[0] == 0 and n else None,
        np.empty(min(per, n) * b),
    )
    out = np.empty(n)
    for i in range(0, n, per):
        out[i : i + per] = _scan_likelihood(z[i : i + per], z_star[i : i + per], prm, log, shared)
    return float(out[0]) if single else out


def _tiles(z: np.ndarray, prm: dict[str, float]):
    """A block of rows of one shared scan, contiguous, and its :func:`_reading_terms`."""
    row = z[:1]
    return tuple(np.repeat(t, len(z), axis=0) for t in (row, *_reading_terms(row, prm)))


def _within(arr: np.ndarray, top: float) -> bool:
    """Whether every entry of ``arr`` is finite and in ``[0, top]`` (False for NaN)."""
    return arr.size == 0 or bool(arr.min() >= 0.0 and arr.max() <= top)


def _scan_likelihood(z, z_star, prm: dict[str, float], log: bool, shared: _Shared):
    """Table 6.1 on validated, broadcast (N, B) arrays: the product (or sum of logs) over beams."""
    p = _mixture(z, z_star, prm, shared)  # lines 5-6, for every beam and pose at once
    if not log:
        return np.prod(p, axis=-1)  # line 7
    if p.size == 0 or p.min() >= LOG_SPACE_BELOW:
        return np.log(p, out=p).sum(axis=-1)
    with np.errstate(divide="ignore"):
        log_p = np.log(p)
    # Beams whose mixture is (near) underflow -- only possible without z_rand, or far
    # in a Gaussian tail -- are recomputed exactly in log space.
    tiny = p < LOG_SPACE_BELOW
    log_p[tiny] = _log_mixture(z[tiny], z_star[tiny], prm)
    return log_p.sum(axis=-1)


def pose_likelihood_map(scan, grid, beam_angles, params, positions, headings):
    r"""Log-likelihood of one scan at every combination of candidate position and heading.

    For position :math:`p` and heading :math:`\theta_h`, the pose is
    :math:`x = (p_x, p_y, \theta_h)`; ray casting on ``grid`` gives the expected
    ranges :math:`z^{k*}(x)` of the beams at :math:`\theta_h + \alpha_k` and

    .. math::

        L[p, h] = \log p(z \mid x, m) = \sum_k \log p(z^k \mid z^{k*}(x))

    (:func:`beam_range_finder_model` with ``log=True``, Table 6.1). A heat map of
    :math:`\max_h L[p, h]` answers "where in the map could the robot be?".

    All poses are cast at once with :func:`robolab.raycast.cast_rays`. The ray
    from position :math:`p` in absolute direction :math:`\phi` does not depend
    on which heading and beam produced :math:`\phi`, so each distinct direction
    :math:`\operatorname{wrap}(\theta_h + \alpha_k)` (to within 1e-9 rad) is cast
    once per position: with headings on the beams' angular lattice (e.g. 60
    beams over 360 degrees and headings in multiples of 6 degrees) that is
    ``B`` rays per position instead of ``H * B``.

    A position inside an obstacle gets :math:`z^* = 0` for every beam (the
    ray-casting convention) and hence a very low, finite score.

    Parameters
    ----------
    scan : array_like, shape (B,)
        Measured ranges, metres, in ``[0, params["max_range"]]``.
    grid : OccupancyGrid
        The map.
    beam_angles : array_like, shape (B,)
        Beam angles relative to the robot's heading, radians.
    params : dict
        Beam model parameters, see :func:`beam_range_finder_model`.
    positions : array_like, shape (P, 2)
        Candidate positions ``(x, y)``, metres, world frame.
    headings : array_like, shape (H,)
        Candidate headings, radians.

    Returns
    -------
    numpy.ndarray, shape (P, H)
        ``L[p, h]``, the log-likelihood of the scan at pose
        ``(positions[p, 0], positions[p, 1], headings[h])``.

    Raises
    ------
    ValueError
        Shapes other than stated, non-finite values, ranges outside
        ``[0, max_range]``, bad ``params``.
    TypeError
        ``grid`` not an OccupancyGrid, ``params`` not a dict, non-numeric input.
    """
    prm = _check_params(params)
    if not isinstance(grid, OccupancyGrid):
        raise TypeError(f"grid must be an OccupancyGrid, got {type(grid).__name__}")
    scan = _ranges("scan", as_array("scan", scan, ndim=1))
    beam_angles = as_array("beam_angles", beam_angles, shape=(scan.shape[0],), finite=True)
    positions = as_array("positions", positions, ndim=2, finite=True)
    if positions.shape[1] != 2:
        raise ValueError(f"positions must have shape (P, 2), got {positions.shape}")
    headings = as_array("headings", headings, ndim=1, finite=True)
    n_pos, n_head, n_beam = positions.shape[0], headings.shape[0], scan.shape[0]
    out = np.empty((n_pos, n_head))
    if out.size == 0:
        return out
    # Distinct absolute beam directions, each cast once per position.
    directions = wrap_angle(headings[:, None] + beam_angles[None, :]).reshape(-1)
    keys, inverse = np.unique(np.round(directions / ANGLE_QUANTUM), return_inverse=True)
    unique_angles = keys * ANGLE_QUANTUM
    per = max(1, CHUNK_BEAMS // max(1, n_head * n_beam))
    for i in range(0, n_pos, per):
        chunk = positions[i : i + per]
        poses = np.column_stack([chunk, np.zeros(len(chunk))])
        z_star = cast_rays(grid, poses, unique_angles, prm["max_range"])[:, inverse]
        out[i : i + per] = np.reshape(
            beam_range_finder_model(scan, z_star.reshape(-1, n_beam), prm, log=True),
            (len(chunk), n_head),
        )
    return out
