"""robolab.bag and robolab.sim are packages of small modules with their public names at the top."""

from __future__ import annotations

import importlib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1] / "robolab"

BAG = [
    "BagError",
    "TopicInfo",
    "Scans",
    "PoseTrack",
    "TfTree",
    "BagReader",
    "BagWriter",
    "laser_pose_in_base",
    "LASER_SCAN",
    "ODOMETRY",
    "POSE_STAMPED",
    "TF_MESSAGE",
]
SIM = [
    "LaserModel",
    "OdometryNoise",
    "Controller",
    "SimRun",
    "follow_route",
    "simulate",
    "write_bag",
    "odometry_from_truth",
    "scan_noise",
    "clearance_field",
    "mapping_run",
    "localization_run",
    "ekf_world",
    "make_data",
    "DATASETS",
    "START_TIME",
    "BAG_TOPICS",
    "MAPPING_ROUTE",
    "MAPPING_START",
    "LOCALIZATION_ROUTE",
    "LOCALIZATION_START",
    "SEEDS",
    "MAPPING_DURATION",
    "LOCALIZATION_DURATION",
]


@pytest.mark.parametrize("package, names", [("robolab.bag", BAG), ("robolab.sim", SIM)])
def test_public_names_keep_their_import_paths(package, names):
    mod = importlib.import_module(package)
    missing = [n for n in names if not hasattr(mod, n)]
    assert not missing
    assert set(mod.__all__) <= set(dir(mod))


@pytest.mark.parametrize("package", ["bag", "sim", "datasets", "realdata"])
def test_modules_stay_small(package):
    for path in (ROOT / package).glob("*.py"):
        assert len(path.read_text().splitlines()) < 450, f"{path} grew past one concept"
