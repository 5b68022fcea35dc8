"""robolab: a probabilistic-robotics workbook.

The support library that the labs in ``notebooks/`` build on: maps and ray
casting, the landmark world, the fiducial robot, ROS bag I/O, a simulator, plots
and the autograder. Units are metres, radians and seconds; frames follow ROS
(REP-103): x forward, y left, angles counter-clockwise.
"""

from pathlib import Path

__version__ = "0.1.0"

#: Folder of the bundled data (maps, bags) made by ``robolab data``.
DATA_DIR = Path(__file__).resolve().parent.parent / "data"

__all__ = ["DATA_DIR", "__version__"]
