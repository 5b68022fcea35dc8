"""Visible checks for lab 03, the landmark particle filter.

Quick and friendly: shapes, one worked example and one invariant per exercise.
The hidden tests are stronger (moments, oracles, end-to-end accuracy).
"""

from __future__ import annotations

import numpy as np

from robolab.checks.base import CheckFailed, check, expect_close, expect_shape

__all__ = [
    "check_move_particles",
    "check_measurement_probability",
    "check_low_variance_resample",
    "check_particle_filter",
]

_LANDMARKS = np.array([[20.0, 20.0], [80.0, 80.0], [20.0, 80.0], [80.0, 20.0]])


@check
def check_move_particles(move_particles):
    """Worked examples without noise, the cyclic wrap, and a noisy cloud's spread."""
    particles = np.array([[10.0, 15.0, 0.0], [50.0, 50.0, 0.0]])
    out = expect_shape(
        "move_particles(2 particles) shape",
        move_particles(particles, np.pi / 2, 10.0, 0.0, 0.0, np.random.default_rng(0)),
        (2, 3),
    )
    expect_close(
        "rotate by pi/2, then move 10 along the NEW heading (no noise)",
        out,
        [[10.0, 25.0, np.pi / 2], [50.0, 60.0, np.pi / 2]],
        atol=1e-9,
    )
    out = np.asarray(
        move_particles(np.array([[98.0, 50.0, 0.0]]), 0.0, 5.0, 0.0, 0.0, np.random.default_rng(0)),
        dtype=float,
    )
    expect_close(
        "the world is cyclic: from x = 98, moving 5 ends at x = 3",
        out[0, :2],
        [3.0, 50.0],
        atol=1e-9,
    )
    out = np.asarray(
        move_particles(np.array([[50.0, 50.0, 3.0]]), 1.0, 0.0, 0.0, 0.0, np.random.default_rng(0)),
        dtype=float,
    )
    expect_close("heading 3 + 1 rad wraps to [-pi, pi)", out[0, 2], 4.0 - 2 * np.pi, atol=1e-9)
    cloud = np.asarray(
        move_particles(
            np.tile([50.0, 50.0, 0.0], (4000, 1)), 0.0, 10.0, 2.0, 0.0, np.random.default_rng(1)
        ),
        dtype=float,
    )
    sd = cloud[:, 0].std()
    if not 1.7 < sd < 2.3:
        raise CheckFailed(f"with forward_noise = 2 the x spread should be about 2, got {sd:.2f}")


@check
def check_measurement_probability(measurement_probability):
    """A worked example (the true pose gets the peak density) and the output shape."""
    particles = np.array([[50.0, 50.0, 0.0], [20.0, 20.0, 1.0], [50.0, 50.0, 2.0]])
    z = np.hypot(50.0 - _LANDMARKS[:, 0], 50.0 - _LANDMARKS[:, 1])  # exact ranges from (50, 50)
    w = expect_shape(
        "measurement_probability(3 particles) shape",
        measurement_probability(z, particles, _LANDMARKS, 5.0),
        (3,),
    )
    peak = (1.0 / (np.sqrt(2 * np.pi) * 5.0)) ** 4
    expect_close(
        "weight of the pose that measured exactly these ranges: (1/(sqrt(2 pi) 5))^4", w[0], peak
    )
    expect_close("the heading must not change the weight", w[2], w[0])
    if not 0 <= w[1] < w[0]:
        raise CheckFailed(
            f"a particle far from the measurement should weigh less: got {w[1]:.3g} vs {w[0]:.3g}"
        )


@check
def check_low_variance_resample(low_variance_resample):
    """Equal weights keep each particle once; a dominant one takes over; all-zero weights raise."""
    particles = np.column_stack([np.arange(6.0), np.arange(6.0) * 10, np.zeros(6)])
    out = expect_shape(
        "low_variance_resample(6 particles) shape",
        low_variance_resample(particles, np.ones(6), np.random.default_rng(0)),
        (6, 3),
    )
    if sorted(out[:, 0].tolist()) != list(range(6)):
        raise CheckFailed(
            f"equal weights must keep every particle exactly once, got particles {out[:, 0]}"
        )
    out = np.asarray(
        low_variance_resample(particles, np.array([0, 0, 5.0, 0, 0, 0]), np.random.default_rng(0)),
        dtype=float,
    )
    expect_close(
        "unnormalized weights [0, 0, 5, 0, 0, 0] select particle 2 six times",
        out[:, 0],
        np.full(6, 2.0),
    )
    try:
        low_variance_resample(particles, np.zeros(6), np.random.default_rng(0))
    except ValueError:
        pass
    else:
        raise CheckFailed("all-zero weights should raise ValueError (see the docstring)")


@check
def check_particle_filter(particle_filter):
    """Output shape and start; with a noise-free model the estimate follows the command."""
    controls = np.array([[0.0, 20.0], [np.pi / 2, 10.0]])
    truth = np.array([[10.0, 15.0], [30.0, 15.0], [30.0, 25.0]])
    z = np.hypot(truth[1:, None, 0] - _LANDMARKS[:, 0], truth[1:, None, 1] - _LANDMARKS[:, 1])
    noise = {"forward_noise": 0.0, "turn_noise": 0.0, "sensor_noise": 5.0}
    path = expect_shape(
        "particle_filter path shape (T + 1, 2)",
        particle_filter(_LANDMARKS, controls, z, 100, noise, np.random.default_rng(0)),
        (3, 2),
    )
    expect_close(
        "noise-free model: the estimated path is the command path from (10, 15)",
        path,
        truth,
        atol=1e-6,
    )
    lost = z.copy()
    lost[0] = 1e4  # ranges of 10 km: every weight of step 1 is 0
    path = np.asarray(
        particle_filter(_LANDMARKS, controls, lost, 100, noise, np.random.default_rng(0)),
        dtype=float,
    )
    if path.shape != (3, 2) or not np.all(np.isfinite(path)):
        raise CheckFailed(
            "a step whose every weight is 0 (ranges of 10 km): expected a finite (3, 2) path, "
            f"got {path}: keep the predicted particles for that step (uniform weights)"
        )
