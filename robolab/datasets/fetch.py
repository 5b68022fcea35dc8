"""Downloading the public data sets into a user cache, checked by sha256 (with ``pooch``).

:data:`REGISTRY` lists each data set's files with the address they are published at
(pinned to a commit) and their sha256. :func:`fetch` downloads what is missing into
``pooch.os_cache("robolab")`` (override with the ``ROBOLAB_DATA_CACHE`` environment
variable), checks every file's hash and returns the folder. :func:`locate` finds a
data set already on disk (a local copy such as ``../shared/data``, then the cache)
without touching the network: labs use it to skip their real-data step with a
friendly note when the data is absent.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

__all__ = ["DataSetUnavailable", "RemoteFile", "REGISTRY", "cache_dir", "fetch", "locate"]

_RAW = "https://raw.githubusercontent.com"


@dataclass(frozen=True)
class RemoteFile:
    """One file of a data set: where it is published and its sha256."""

    url: str
    sha256: str


#: Data set name -> {file name: RemoteFile}.
REGISTRY: dict[str, dict[str, RemoteFile]] = {
    "intel_lab": {
        "intel-corrected.log.gz": RemoteFile(
            f"{_RAW}/acschaefer/ple/cfcb5a7f12a793b616357381a688cfcc26eed347"
            "/data/carmen/intel-corrected.log.gz",
            "71bef16e9926506cf7417995ef35ace09dbd5de067fd042a3aab85188b5480dc",
        ),
    },
    "freiburg_course": {
        "world.dat": RemoteFile(
            f"{_RAW}/SiweiGong/mobile_robot_framework/aca7e56152069a970a07288178d6be998b1f7938"
            "/src/fastSLAM_data/world.dat",
            "35401a34be49bdb24333efa7ad4ef680c073ec58096a4393be36a03718454253",
        ),
        "sensor_data.dat": RemoteFile(
            f"{_RAW}/SiweiGong/mobile_robot_framework/aca7e56152069a970a07288178d6be998b1f7938"
            "/src/fastSLAM_data/sensor_data.dat",
            "4553824603857e94e3e5ccc3c93379a45131b7b5faae1c6929dfcb0f3a6308e7",
        ),
    },
    "graph_slam": {
        "simulation-pose-pose.g2o": RemoteFile(
            f"{_RAW}/BazzaCipher/robotics-rs/b39d11dff1a8bde0f5f7bb876c6189357823cd8e"
            "/dataset/g2o/simulation-pose-pose.g2o",
            "a8e73874e3a94c3a6f9da0e4ceccb842d7537c01612def2f974f18c8afdeed84",
        ),
        "simulation-pose-landmark.g2o": RemoteFile(
            f"{_RAW}/BazzaCipher/robotics-rs/b39d11dff1a8bde0f5f7bb876c6189357823cd8e"
            "/dataset/g2o/simulation-pose-landmark.g2o",
            "8bb0a1f2824713758a7eaf50a8229dbd9e08cc57562f295bd1d47f97f97c775b",
        ),
        "intel.g2o": RemoteFile(
            f"{_RAW}/BazzaCipher/robotics-rs/b39d11dff1a8bde0f5f7bb876c6189357823cd8e"
            "/dataset/g2o/intel.g2o",
            "a6c086e1587d7b403effa0f2b755d4eff4a71eb705fefce0220e2f9aca1a14a2",
        ),
        "input_M3500_g2o.g2o": RemoteFile(
            f"{_RAW}/BazzaCipher/robotics-rs/b39d11dff1a8bde0f5f7bb876c6189357823cd8e"
            "/dataset/g2o/input_M3500_g2o.g2o",
            "1883593980e602b11bd0ba95799c969e59ee8a6892bdb2a3a48f495459efe9d8",
        ),
    },
    "olin_ac109_1": {
        "ac109_1_demo.bag": RemoteFile(
            f"{_RAW}/anushadatar/robot_localization/4b4253fb00d361a740ff41a8da0ba7a3c6fbd9de"
            "/robot_localizer/bags/ac109_1_demo.bag",
            "4b27e23ec7e2526d361540929aceb12cf004eb1f4e03b57d060f52af1ba5af27",
        ),
        "ac109_1.yaml": RemoteFile(
            f"{_RAW}/anushadatar/robot_localization/4b4253fb00d361a740ff41a8da0ba7a3c6fbd9de"
            "/robot_localizer/maps/ac109_1.yaml",
            "383872dece45d75996ff2fe9d38f3475000e9c9cdfd95fc9cf4108114f7c6e57",
        ),
        "ac109_1.pgm": RemoteFile(
            f"{_RAW}/anushadatar/robot_localization/4b4253fb00d361a740ff41a8da0ba7a3c6fbd9de"
            "/robot_localizer/maps/ac109_1.pgm",
            "db990c13396c249451bb98a21e816cc9559be0b61a2e8e73d76d773cde31d061",
        ),
    },
}

#: Folders searched by :func:`locate` before the cache (relative to the repository root).
LOCAL_ROOTS = ("../shared/data",)


class DataSetUnavailable(RuntimeError):
    """A data set is neither on disk nor downloadable (offline, or the address failed)."""


def _files(name: str) -> dict[str, RemoteFile]:
    if not isinstance(name, str):
        raise TypeError(f"name must be a data set name (str), got {type(name).__name__}")
    if name not in REGISTRY:
        raise ValueError(f"unknown data set {name!r}; known: {', '.join(sorted(REGISTRY))}")
    return REGISTRY[name]


def cache_dir() -> Path:
    """The download cache: ``$ROBOLAB_DATA_CACHE`` or pooch's per-user cache for robolab."""
    env = os.environ.get("ROBOLAB_DATA_CACHE")
    if env:
        return Path(env)
    import pooch

    return Path(pooch.os_cache("robolab"))


def _complete(folder: Path, files) -> bool:
    return all((folder / f).is_file() for f in files)


def locate(name: str, roots=None) -> Path | None:
    """The folder holding data set ``name`` if every file of it is on disk, else None.

    Looks in ``roots`` (default :data:`LOCAL_ROOTS`, relative to the repository root),
    then in :func:`cache_dir`. Never uses the network, never checks hashes (a local
    copy is trusted as it is).
    """
    files = _files(name)
    from robolab import DATA_DIR

    repo = Path(DATA_DIR).parent
    candidates = [Path(r) if Path(r).is_absolute() else repo / r for r in (roots or LOCAL_ROOTS)]
    for root in [*candidates, cache_dir()]:
        if _complete(root / name, files):
            return (root / name).resolve()
    return None


def fetch(name: str, *, progress: bool = False) -> Path:
    """Download data set ``name`` (see :data:`REGISTRY`) into the cache; return its folder.

    Files already in the cache with the right sha256 are not downloaded again.

    Raises
    ------
    ValueError
        An unknown name (the message lists the known ones).
    DataSetUnavailable
        A file could not be downloaded (no network, the address failed): the message
        says which file, from where, and how to put it in place by hand.
    """
    files = _files(name)
    import pooch

    folder = cache_dir() / name
    for fname, remote in files.items():
        try:
            pooch.retrieve(
                url=remote.url,
                known_hash=f"sha256:{remote.sha256}",
                fname=fname,
                path=folder,
                progressbar=progress,
            )
        except ValueError:  # pooch: the downloaded file's hash does not match
            raise
        except Exception as exc:  # requests' ConnectionError, HTTPError, timeouts, OSError
            raise DataSetUnavailable(
                f"cannot download {fname} of data set {name!r} from {remote.url} "
                f"({type(exc).__name__}: {exc}). Are you offline? Copy the file by hand to "
                f"{folder / fname} (sha256 {remote.sha256}), or run fetch({name!r}) online."
            ) from exc
    return folder
