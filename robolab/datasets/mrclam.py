"""The UTIAS Multi-Robot Cooperative Localization and Mapping data sets (MRCLAM 1-9).

A data set folder (``MRCLAM_Dataset1/``) holds whitespace-separated ``.dat`` text
files whose ``#`` lines are comments:

``Barcodes.dat``
    ``subject barcode``: subjects 1-5 are the robots, 6-20 the landmarks; each
    carries a barcode, and the measurement files name what was seen by *barcode*.
``Landmark_Groundtruth.dat``
    ``subject x y x_sd y_sd`` (metres).
``Robot<i>_Groundtruth.dat``
    ``time x y theta`` (Vicon, seconds, metres, radians).
``Robot<i>_Odometry.dat``
    ``time v w``: forward and angular velocity commands (m/s, rad/s).
``Robot<i>_Measurement.dat``
    ``time barcode range bearing``: range and bearing to a landmark or another robot.

The three streams run on their own clocks. :func:`read_mrclam` aligns them on one
time grid of step ``dt`` (0.02 s, the data set's own sample script's choice) from
the latest first sample to the earliest last sample: the odometry command in force
at each step (zero-order hold: the last command at or before it), ground truth
interpolated at each step, and each measurement assigned to the step nearest its
time. Barcodes are mapped to subjects, and landmark subjects to rows ``0..K-1`` of
:attr:`MrclamRun.landmarks`; measurements of robots, or of barcodes the table lacks,
are kept apart (:attr:`MrclamRun.other_measurements`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from robolab.bag import PoseTrack
from robolab.datasets.textlog import data_folder, text_lines
from robolab.validation import check_count, check_positive

__all__ = ["MrclamError", "MrclamRun", "read_dat", "read_mrclam", "DT"]

#: The time step of the data set's sample script, seconds.
DT = 0.02


class MrclamError(ValueError):
    """An MRCLAM file is missing columns or values, or the streams do not overlap in time."""


def read_dat(path, columns: int) -> np.ndarray:
    """A ``.dat`` file as a float ``(N, columns)`` array (``#`` comment lines skipped)."""
    path = Path(path)
    rows = []
    for lineno, line in text_lines(path, MrclamError, "MRCLAM data"):
        tok = line.split("#", 1)[0].split()
        if not tok:
            continue
        if len(tok) != columns:
            raise MrclamError(f"{path}:{lineno}: expected {columns} columns, got {len(tok)}: {tok}")
        try:
            rows.append([float(v) for v in tok])
        except ValueError as exc:
            raise MrclamError(f"{path}:{lineno}: {exc}") from exc
    a = np.array(rows, dtype=float).reshape(-1, columns)
    if not np.isfinite(a).all():
        raise MrclamError(f"{path}: values must be finite")
    return a


@dataclass(frozen=True, eq=False)
class MrclamRun:
    """One robot's run, aligned on a time grid.

    Attributes
    ----------
    t : numpy.ndarray, shape (S,)
        Step times, seconds (the data set's clock).
    commands : numpy.ndarray, shape (S, 2)
        ``(v, w)`` in force at each step.
    truth : numpy.ndarray, shape (S, 3)
        Ground-truth pose at each step.
    measurements : numpy.ndarray, shape (M, 4)
        Landmark measurements ``[step, range, bearing, landmark row]``, by step.
    other_measurements : numpy.ndarray, shape (M', 4)
        ``[step, range, bearing, barcode]`` of robots and unknown barcodes.
    landmark_subjects : numpy.ndarray of int, shape (K,)
        The subject number of each landmark row.
    landmarks : numpy.ndarray, shape (K, 2)
        True landmark positions; ``landmark_sd`` (K, 2) their standard deviations.
    barcodes : dict of int to int
        Barcode -> subject.
    """

    t: np.ndarray
    commands: np.ndarray
    truth: np.ndarray
    measurements: np.ndarray
    other_measurements: np.ndarray
    landmark_subjects: np.ndarray
    landmarks: np.ndarray
    landmark_sd: np.ndarray
    barcodes: dict

    @property
    def dt(self) -> float:
        """The step, seconds."""
        return float(self.t[1] - self.t[0]) if self.t.size > 1 else DT

    def __len__(self) -> int:
        return self.t.size

    def observations(self, step: int) -> np.ndarray:
        """Landmark measurements of one step as ``(k, 3)`` rows ``[range, bearing, row]``."""
        m = self.measurements
        lo, hi = np.searchsorted(m[:, 0], [step, step + 1])
        return m[lo:hi, 1:].copy()


def read_mrclam(folder, robot: int = 1, *, dt: float = DT) -> MrclamRun:
    """Read robot ``robot`` of an MRCLAM data set folder and align its streams (module docstring).

    Raises
    ------
    FileNotFoundError
        A file of the folder is missing.
    MrclamError
        Malformed files, or streams that do not overlap in time.
    """
    folder = data_folder(folder, MrclamError, "MRCLAM data set")
    robot = check_count("robot", robot)
    dt = check_positive("dt", dt)
    codes = read_dat(folder / "Barcodes.dat", 2).astype(np.int64)
    lm = read_dat(folder / "Landmark_Groundtruth.dat", 5)
    gt = read_dat(folder / f"Robot{robot}_Groundtruth.dat", 4)
    odo = read_dat(folder / f"Robot{robot}_Odometry.dat", 3)
    meas = read_dat(folder / f"Robot{robot}_Measurement.dat", 4)
    for name, a in (("Groundtruth", gt), ("Odometry", odo)):
        if a.shape[0] < 2:
            raise MrclamError(f"{folder}: Robot{robot}_{name}.dat needs at least two rows")
    barcodes = {int(b): int(s) for s, b in codes}
    start = max(gt[0, 0], odo[0, 0])
    stop = min(gt[-1, 0], odo[-1, 0])
    if stop <= start:
        raise MrclamError(
            f"{folder}: robot {robot}'s ground truth ({gt[0, 0]}..{gt[-1, 0]} s) and odometry "
            f"({odo[0, 0]}..{odo[-1, 0]} s) do not overlap"
        )
    t = start + dt * np.arange(int(np.floor((stop - start) / dt + 1e-9)) + 1)
    # zero-order hold: the last command at or before each step (sorted by time first)
    odo = odo[np.argsort(odo[:, 0], kind="stable")]
    held = np.clip(np.searchsorted(odo[:, 0], t + 1e-9, side="right") - 1, 0, len(odo) - 1)
    commands = odo[held, 1:3]
    truth = PoseTrack(gt[:, 0], gt[:, 1:4]).at(t)
    # measurements: nearest step, inside the grid; barcodes -> subjects -> landmark rows
    step = np.rint((meas[:, 0] - start) / dt).astype(np.int64)
    inside = (step >= 0) & (step < t.size)
    meas, step = meas[inside], step[inside]
    subjects = np.array([barcodes.get(int(b), -1) for b in meas[:, 1]], dtype=np.int64)
    lm_subjects = lm[:, 0].astype(np.int64)
    row_of = {int(s): k for k, s in enumerate(lm_subjects)}
    rows = np.array([row_of.get(int(s), -1) for s in subjects], dtype=np.int64)
    is_lm = rows >= 0
    order = np.argsort(step, kind="stable")
    keep, other = order[is_lm[order]], order[~is_lm[order]]
    return MrclamRun(
        t=t,
        commands=commands,
        truth=truth,
        measurements=np.column_stack([step[keep], meas[keep, 2], meas[keep, 3], rows[keep]]),
        other_measurements=np.column_stack(
            [step[other], meas[other, 2], meas[other, 3], meas[other, 1]]
        ),
        landmark_subjects=lm_subjects,
        landmarks=lm[:, 1:3],
        landmark_sd=lm[:, 3:5],
        barcodes=barcodes,
    )
