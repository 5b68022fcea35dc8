"""robolab.bag reads ROS1 bags where rosbags' ROS2 reader (and its zstd module) cannot load."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from robolab import DATA_DIR

ROOT = Path(__file__).resolve().parents[1]
OLIN = ROOT.parent / "shared" / "data" / "olin_ac109_1"

#: Runs in a fresh interpreter: blocks the zstd modules, then reads a bag and prints a summary.
PROBE = r"""
import json, sys
class NoZstd:
    def find_spec(self, name, path=None, target=None):
        if name.split(".")[0] in ("backports", "compression", "zstandard"):
            raise ImportError(f"{name} blocked by the test")
sys.meta_path.insert(0, NoZstd())
import numpy as np
from robolab.bag import BagReader
from robolab.bag.ros1 import any_reader_class
out = {"reader": any_reader_class().__name__}
with BagReader(sys.argv[1]) as bag:
    out["topics"] = {k: v.msgtype for k, v in bag.topics.items()}
    scan_topic = next(t for t, i in bag.topics.items() if i.msgtype.endswith("LaserScan"))
    scans = bag.scans(scan_topic)
    out["scan_sum"] = float(np.nansum(np.where(np.isfinite(scans.ranges), scans.ranges, 0)))
    out["n_scans"] = int(len(scans.stamps))
print(json.dumps(out))
"""


def _probe(bag: Path, block: bool) -> dict:
    code = PROBE if block else PROBE.replace("sys.meta_path.insert(0, NoZstd())", "")
    proc = subprocess.run([sys.executable, "-c", code, str(bag)], capture_output=True, text=True,
                          timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return json.loads(proc.stdout.strip().splitlines()[-1])


@pytest.mark.parametrize("bag", [DATA_DIR / "mapping.bag", OLIN / "ac109_1_demo.bag"],
                         ids=["bundled", "olin-real-bz2"])
def test_ros1_bag_reads_the_same_without_the_ros2_reader(bag):
    """Topics and every scan range are the same through the ROS1-only reader and AnyReader."""
    if not bag.is_file():
        pytest.skip(f"{bag} is not available (../shared/data)")
    normal, fallback = _probe(bag, block=False), _probe(bag, block=True)
    assert normal["reader"] == "AnyReader" and fallback["reader"] == "Ros1OnlyReader"
    assert fallback["topics"] == normal["topics"]
    assert fallback["n_scans"] == normal["n_scans"] > 0
    assert fallback["scan_sum"] == pytest.approx(normal["scan_sum"], rel=0, abs=1e-9)


def test_a_ros2_bag_without_the_ros2_reader_says_what_to_install(tmp_path):
    """A ROS2 bag cannot be read by the fallback: the error names the missing module."""
    from robolab.bag.ros1 import Ros1OnlyReader

    with pytest.raises(ValueError, match="zstd"):
        Ros1OnlyReader([tmp_path / "run.mcap"])
