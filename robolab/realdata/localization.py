"""Lab 05 on real data: the Olin AC109 Neato bag (ceiling-camera ground truth).

Its topics differ from the simulated bag's (``/scan``, PoseStamped ``/map_pose``),
its laser is mounted backwards, beams with no return read 0 and its map is a
map_server P6 image at 2 cm: :func:`neato_localization` reads it all into the
:class:`robolab.plotting.mcl.LocalizationData` that the lab's runners take.
"""

from __future__ import annotations

from pathlib import Path

from robolab.datasets.fetch import DataSetUnavailable, locate

__all__ = ["NEATO", "neato_localization"]

#: The data set's name in :data:`robolab.datasets.REGISTRY`.
NEATO = "olin_ac109_1"


def neato_localization(folder=None, *, truth_delay: float = 0.0):
    """The Neato bag and its map as :class:`~robolab.plotting.mcl.LocalizationData`.

    Parameters
    ----------
    folder : str or Path, optional
        Where ``ac109_1_demo.bag`` and ``ac109_1.yaml`` are; default wherever
        :func:`robolab.datasets.locate` finds them (``../shared/data`` or the cache).
    truth_delay : float
        Seconds the camera's stamps run behind the robot's (see
        :func:`robolab.datasets.read_recording`).

    Raises
    ------
    DataSetUnavailable
        The data set is not on disk: the message says how to get it
        (``robolab.datasets.fetch("olin_ac109_1")``).
    """
    from robolab.plotting.mcl import load_localization

    where = Path(folder) if folder is not None else locate(NEATO)
    if where is None or not (where / "ac109_1_demo.bag").is_file():
        raise DataSetUnavailable(
            f"the real Neato data set {NEATO!r} is not on disk; "
            f"robolab.datasets.fetch({NEATO!r}) downloads it (3 MB + 3.5 MB)"
        )
    return load_localization(
        where / "ac109_1_demo.bag",
        where / "ac109_1.yaml",
        scan_topic="/scan",
        truth="/map_pose",
        truth_delay=truth_delay,
    )
