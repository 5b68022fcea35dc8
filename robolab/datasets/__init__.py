"""Readers of public robot data sets, one module per format, and their download.

Every reader returns robolab's typed arrays (:class:`robolab.bag.Scans`,
:class:`robolab.bag.PoseTrack`, numpy arrays) so that the lab functions run on
real data unchanged.

============  =====================================================================
module        reads
============  =====================================================================
``carmen``    CARMEN logs: ``ODOM``, ``FLASER`` / ``RLASER``, ``ROBOTLASER1``,
              ``RAWLASER1-4``, ``TRUEPOS`` (:func:`read_carmen`; corrected logs such
              as the Intel Research Lab's carry the corrected laser poses)
``freiburg``  the Freiburg Robot Mapping course format, ``world.dat`` and
              ``sensor_data.dat`` (:func:`read_freiburg`)
``g2o``       pose graphs in the g2o text format (``VERTEX_SE2``, ``VERTEX_XY``,
              ``EDGE_SE2``, ``EDGE_SE2_XY``) as a :class:`PoseGraph` (:func:`read_g2o`,
              :func:`write_g2o`)
``mrclam``    UTIAS MRCLAM ``.dat`` files, barcodes mapped to landmarks, streams
              aligned in time (:func:`read_mrclam`)
``rosbag``    ROS bags with configurable topics and message types (Odometry,
              PoseStamped, TF) (:func:`read_recording`, :func:`read_track`)
``fetch``     :func:`fetch` downloads a data set by URL and sha256 into a user cache
              (pooch); :func:`locate` finds one already on disk
============  =====================================================================
"""

from robolab.datasets.carmen import CarmenError, CarmenLaser, CarmenLog, read_carmen
from robolab.datasets.fetch import REGISTRY, DataSetUnavailable, fetch, locate
from robolab.datasets.freiburg import FreiburgData, FreiburgError, read_freiburg
from robolab.datasets.g2o import G2oError, PoseGraph, read_g2o, write_g2o
from robolab.datasets.mrclam import MrclamError, MrclamRun, read_mrclam
from robolab.datasets.rosbag import Recording, read_recording, read_track

__all__ = [
    "CarmenError",
    "CarmenLaser",
    "CarmenLog",
    "read_carmen",
    "FreiburgData",
    "FreiburgError",
    "read_freiburg",
    "G2oError",
    "PoseGraph",
    "read_g2o",
    "write_g2o",
    "MrclamError",
    "MrclamRun",
    "read_mrclam",
    "Recording",
    "read_recording",
    "read_track",
    "REGISTRY",
    "DataSetUnavailable",
    "fetch",
    "locate",
]
