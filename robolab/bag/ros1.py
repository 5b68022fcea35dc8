"""A ROS1-only stand-in for rosbags' ``AnyReader``, for where its ROS2 reader cannot load.

``rosbags.highlevel`` imports the ROS2 reader, which needs a compiled zstd module
(``backports.zstd`` before Python 3.14). Where that is missing -- in the browser
(JupyterLite / Pyodide) or a minimal install -- :class:`BagReader` still reads ROS1
``.bag`` files through this adapter: ``rosbags.rosbag1.Reader`` plus a typestore built
from the message definitions the bag carries, exactly as ``AnyReader`` builds it for
ROS1 bags (same ``topics``, ``connections``, ``messages`` and ``deserialize``).
"""

from __future__ import annotations

from pathlib import Path

__all__ = ["LatestTypestore", "Ros1OnlyReader", "any_reader_class"]


class LatestTypestore:
    """rosbags' ``get_typestore(Stores.LATEST)``, built on first use.

    The readers consult their default typestore only for a bag that carries no message
    definitions (the bundled and the Olin bags carry theirs); building it imports every
    ROS2 distribution's type module (dashing to kilted, each importing its predecessor:
    about 0.05 s of CPU per process), which such a bag never needs. Any attribute is
    the real typestore's.
    """

    def __getattr__(self, name):
        if name.startswith("__"):  # copy, pickle and the like probe dunders: not the store's
            raise AttributeError(name)
        store = self.__dict__.get("_store")
        if store is None:
            from rosbags.typesys import Stores, get_typestore

            store = self.__dict__["_store"] = get_typestore(Stores.LATEST)
        return getattr(store, name)


def any_reader_class():
    """``rosbags.highlevel.AnyReader``, or :class:`Ros1OnlyReader` when it cannot be imported."""
    try:
        from rosbags.highlevel import AnyReader
    except ImportError:
        return Ros1OnlyReader
    return AnyReader


class Ros1OnlyReader:
    """Read ROS1 bags with the subset of ``AnyReader``'s interface that robolab uses.

    Parameters
    ----------
    paths : list of Path
        ROS1 ``.bag`` files (one, as :class:`robolab.bag.BagReader` opens them).
    default_typestore : rosbags Typestore, optional
        Types to use when the bag carries no message definitions.

    Raises
    ------
    ValueError
        For a ROS2 bag: reading it needs rosbags' ROS2 reader and its zstd module.
    """

    def __init__(self, paths, default_typestore=None) -> None:
        self.paths = [Path(p) for p in paths]
        ros2 = [p for p in self.paths if p.suffix != ".bag"]
        if ros2:
            raise ValueError(
                f"{ros2[0]} is a ROS2 bag, and rosbags' ROS2 reader cannot be imported here "
                "(it needs the zstd module: pip install backports.zstd); ROS1 .bag files "
                "still work"
            )
        self.default_typestore = default_typestore
        self._readers = []
        self.connections = []
        self.typestore = None

    def open(self) -> None:
        from rosbags.rosbag1 import Reader
        from rosbags.typesys import Stores, get_types_from_msg, get_typestore

        self._readers = [Reader(p) for p in self.paths]
        for reader in self._readers:
            reader.open()
        self.connections = [c for r in self._readers for c in r.connections]
        types: dict = {}
        with_defs = [c for c in self.connections if c.msgdef.data]
        for connection in with_defs:
            types.update(get_types_from_msg(connection.msgdef.data, connection.msgtype))
        if not with_defs and self.default_typestore is not None:
            types.update(self.default_typestore.fielddefs)
        typestore = get_typestore(Stores.EMPTY)
        typestore.register(types)
        self.typestore = typestore

    def close(self) -> None:
        for reader in self._readers:
            reader.close()
        self._readers = []
        self.connections = []

    @property
    def topics(self) -> dict:
        """``{name: TopicInfo}`` merged over the files (one file: its own)."""
        merged: dict = {}
        for reader in self._readers:
            for name, info in reader.topics.items():
                merged.setdefault(name, info)
        return merged

    def messages(self, connections=()):
        """``(connection, timestamp_ns, raw)`` in time order, like ``AnyReader.messages``."""
        from heapq import merge

        wanted = list(connections)
        streams = []
        for reader in self._readers:
            mine = [c for c in wanted if c.owner is reader] if wanted else None
            if wanted and not mine:
                continue
            streams.append(reader.messages(connections=mine) if mine else reader.messages())
        yield from merge(*streams, key=lambda item: item[1])

    def deserialize(self, raw: bytes, msgtype: str):
        """A message object from its ROS1 serialization."""
        return self.typestore.deserialize_ros1(raw, msgtype)
