"""TF trees: chained lookups over the edges seen on /tf and /tf_static."""

from __future__ import annotations

from collections import deque
from collections.abc import Iterable, Mapping

import numpy as np

from robolab.bag.messages import BagError
from robolab.bag.poses import PoseTrack
from robolab.geometry import (
    compose,
    inverse,
)


def _frame(name: str) -> str:
    # tf2 ignores a leading slash in frame ids (ROS1 tf used "/odom").
    return name.lstrip("/")


class TfTree:
    """Transforms between frames, from every edge seen on ``/tf`` and ``/tf_static``.

    The edges may form several trees (the Olin bag has odom -> base_link ->
    base_laser_link, map -> odom from a filter, and a camera's tag frames).

    Parameters
    ----------
    edges : mapping of (parent, child) -> PoseTrack
        Each edge's poses of ``child`` in ``parent`` over time.
    static : iterable of (parent, child)
        Edges that hold at all times (from ``/tf_static``). An edge with a single
        sample is static too.
    """

    def __init__(
        self, edges: Mapping[tuple[str, str], PoseTrack], static: Iterable[tuple[str, str]] = ()
    ):
        self._edges: dict[tuple[str, str], PoseTrack] = {}
        for key, track in edges.items():
            if not (
                isinstance(key, tuple) and len(key) == 2 and all(isinstance(k, str) for k in key)
            ):
                raise TypeError(f"edges keys must be (parent, child) string pairs, got {key!r}")
            if not isinstance(track, PoseTrack):
                raise TypeError(f"edges[{key!r}] must be a PoseTrack, got {type(track).__name__}")
            k = (_frame(key[0]), _frame(key[1]))
            if k in self._edges:
                raise ValueError(
                    f"edge {k[0]} -> {k[1]} given twice (frame ids differ only by a leading '/')"
                )
            self._edges[k] = track
        static = {(_frame(p), _frame(c)) for p, c in static}
        if unknown := static - self._edges.keys():
            raise ValueError(f"static edges {sorted(unknown)} are not in edges")
        self._static = frozenset(static | {k for k, v in self._edges.items() if len(v) == 1})
        self._adjacent: dict[str, list[tuple[str, tuple[str, str], bool]]] = {}
        for p, c in self._edges:
            self._adjacent.setdefault(p, []).append((c, (p, c), True))
            self._adjacent.setdefault(c, []).append((p, (p, c), False))

    def __repr__(self) -> str:
        return f"TfTree({len(self._edges)} edges: {', '.join(f'{p}->{c}' for p, c in self._edges)})"

    @property
    def edges(self) -> dict[tuple[str, str], PoseTrack]:
        """``{(parent, child): PoseTrack}`` for every edge (frame ids without a leading slash)."""
        return dict(self._edges)

    @property
    def static(self) -> frozenset[tuple[str, str]]:
        """Edges that hold at all times."""
        return self._static

    @property
    def frames(self) -> list[str]:
        """Every frame id, sorted."""
        return sorted(self._adjacent)

    def chain(self, parent: str, child: str) -> list[tuple[tuple[str, str], bool]]:
        """The edges from ``parent`` to ``child``: ``[(edge, forward), ...]``.

        ``forward`` is False when the edge is walked from its child to its parent.
        Raises :class:`BagError` for unknown frames or frames in different trees.
        """
        parent, child = _frame(parent), _frame(child)
        for role, f in (("parent", parent), ("child", child)):
            if f not in self._adjacent:
                raise BagError(
                    f"unknown {role} frame {f!r}; frames in the TF tree: "
                    f"{', '.join(self.frames) or 'none'}"
                )
        came: dict[str, tuple[str, tuple[str, str], bool] | None] = {parent: None}
        queue = deque([parent])
        while queue:  # breadth first: the shortest chain
            f = queue.popleft()
            if f == child:
                break
            for nxt, edge, forward in self._adjacent[f]:
                if nxt not in came:
                    came[nxt] = (f, edge, forward)
                    queue.append(nxt)
        if child not in came:
            raise BagError(
                f"no TF chain from {parent!r} to {child!r}: they are in different trees; "
                f"{parent!r} connects to {sorted(came)}"
            )
        steps = []
        f = child
        while came[f] is not None:
            prev, edge, forward = came[f]
            steps.append((edge, forward))
            f = prev
        return steps[::-1]

    def lookup(self, parent: str, child: str, t=None) -> np.ndarray:
        """Pose of ``child`` in ``parent``, chaining edges in either direction.

        Parameters
        ----------
        parent, child : str
            Frame ids (a leading slash is ignored).
        t : float, array_like (K,), or None
            Time(s) in seconds. Static edges apply at all times. ``None`` asks for a
            rigid transform: every edge on the chain must be static or constant
            over time (e.g. a laser mount published on ``/tf`` at every step).

        Returns
        -------
        numpy.ndarray, shape (3,) or (K, 3)

        Raises
        ------
        BagError
            Unknown frames, frames in different trees, ``t`` outside a dynamic
            edge's time range, or ``t=None`` with an edge that moves.
        """
        steps = self.chain(parent, child)
        shape = (3,) if t is None or np.ndim(t) == 0 else (np.size(t), 3)
        pose = np.zeros(shape)
        for (p, c), forward in steps:
            track = self._edges[(p, c)]
            if (p, c) in self._static:
                edge = track.poses[-1]  # latched: the last published value holds
            elif t is None:
                if not track.is_constant:
                    raise BagError(
                        f"edge {p} -> {c} changes over time; pass the time t to look it up"
                    )
                edge = track.poses[0]
            else:
                try:
                    edge = track.at(t)
                except ValueError as exc:
                    raise BagError(f"cannot look up edge {p} -> {c}: {exc}") from exc
            pose = compose(pose, edge if forward else inverse(edge))
        return np.broadcast_to(pose, shape).copy()


def laser_pose_in_base(
    tf: TfTree, laser_frame: str, base_frame: str = "base_link", t=None
) -> np.ndarray:
    """The laser's mounting pose: the ``base_frame -> laser_frame`` transform.

    Parameters
    ----------
    tf : TfTree
        From :meth:`BagReader.tf`.
    laser_frame : str
        The scans' ``frame_id``, e.g. ``"base_laser_link"``.
    base_frame : str
        The robot's body frame.
    t : float or None
        Time; ``None`` (default) requires a rigid mount (see :meth:`TfTree.lookup`).

    Returns
    -------
    numpy.ndarray, shape (3,)
        ``(x, y, theta)`` of the laser in the base frame. The Olin Neato's laser is
        mounted backwards: ``(-0.1016, 0, -pi)``. A scan endpoint ``q`` in the laser
        frame is at ``transform_points(q, compose(robot_pose, laser_pose))`` in the world.
    """
    if not isinstance(tf, TfTree):
        raise TypeError(f"tf must be a TfTree (from BagReader.tf()), got {type(tf).__name__}")
    return tf.lookup(base_frame, laser_frame, t)
