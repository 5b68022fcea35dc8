"""The bundled runs: routes, start poses, random seeds and durations."""

from __future__ import annotations

import numpy as np

from robolab.maps import OccupancyGrid
from robolab.sim.run import SimRun, simulate

#: Random seeds of the bundled data sets.
SEEDS = {"mapping": 4, "localization": 5, "ekf_world": 6}
#: Length of the bundled runs, seconds.
MAPPING_DURATION = 80.0
LOCALIZATION_DURATION = 85.0

#: Mapping route: corridor -> open-plan room (around a pillar) -> corridor ->
#: north office 2 (around its table) -> back into the corridor.
MAPPING_ROUTE = np.array(
    [
        [1.0, 6.0],
        [3.75, 6.0],
        [3.75, 3.8],
        [6.6, 3.8],
        [6.6, 1.3],
        [4.0, 1.3],
        [4.0, 6.0],
        [11.5, 6.0],
        [11.5, 8.0],
        [14.3, 8.0],
        [14.3, 10.2],
        [11.5, 10.2],
        [11.5, 6.0],
    ]
)

#: Localization route: starts inside north office 1 (four identical offices:
#: global localization is ambiguous until the robot sees the corridor), leaves
#: it, drives west along the corridor, loops through the open-plan room and
#: drives east along the corridor.
LOCALIZATION_ROUTE = np.array(
    [
        [7.2, 9.8],
        [9.2, 9.8],
        [9.2, 8.0],
        [6.5, 8.0],
        [6.5, 6.0],
        [3.75, 6.0],
        [3.75, 3.8],
        [7.0, 3.8],
        [7.0, 1.5],
        [4.0, 1.5],
        [4.0, 6.0],
        [18.5, 6.0],
    ]
)
# The start poses sit a little off the 5 cm cell boundaries (1.0, 6.0 and 7.2,
# 9.8 lie exactly on them), which keeps every ray of the first scan off a grid line.
#: Initial ground-truth pose of the mapping run.
MAPPING_START = (1.03, 6.02, 0.0)
#: Initial ground-truth pose of the localization run, inside the second north office.
LOCALIZATION_START = (7.23, 9.82, 0.0)


def _office() -> OccupancyGrid:
    from robolab.floorplan import office_floorplan

    return office_floorplan()


def mapping_run(duration: float = MAPPING_DURATION, *, progress: bool = False) -> SimRun:
    """The run behind ``data/mapping.bag`` (seed ``SEEDS["mapping"]``).

    A shorter ``duration`` reproduces the start of the full run exactly.
    """
    return simulate(
        _office(),
        MAPPING_ROUTE,
        start_pose=MAPPING_START,
        duration=duration,
        rng=np.random.default_rng(SEEDS["mapping"]),
        progress=progress,
    )


def localization_run(duration: float = LOCALIZATION_DURATION, *, progress: bool = False) -> SimRun:
    """The run behind ``data/localization.bag`` (seed ``SEEDS["localization"]``).

    A shorter ``duration`` reproduces the start of the full run exactly.
    """
    return simulate(
        _office(),
        LOCALIZATION_ROUTE,
        duration=duration,
        start_pose=LOCALIZATION_START,
        rng=np.random.default_rng(SEEDS["localization"]),
        progress=progress,
    )
