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


def _imports(path: Path) -> set[str]:
    """Every module a file imports, at any depth (function-level imports too)."""
    import ast

    found = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            found.add(node.module)
            found.update(f"{node.module}.{alias.name}" for alias in node.names)
    return found


def test_the_library_never_imports_the_answers():
    """Outside the grader, robolab never imports solutions/ or tests/ (the student edition)."""
    offenders = {
        str(path.relative_to(ROOT.parent)): sorted(
            m for m in _imports(path) if m.split(".")[0] in ("solutions", "tests")
        )
        for path in ROOT.rglob("*.py")
        if "grading" not in path.relative_to(ROOT).parts
    }
    assert not {k: v for k, v in offenders.items() if v}


# package -> grader packages it must not import (docs/architecture.md, "The layers")
FORBIDDEN = {
    "wire": {"loading", "isolation", "running", "course", "exports", "labs", "commands"},
    "loading": {"isolation", "running", "course", "exports", "commands"},
    "course": {"isolation", "exports", "commands"},
    "running": {"course", "exports", "commands"},
}


@pytest.mark.parametrize("package", sorted(FORBIDDEN))
def test_grader_packages_import_only_the_layers_below(package):
    bad = {}
    for path in (ROOT / "grading" / package).rglob("*.py"):
        hits = sorted(
            m for m in _imports(path)
            if m.startswith("robolab.grading.") and m.split(".")[2] in FORBIDDEN[package]
        )
        if hits:
            bad[path.name] = hits
    assert not bad, f"robolab.grading.{package} reaches above its layer: {bad}"


def test_grader_packages_say_what_they_own_and_may_import():
    for init in (ROOT / "grading").glob("*/__init__.py"):
        doc = init.read_text()
        assert "Owns:" in doc and "May import:" in doc, init


def test_no_library_module_outgrows_one_concept():
    """About 600 lines at most per module (docs/architecture.md): split by concept beyond that."""
    long = {
        str(p.relative_to(ROOT.parent)): n
        for p in ROOT.rglob("*.py")
        if (n := len(p.read_text().splitlines())) > 620
    }
    assert not long, long
