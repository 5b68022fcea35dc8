"""Lab 09 on real data: the Intel Research Lab and Manhattan (M3500) pose graphs.

Both are g2o files of the ``graph_slam`` data set (:data:`robolab.datasets.REGISTRY`),
each with its own initial guess (odometry, or a poor one for M3500). The anchor the
lab compares against was measured with GTSAM 4.3's Gauss-Newton from the same
guesses, the objective evaluated with :func:`robolab.evaluation.graph_objective`:
Intel 1.795e6 -> 359.997 in 5 iterations, M3500 2.567e6 -> 137.913 in 6.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path

from robolab.datasets.fetch import locate
from robolab.datasets.g2o import read_g2o

__all__ = ["GRAPH_DATA", "REAL_GRAPHS", "GTSAM_ANCHOR", "optimize_real_graphs"]

#: The data set's name in :data:`robolab.datasets.REGISTRY`.
GRAPH_DATA = "graph_slam"
#: The real graphs, file name -> label.
REAL_GRAPHS = {"intel.g2o": "Intel Research Lab", "input_M3500_g2o.g2o": "Manhattan M3500"}
#: GTSAM 4.3 Gauss-Newton, per file: (initial objective, final objective, iterations).
GTSAM_ANCHOR = {"intel.g2o": (1.795e6, 359.997, 5), "input_M3500_g2o.g2o": (2.567e6, 137.913, 6)}


def optimize_real_graphs(
    optimize_graph: Callable, folder=None, names=tuple(REAL_GRAPHS)
) -> dict | None:
    """Run ``optimize_graph(graph)`` on each real graph; None when the data set is not on disk.

    Returns
    -------
    dict or None
        ``{file name: {"initial": PoseGraph, "optimized": PoseGraph, "history": dict,
        "cpu_seconds": float}}``; the CPU time is the process's, around the call only.
    """
    folder = locate(GRAPH_DATA) if folder is None else Path(folder)
    if folder is None:
        return None
    out = {}
    for name in names:
        graph = read_g2o(Path(folder) / name)
        start = time.process_time()
        optimized, history = optimize_graph(graph)
        out[name] = {
            "initial": graph,
            "optimized": optimized,
            "history": history,
            "cpu_seconds": time.process_time() - start,
        }
    return out
