"""robolab: a probabilistic-robotics workbook.

The support library that the labs in ``notebooks/`` build on: maps and ray
casting, the landmark world, the fiducial robot, ROS bag I/O, a simulator, plots
and the autograder. Units are metres, radians and seconds; frames follow ROS
(REP-103): x forward, y left, angles counter-clockwise.
"""

from pathlib import Path

__version__ = "0.1.0"


def _data_dir() -> Path:
    """Where the bundled data is: inside the installed package, else the repository's ``data/``.

    A wheel (``robolab release`` builds one) carries the data as package data in
    ``robolab/data/``, found through :mod:`importlib.resources`, so the labs run from
    any working directory; a development checkout keeps it in ``<repo>/data/``.
    """
    package = Path(__file__).parent
    if package.is_dir():  # on the file system, importlib.resources would find package/data
        packaged = package / "data"
    else:  # a zip, say (importlib.resources costs 15 ms to import: only when it is needed)
        from importlib.resources import files

        packaged = files(__name__) / "data"
    if packaged.is_dir():
        return Path(str(packaged))
    return Path(__file__).resolve().parent.parent / "data"


#: Folder of the bundled data (maps, bags) made by ``robolab data``.
DATA_DIR = _data_dir()

__all__ = ["DATA_DIR", "__version__"]
