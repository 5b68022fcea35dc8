"""Lets the library's unicycle step move the particles, then adds the noise.

class: delegation
"""

from robolab.fiducials import DT, sqrt_psd, unicycle
from robolab.geometry import wrap_angle
from robolab.validation import as_array, check_covariance, check_positive, check_rng
from solutions.fastslam import _poses


def predict_poses(poses, command, Q, rng, dt=DT):
    p = _poses(poses)
    u = as_array("command", command, shape=(2,), finite=True)
    q = check_covariance("Q", Q, 3, definite=False)
    check_rng(rng)
    dt = check_positive("dt", dt)
    out = unicycle(p, u, dt) + rng.standard_normal(p.shape) @ sqrt_psd(q).T
    out[:, 2] = wrap_angle(out[:, 2])
    return out
