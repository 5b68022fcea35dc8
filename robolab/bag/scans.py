"""Laser scans of one topic as numpy arrays."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robolab.geometry import (
    transform_points,
)
from robolab.validation import as_array


@dataclass(frozen=True, eq=False)
class Scans:
    """All ``sensor_msgs/LaserScan`` messages of one topic.

    Attributes
    ----------
    stamps : numpy.ndarray, shape (T,)
        Header stamps, seconds.
    ranges : numpy.ndarray, shape (T, B)
        Ranges in metres, raw as recorded (0, inf and NaN included).
    angles : numpy.ndarray, shape (B,)
        Beam angles in the laser frame, ``angle_min + i * angle_increment``, radians
        (not wrapped: a 361-beam scan from -pi to pi keeps both ends).
    range_min, range_max : float
        Valid range interval, metres.
    frame_id : str
        The laser's frame (``header.frame_id``).
    """

    stamps: np.ndarray
    ranges: np.ndarray
    angles: np.ndarray
    range_min: float
    range_max: float
    frame_id: str

    def __post_init__(self):
        stamps = as_array("stamps", self.stamps, ndim=1, finite=True)
        ranges = as_array("ranges", self.ranges, ndim=2)
        angles = as_array("angles", self.angles, ndim=1, finite=True)
        if ranges.shape != (stamps.size, angles.size):
            raise ValueError(
                f"ranges must have shape (T, B) = ({stamps.size}, {angles.size}) to match stamps "
                f"and angles, "
                f"got {ranges.shape}"
            )
        rmin, rmax = float(self.range_min), float(self.range_max)
        if not (np.isfinite(rmin) and np.isfinite(rmax) and 0 <= rmin < rmax):
            raise ValueError(
                f"range_min and range_max must be finite with 0 <= range_min < range_max, "
                f"got {rmin}, {rmax}"
            )
        object.__setattr__(self, "stamps", stamps)
        object.__setattr__(self, "ranges", ranges)
        object.__setattr__(self, "angles", angles)
        object.__setattr__(self, "range_min", rmin)
        object.__setattr__(self, "range_max", rmax)

    def __len__(self) -> int:
        return self.stamps.size

    @property
    def beams(self) -> int:
        """Number of beams per scan ``B``."""
        return self.angles.size

    @property
    def valid(self) -> np.ndarray:
        """``(T, B)`` bool: real returns (finite, > 0, within ``[range_min, range_max)``).

        0, inf and NaN mean "no return" and are never turned into hits. A reading
        of exactly ``range_max`` is a max-range reading (a failed return, the beam
        model's ``p_max``), not an obstacle at ``range_max``: AMCL and gmapping
        skip it too.
        """
        r = self.ranges
        with np.errstate(invalid="ignore"):
            return np.isfinite(r) & (r > 0) & (r >= self.range_min) & (r < self.range_max)

    def endpoints(self, i: int, laser_pose=(0.0, 0.0, 0.0)) -> np.ndarray:
        """Endpoints of the valid beams of scan ``i``.

        Parameters
        ----------
        i : int
            Scan index (negative indices count from the end).
        laser_pose : array_like, shape (3,)
            Pose of the laser in some frame, e.g. ``compose(robot_pose, laser_pose_in_base(...))``
            for the map frame. Default: the laser frame itself.

        Returns
        -------
        numpy.ndarray, shape (P, 2)
            ``(x, y)`` of each valid beam's endpoint in the frame ``laser_pose`` is given in.
        """
        if not isinstance(i, (int, np.integer)) or not -len(self) <= i < len(self):
            raise IndexError(
                f"i must be an integer scan index in [-{len(self)}, {len(self)}), got {i!r}"
            )
        pose = as_array("laser_pose", laser_pose, shape=(3,), finite=True)
        ok = self.valid[i]
        r, a = self.ranges[i, ok], self.angles[ok]
        return transform_points(np.stack([r * np.cos(a), r * np.sin(a)], -1), pose)
