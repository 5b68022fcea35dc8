"""Regenerating the bundled data (``robolab data``)."""

from __future__ import annotations

import io
import sys
import zipfile
from collections.abc import Callable, Iterable
from pathlib import Path

import numpy as np
from tqdm.auto import tqdm

from robolab.maps import save_map
from robolab.sim.bagfile import write_bag
from robolab.sim.ekf import ekf_world
from robolab.sim.runs import _office, localization_run, mapping_run


def _save_npz(path: Path, arrays: dict[str, np.ndarray]) -> Path:
    """Like ``numpy.savez_compressed`` but byte-for-byte reproducible (fixed zip timestamps)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        for name, arr in arrays.items():
            buf = io.BytesIO()
            np.lib.format.write_array(buf, np.asarray(arr), allow_pickle=False)
            info = zipfile.ZipInfo(f"{name}.npy", date_time=(1980, 1, 1, 0, 0, 0))
            info.compress_type = zipfile.ZIP_DEFLATED
            info.external_attr = 0o644 << 16
            zf.writestr(info, buf.getvalue())
    return path


# -- make_data -----------------------------------------------------------------
def _make_office(out: Path, progress: bool) -> list[Path]:
    y = save_map(_office(), out / "office.yaml")
    return [y, y.with_suffix(".pgm")]


def _make_mapping(out: Path, progress: bool) -> list[Path]:
    return [write_bag(mapping_run(progress=progress), out / "mapping.bag", progress=progress)]


def _make_localization(out: Path, progress: bool) -> list[Path]:
    return [
        write_bag(localization_run(progress=progress), out / "localization.bag", progress=progress)
    ]


def _make_ekf_world(out: Path, progress: bool) -> list[Path]:
    return [_save_npz(out / "ekf_world.npz", ekf_world())]


def _make_maze(out: Path, progress: bool) -> list[Path]:
    from robolab.maze import write_maze

    y = Path(write_maze(out))
    return [y, out / "maze.png"]


def _make_fastslam(out: Path, progress: bool) -> list[Path]:
    from robolab.fiducials import write_run

    return [Path(write_run(out / "fastslam.npz", seed=0))]


def _make_graph_slam(out: Path, progress: bool) -> list[Path]:
    from robolab.datasets.g2o import write_g2o
    from robolab.sim.graphs import simulate_graph

    graph, truth, landmarks = simulate_graph(seed=0)
    out.mkdir(parents=True, exist_ok=True)
    return [
        write_g2o(graph, out / "graph_slam.g2o"),
        _save_npz(out / "graph_slam_truth.npz", {"poses": truth, "landmarks": landmarks}),
    ]


#: Data set name -> the function that writes it into a folder.
DATASETS: dict[str, Callable[[Path, bool], list[Path]]] = {
    "office": _make_office,
    "mapping": _make_mapping,
    "localization": _make_localization,
    "ekf_world": _make_ekf_world,
    "maze": _make_maze,
    "fastslam": _make_fastslam,
    "graph_slam": _make_graph_slam,
}


def make_data(
    out_dir=None, only: Iterable[str] | None = None, *, progress: bool = True
) -> list[Path]:
    """Regenerate the bundled data deterministically (``robolab data``).

    Parameters
    ----------
    out_dir : str or Path, optional
        Output folder; default :data:`robolab.DATA_DIR` (the repository's ``data/``).
    only : iterable of str, optional
        Names of the data sets to make (see :data:`DATASETS`); default all.
        ``office``: office.yaml + office.pgm; ``mapping``: mapping.bag;
        ``localization``: localization.bag; ``ekf_world``: ekf_world.npz;
        ``maze``: maze.png + maze.yaml; ``fastslam``: fastslam.npz;
        ``graph_slam``: graph_slam.g2o + graph_slam_truth.npz.
    progress : bool
        Show tqdm progress bars.

    Returns
    -------
    list of Path
        The files written.

    Raises
    ------
    ValueError
        An unknown name in ``only`` (the message lists the valid ones).
    """
    if out_dir is None:
        from robolab import DATA_DIR

        out_dir = DATA_DIR
    out = Path(out_dir)
    if isinstance(only, str):
        only = [only]
    if only is not None:
        only = list(only)
        if not all(isinstance(n, str) for n in only):
            raise TypeError(f"only must be data set names (str), got {only!r}")
    names = list(DATASETS) if not only else list(dict.fromkeys(only))
    unknown = [n for n in names if n not in DATASETS]
    if unknown:
        raise ValueError(
            f"unknown data set(s) {', '.join(map(repr, unknown))}; "
            f"valid names: {', '.join(DATASETS)}"
        )
    written: list[Path] = []
    out.mkdir(parents=True, exist_ok=True)
    with tqdm(names, desc="robolab data", unit="set", disable=not progress, file=sys.stderr) as bar:
        for name in bar:
            bar.set_postfix_str(name)
            written += DATASETS[name](out, progress)
    return written
