"""Pose tracks: odometry, ground truth or one TF edge, with interpolation."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from robolab.geometry import (
    angle_diff,
    wrap_angle,
)
from robolab.validation import as_array

# A transform whose samples differ by less than this (metres / radians) is rigid.
_RIGID_TOL = 1e-6


@dataclass(frozen=True, eq=False)
class PoseTrack:
    """A time series of planar poses: odometry, ground truth, or one TF edge.

    Attributes
    ----------
    stamps : numpy.ndarray, shape (T,)
        Seconds, as recorded (not necessarily unique or sorted).
    poses : numpy.ndarray, shape (T, 3)
        ``(x, y, theta)`` of ``child_frame_id`` in ``frame_id``; theta wrapped to [-pi, pi).
    frame_id : str
        Parent frame.
    child_frame_id : str
        Child frame (empty for a PoseStamped, whose child is implicit).

    Notes
    -----
    :meth:`at` interpolates on the samples sorted by time, with samples that share
    a stamp replaced by their *average* (mean x, y; circular mean of theta). The
    Olin ``/map_pose`` has about a quarter of its stamps carrying two camera
    detections 1.5 cm apart; averaging them is the least-squares estimate, where
    keeping either one would be an arbitrary choice.
    """

    stamps: np.ndarray
    poses: np.ndarray
    frame_id: str = ""
    child_frame_id: str = ""

    def __post_init__(self):
        stamps = as_array("stamps", self.stamps, ndim=1, finite=True)
        poses = as_array("poses", self.poses, shape=(stamps.size, 3), finite=True).copy()
        if stamps.size == 0:
            raise ValueError("stamps must hold at least one sample, got 0")
        poses[:, 2] = wrap_angle(poses[:, 2])
        object.__setattr__(self, "stamps", stamps)
        object.__setattr__(self, "poses", poses)

    def __len__(self) -> int:
        return self.stamps.size

    @property
    def x(self) -> np.ndarray:
        """``(T,)`` x, metres."""
        return self.poses[:, 0]

    @property
    def y(self) -> np.ndarray:
        """``(T,)`` y, metres."""
        return self.poses[:, 1]

    @property
    def theta(self) -> np.ndarray:
        """``(T,)`` heading, radians in [-pi, pi)."""
        return self.poses[:, 2]

    @property
    def is_constant(self) -> bool:
        """True when every sample equals the first (a rigid mount published repeatedly)."""
        d = self.poses - self.poses[0]
        return bool(
            np.all(np.abs(d[:, :2]) < _RIGID_TOL)
            and np.all(np.abs(angle_diff(self.poses[:, 2], self.poses[0, 2])) < _RIGID_TOL)
        )

    @cached_property
    def _knots(self) -> tuple[np.ndarray, np.ndarray]:
        """Sorted unique stamps and their (averaged) poses, the interpolation knots."""
        order = np.argsort(self.stamps, kind="stable")
        s, p = self.stamps[order], self.poses[order]
        u, start, counts = np.unique(s, return_index=True, return_counts=True)
        if u.size == s.size:
            return s, p
        xy = np.add.reduceat(p[:, :2], start, axis=0) / counts[:, None]
        th = np.arctan2(
            np.add.reduceat(np.sin(p[:, 2]), start), np.add.reduceat(np.cos(p[:, 2]), start)
        )
        return u, np.column_stack([xy, wrap_angle(th)])

    def at(self, t) -> np.ndarray:
        """Pose at time(s) ``t`` by linear interpolation (shortest arc for theta).

        Parameters
        ----------
        t : float or array_like, shape (K,)
            Seconds, within ``[stamps.min(), stamps.max()]``.

        Returns
        -------
        numpy.ndarray, shape (3,) for a scalar ``t``, (K, 3) otherwise

        Raises
        ------
        ValueError
            If any ``t`` lies outside the recorded time range: the track does not
            extrapolate silently.
        """
        tt = as_array("t", t, ndim=(0, 1), finite=True)
        scalar = tt.ndim == 0
        tt = np.atleast_1d(tt)
        s, p = self._knots
        outside = (tt < s[0]) | (tt > s[-1])
        if np.any(outside):
            raise ValueError(
                f"t = {tt[outside][0]!r} s is outside the time range [{s[0]!r}, {s[-1]!r}] s of "
                f"{self.frame_id or '?'} -> {self.child_frame_id or '?'}; "
                "PoseTrack.at does not extrapolate"
            )
        if s.size == 1:
            out = np.repeat(p, tt.size, axis=0)
        else:
            i = np.clip(np.searchsorted(s, tt, side="right") - 1, 0, s.size - 2)
            f = (tt - s[i]) / (s[i + 1] - s[i])
            xy = p[i, :2] + f[:, None] * (p[i + 1, :2] - p[i, :2])
            th = wrap_angle(p[i, 2] + f * angle_diff(p[i + 1, 2], p[i, 2]))
            out = np.column_stack([xy, th])
        return out[0] if scalar else out

    #: The issue's name for :meth:`at`.
    pose_at = at
