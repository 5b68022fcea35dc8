"""The Freiburg Robot Mapping course format: ``world.dat`` and ``sensor_data.dat``.

``world.dat``
    One landmark a line: ``id x y`` (metres).
``sensor_data.dat``
    Time steps, each an ``ODOMETRY r1 t r2`` line (the odometry motion model's
    rotation, translation, rotation: radians and metres) followed by zero or more
    ``SENSOR id range bearing`` lines observed *after* that motion (known
    correspondences: ``id`` is a landmark of ``world.dat``).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from robolab.datasets.textlog import data_folder, text_lines

__all__ = ["FreiburgError", "FreiburgData", "read_world", "read_sensor_data", "read_freiburg"]


class FreiburgError(ValueError):
    """A line of a Freiburg course file is malformed (the message names file and line)."""


@dataclass(frozen=True, eq=False)
class FreiburgData:
    """A Freiburg run: landmarks, odometry and observations per step.

    Attributes
    ----------
    landmark_ids : numpy.ndarray of int, shape (K,)
        The ids of ``world.dat``, in file order (empty if no world file was read).
    landmarks : numpy.ndarray, shape (K, 2)
        Their true positions.
    odometry : numpy.ndarray, shape (T, 3)
        ``(r1, t, r2)`` of every step.
    observations : list of numpy.ndarray, each shape (k, 3)
        Step ``i``'s rows ``[range, bearing, id]`` (``k`` may be 0), with the ids
        of the file.
    """

    landmark_ids: np.ndarray
    landmarks: np.ndarray
    odometry: np.ndarray
    observations: list

    def __len__(self) -> int:
        return self.odometry.shape[0]

    def landmark_index(self, ids) -> np.ndarray:
        """Row of ``landmarks`` for each landmark id (ValueError for an id not in the world)."""
        ids = np.asarray(ids)
        order = np.argsort(self.landmark_ids)
        pos = np.searchsorted(self.landmark_ids, ids, sorter=order)
        pos = np.minimum(pos, max(len(order) - 1, 0))
        found = len(order) > 0 and np.all(self.landmark_ids[order[pos]] == ids)
        if not found:
            missing = sorted(set(np.ravel(ids).tolist()) - set(self.landmark_ids.tolist()))
            raise ValueError(f"landmark id(s) {missing} are not in world.dat")
        return order[pos]

    def indexed_observations(self, i: int) -> np.ndarray:
        """Step ``i``'s observations as ``[range, bearing, landmark row]`` (0-based rows)."""
        obs = self.observations[i].copy()
        if len(obs):
            obs[:, 2] = self.landmark_index(obs[:, 2].astype(np.int64))
        return obs


def _rows(path: Path):
    for lineno, line in text_lines(path, FreiburgError, "Freiburg data"):
        tok = line.split()
        if tok and not tok[0].startswith("#"):
            yield lineno, tok


def _floats(path, lineno, tok, n, what):
    if len(tok) != n:
        raise FreiburgError(f"{path}:{lineno}: {what} needs {n} fields, got {len(tok)}: {tok}")
    try:
        values = [float(v) for v in tok]
    except ValueError as exc:
        raise FreiburgError(f"{path}:{lineno}: {what}: {exc}") from exc
    if not np.all(np.isfinite(values)):
        raise FreiburgError(f"{path}:{lineno}: {what} must be finite, got {tok}")
    return values


def _landmark_id(path, lineno, value) -> int:
    if value != int(value):
        raise FreiburgError(f"{path}:{lineno}: a landmark id must be an integer, got {value}")
    return int(value)


def read_world(path) -> tuple[np.ndarray, np.ndarray]:
    """``world.dat`` as ``(ids (K,), positions (K, 2))``; ids must be unique integers."""
    path = Path(path)
    ids, xy = [], []
    for lineno, tok in _rows(path):
        i, x, y = _floats(path, lineno, tok, 3, "a landmark")
        ids.append(_landmark_id(path, lineno, i))
        xy.append((x, y))
    if not ids:
        raise FreiburgError(f"{path}: no landmarks (the file is empty or holds comments only)")
    if len(set(ids)) != len(ids):
        raise FreiburgError(f"{path}: landmark ids repeat: {sorted(ids)}")
    return np.array(ids, dtype=np.int64), np.array(xy, dtype=float).reshape(-1, 2)


def read_sensor_data(path) -> tuple[np.ndarray, list]:
    """``sensor_data.dat`` as ``(odometry (T, 3), observations)`` (see :class:`FreiburgData`)."""
    path = Path(path)
    odometry, observations = [], []
    for lineno, tok in _rows(path):
        kind, rest = tok[0], tok[1:]
        if kind == "ODOMETRY":
            odometry.append(_floats(path, lineno, rest, 3, "ODOMETRY"))
            observations.append([])
        elif kind == "SENSOR":
            if not odometry:
                raise FreiburgError(f"{path}:{lineno}: SENSOR before the first ODOMETRY line")
            j, r, b = _floats(path, lineno, rest, 3, "SENSOR")
            if r < 0:
                raise FreiburgError(f"{path}:{lineno}: a range must be >= 0, got {r}")
            observations[-1].append((r, b, _landmark_id(path, lineno, j)))
        else:
            raise FreiburgError(f"{path}:{lineno}: unknown line type {kind!r}")
    if not odometry:
        raise FreiburgError(f"{path}: no ODOMETRY lines (the file is empty or holds comments only)")
    obs = [np.array(o, dtype=float).reshape(-1, 3) for o in observations]
    return np.array(odometry, dtype=float).reshape(-1, 3), obs


def read_freiburg(folder=None, *, world=None, sensor_data=None) -> FreiburgData:
    """Read ``folder/world.dat`` and ``folder/sensor_data.dat`` (or the files given).

    Raises
    ------
    FileNotFoundError
    FreiburgError
        A malformed line, an observed id that ``world.dat`` lacks, a file that is not
        text or holds no data (empty, comments only), a folder that is a file.
    """
    if folder is None and (world is None or sensor_data is None):
        raise TypeError("give folder, or both world and sensor_data")
    if folder is not None:
        folder = data_folder(folder, FreiburgError, "Freiburg data")
    world = Path(folder) / "world.dat" if world is None else Path(world)
    sensor_data = Path(folder) / "sensor_data.dat" if sensor_data is None else Path(sensor_data)
    ids, xy = read_world(world)
    odometry, observations = read_sensor_data(sensor_data)
    data = FreiburgData(ids, xy, odometry, observations)
    seen = {int(j) for o in observations for j in o[:, 2]}
    unknown = sorted(seen - set(ids.tolist()))
    if unknown:
        raise FreiburgError(f"{sensor_data}: observed landmark id(s) {unknown} not in {world}")
    return data
