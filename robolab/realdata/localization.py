"""Lab 05 on real data: the Olin AC109 Neato bag (ceiling-camera ground truth).

Its topics differ from the simulated bag's (``/scan``, PoseStamped ``/map_pose``),
its laser is mounted backwards, beams with no return read 0 and its map is a
map_server P6 image at 2 cm: :func:`neato_localization` reads it all into the
:class:`robolab.plotting.mcl.LocalizationData` that the lab's runners take.
"""

from __future__ import annotations

from pathlib import Path

from robolab.datasets.fetch import DataSetUnavailable, locate

__all__ = ["NEATO", "NEATO_SCAN_DELAY", "neato_localization"]

#: The data set's name in :data:`robolab.datasets.REGISTRY`.
NEATO = "olin_ac109_1"


#: The scans of the Olin Neato recordings are stamped this late against odometry and the
#: ceiling camera, seconds (measured on three recordings of the same robot; see
#: :func:`robolab.datasets.rosbag.read_recording`'s ``scan_delay``).
NEATO_SCAN_DELAY = 0.3


def neato_localization(
    bag=None,
    map=None,  # noqa: A002 - the map file, as the lab calls it
    *,
    folder=None,
    scan_delay: float = 0.0,
    truth_delay: float = 0.0,
):
    """A Neato recording and its map as :class:`~robolab.plotting.mcl_runs.LocalizationData`.

    Parameters
    ----------
    bag : str or Path, optional
        A recording of the Olin Neato (topics ``/scan``, ``/odom``, ``/map_pose``); default
        ``ac109_1_demo.bag`` of ``folder``. Other recordings of the same robot load too.
    map : str or Path, optional
        Its map_server ``.yaml``; default ``ac109_1.yaml`` for the default bag, else the one
        ``.yaml`` file beside ``bag``.
    folder : str or Path, optional
        Where the default files are; default wherever :func:`robolab.datasets.locate`
        finds the ``olin_ac109_1`` data set (``../shared/data`` or the download cache).
    scan_delay : float
        Seconds the scans' stamps run late against odometry and the camera; 0 (the
        default) reads every stream as stamped. The Olin scans are late by about
        :data:`NEATO_SCAN_DELAY` (0.3 s): pass that positive value to read odometry and
        truth 0.3 s before each scan's stamp.
    truth_delay : float
        Seconds the camera's stamps run late against odometry (0 on these recordings).

    Raises
    ------
    DataSetUnavailable
        The default data set is not on disk: the message says how to get it
        (``robolab.datasets.fetch("olin_ac109_1")``).
    FileNotFoundError
        A ``bag`` or ``map`` given by name does not exist.
    ValueError
        ``map`` is not given and the folder of ``bag`` holds no or several ``.yaml`` files.
    """
    from robolab.plotting.mcl_runs import load_localization

    if bag is None:
        where = Path(folder) if folder is not None else locate(NEATO)
        if where is None or not (where / "ac109_1_demo.bag").is_file():
            raise DataSetUnavailable(
                f"the real Neato data set {NEATO!r} is not on disk; "
                f"robolab.datasets.fetch({NEATO!r}) downloads it (3 MB + 3.5 MB)"
            )
        bag = where / "ac109_1_demo.bag"
        map = where / "ac109_1.yaml" if map is None else map
    bag = Path(bag)
    if map is None:  # the one map_server file beside the recording
        maps = sorted(bag.parent.glob("*.yaml"))
        if len(maps) != 1:
            raise ValueError(
                f"neato_localization: pass map=, the map of {bag.name} "
                f"({len(maps)} .yaml files beside it)"
            )
        map = maps[0]
    for what, path in (("bag", bag), ("map", Path(map))):
        if not path.is_file():
            raise FileNotFoundError(f"neato_localization: no such {what} file: {path}")
    return load_localization(
        bag,
        Path(map),
        scan_topic="/scan",
        truth="/map_pose",
        scan_delay=scan_delay,
        truth_delay=truth_delay,
    )
