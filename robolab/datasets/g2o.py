r"""Pose graphs in the g2o text format, as a :class:`PoseGraph` of arrays.

The format (one element a line, whitespace-separated, angles in radians)::

    VERTEX_SE2   id x y theta                       a pose and its initial guess
    VERTEX_XY    id x y                             a landmark and its initial guess
    EDGE_SE2     i j dx dy dtheta I11 I12 I13 I22 I23 I33
                                                    pose j measured in the frame of pose i
    EDGE_SE2_XY  i j dx dy I11 I12 I22             landmark j measured in the frame of pose i

An edge's information matrix :math:`\Omega` (the inverse of the measurement's
covariance) is written as its upper triangle, row by row. Vertex ids are any
non-negative integers, not necessarily ``0..N-1`` nor in order; the graph's rows
are the vertices sorted by id (``pose_ids``, ``landmark_ids`` keep the ids), and
its edges hold row indices. Lines that start with ``#`` and blank lines are
skipped; ``FIX id`` (g2o's gauge) is read into ``fixed``. Any other element type
is refused, so that nothing is silently dropped.

The error of an edge and the objective :math:`\sum e^T \Omega e` are in
:func:`robolab.evaluation.graph_objective` (Grisetti, Kuemmerle, Stachniss and
Burgard, "A tutorial on graph-based SLAM", 2010; Probabilistic Robotics
chapter 11 formulates the same least-squares problem).
"""

from __future__ import annotations

import dataclasses
import itertools
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

__all__ = ["G2oError", "PoseGraph", "read_g2o", "write_g2o"]

#: Field count after the tag, per element type.
_FIELDS = {"VERTEX_SE2": 4, "VERTEX_XY": 3, "EDGE_SE2": 11, "EDGE_SE2_XY": 7, "FIX": 1}
#: Relative tolerance of the checks that an information matrix is symmetric positive semi-definite.
_PSD_TOL = 1e-9


class G2oError(ValueError):
    """A g2o file, or a PoseGraph, is malformed (the message names the file and line)."""


def _empty(*shape, dtype=float):
    return field(default_factory=lambda: np.zeros(shape, dtype=dtype))


@dataclass(frozen=True, eq=False)
class PoseGraph:
    """A pose graph, or a pose-landmark graph: the vertices' estimates and the edges.

    Attributes
    ----------
    poses : numpy.ndarray, shape (N, 3)
        Pose estimates ``(x, y, theta)``, metres and radians.
    edges : numpy.ndarray of int, shape (E, 2)
        Pose-pose edges as rows ``(i, j)`` into ``poses``: pose j measured from pose i.
    measurements : numpy.ndarray, shape (E, 3)
        Each edge's measured relative pose :math:`z_{ij}` (pose j in the frame of pose i).
    information : numpy.ndarray, shape (E, 3, 3)
        Each edge's information matrix :math:`\\Omega_{ij}` (symmetric, positive semi-definite).
    landmarks : numpy.ndarray, shape (L, 2)
        Landmark position estimates (L may be 0).
    landmark_edges : numpy.ndarray of int, shape (F, 2)
        Pose-landmark edges as rows ``(i, k)``: landmark k (row of ``landmarks``) seen from pose i.
    landmark_measurements : numpy.ndarray, shape (F, 2)
        The landmark's measured position in the frame of pose i.
    landmark_information : numpy.ndarray, shape (F, 2, 2)
        Their information matrices.
    pose_ids, landmark_ids : numpy.ndarray of int, shape (N,) and (L,)
        The g2o ids of the rows (default ``0..N-1`` and ``N..N+L-1``).
    fixed : numpy.ndarray of int
        Rows of ``poses`` that a ``FIX`` line holds still (empty: none written).
    """

    poses: np.ndarray
    edges: np.ndarray = _empty(0, 2, dtype=np.int64)
    measurements: np.ndarray = _empty(0, 3)
    information: np.ndarray = _empty(0, 3, 3)
    landmarks: np.ndarray = _empty(0, 2)
    landmark_edges: np.ndarray = _empty(0, 2, dtype=np.int64)
    landmark_measurements: np.ndarray = _empty(0, 2)
    landmark_information: np.ndarray = _empty(0, 2, 2)
    pose_ids: np.ndarray | None = None
    landmark_ids: np.ndarray | None = None
    fixed: np.ndarray = _empty(0, dtype=np.int64)

    def __post_init__(self) -> None:
        set_ = object.__setattr__  # frozen: normalise the fields once, here
        set_(self, "poses", _float("poses", self.poses, (None, 3)))
        n = self.poses.shape[0]
        set_(self, "landmarks", _float("landmarks", self.landmarks, (None, 2)))
        nl = self.landmarks.shape[0]
        set_(self, "edges", _index("edges", self.edges, n, n))
        set_(self, "measurements", _float("measurements", self.measurements, (len(self.edges), 3)))
        set_(self, "information", _information("information", self.information, len(self.edges), 3))
        set_(self, "landmark_edges", _index("landmark_edges", self.landmark_edges, n, nl))
        f = len(self.landmark_edges)
        set_(
            self,
            "landmark_measurements",
            _float("landmark_measurements", self.landmark_measurements, (f, 2)),
        )
        set_(
            self,
            "landmark_information",
            _information("landmark_information", self.landmark_information, f, 2),
        )
        pose_ids = np.arange(n) if self.pose_ids is None else self.pose_ids
        landmark_ids = np.arange(n, n + nl) if self.landmark_ids is None else self.landmark_ids
        set_(self, "pose_ids", _ids("pose_ids", pose_ids, n))
        set_(self, "landmark_ids", _ids("landmark_ids", landmark_ids, nl))
        if np.intersect1d(self.pose_ids, self.landmark_ids).size:
            raise G2oError("pose_ids and landmark_ids must not share an id")
        fixed = np.asarray(self.fixed, dtype=np.int64).reshape(-1)
        if fixed.size and (fixed.min() < 0 or fixed.max() >= n):
            raise G2oError(f"fixed must hold rows of poses in [0, {n}), got {fixed.tolist()}")
        set_(self, "fixed", fixed)

    @property
    def n_poses(self) -> int:
        return self.poses.shape[0]

    @property
    def n_landmarks(self) -> int:
        return self.landmarks.shape[0]

    @property
    def state_size(self) -> int:
        """Length of the stacked state ``[x_0, ..., x_{N-1}, l_0, ..., l_{L-1}]``: 3N + 2L."""
        return 3 * self.n_poses + 2 * self.n_landmarks

    def with_estimate(self, poses, landmarks=None) -> PoseGraph:
        """The same graph (edges, ids) with new vertex estimates; no array is shared with this one.

        Only the new estimate is checked: the edges were checked when this graph was
        made (a solver makes one graph per iteration).
        """
        lm = self.landmarks if landmarks is None else landmarks
        new_poses = _float("poses", poses, self.poses.shape)
        new_landmarks = _float("landmarks", lm, self.landmarks.shape)
        new = object.__new__(PoseGraph)
        for f in dataclasses.fields(self):
            object.__setattr__(new, f.name, np.array(getattr(self, f.name)))
        object.__setattr__(new, "poses", new_poses)
        object.__setattr__(new, "landmarks", new_landmarks)
        return new

    def copy(self) -> PoseGraph:
        """A deep copy: no array shared with this graph."""
        return dataclasses.replace(
            self, **{f.name: np.array(getattr(self, f.name)) for f in dataclasses.fields(self)}
        )


def _float(name, value, shape) -> np.ndarray:
    try:
        arr = np.array(value, dtype=float)  # a copy: the graph owns its arrays
    except (TypeError, ValueError) as exc:
        raise G2oError(f"{name} must be a numeric array, got {type(value).__name__}") from exc
    if arr.size == 0 and shape[0] in (None, 0):
        arr = arr.reshape((0,) + tuple(shape[1:]))
    if arr.ndim != len(shape) or any(
        s is not None and s != a for s, a in zip(shape, arr.shape, strict=True)
    ):
        want = "(" + ", ".join("N" if s is None else str(s) for s in shape) + ")"
        raise G2oError(f"{name} must have shape {want}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise G2oError(f"{name} must be finite (no NaN or inf)")
    return arr


def _index(name, value, n_from, n_to) -> np.ndarray:
    arr = np.array(value)
    if arr.size == 0:
        arr = arr.reshape(0, 2)
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise G2oError(f"{name} must have shape (E, 2), got {arr.shape}")
    if arr.dtype.kind not in "iu" and not (arr.dtype.kind == "f" and np.all(arr == np.round(arr))):
        raise G2oError(f"{name} must hold integer row indices, got dtype {arr.dtype}")
    arr = arr.astype(np.int64)
    bad = (arr[:, 0] < 0) | (arr[:, 0] >= n_from) | (arr[:, 1] < 0) | (arr[:, 1] >= n_to)
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        raise G2oError(
            f"{name}[{k}] = {arr[k].tolist()} is out of range (rows [0, {n_from}) and [0, {n_to}))"
        )
    return arr


def _bad_information(arr: np.ndarray) -> tuple[int, str] | None:
    """The first matrix of ``arr`` (E, d, d) not symmetric PSD, and why; None when all are."""
    if not len(arr):
        return None
    scale = np.maximum(np.abs(arr).max(axis=(1, 2)), 1.0)
    asym = np.abs(arr - np.swapaxes(arr, 1, 2)).max(axis=(1, 2)) > _PSD_TOL * scale
    if asym.any():
        return int(np.flatnonzero(asym)[0]), "is not symmetric"
    # PSD <=> every principal minor >= 0 (not only the leading ones); for d <= 3 the
    # minors are cheaper than eigenvalues, which matters when a solver makes a graph per step
    neg = np.zeros(len(arr), dtype=bool)
    for k in range(1, arr.shape[1] + 1):
        for subset in itertools.combinations(range(arr.shape[1]), k):
            minor = (
                np.linalg.det(arr[:, subset][:, :, subset])
                if k > 1
                else arr[:, subset[0], subset[0]]
            )
            neg |= minor < -_PSD_TOL * scale**k
    if neg.any():
        return int(np.flatnonzero(neg)[0]), (
            "is not positive semi-definite (an information matrix is the inverse of a covariance)"
        )
    return None


def _information(name, value, count, dim) -> np.ndarray:
    arr = _float(name, value, (count, dim, dim))
    bad = _bad_information(arr)
    if bad is not None:
        raise G2oError(f"{name}[{bad[0]}] {bad[1]}")
    return arr


def _ids(name, value, n) -> np.ndarray:
    arr = np.asarray(value).reshape(-1)
    if arr.shape != (n,) or (arr.size and arr.dtype.kind not in "iu"):
        raise G2oError(f"{name} must be {n} integers, got {arr.dtype} of shape {arr.shape}")
    arr = arr.astype(np.int64)
    if len(np.unique(arr)) != n:
        raise G2oError(f"{name} must be unique")
    return arr


def _upper_to_full(upper: np.ndarray, dim: int) -> np.ndarray:
    """``(E, dim (dim + 1) / 2)`` upper triangles, row by row, as symmetric ``(E, dim, dim)``."""
    rows, cols = np.triu_indices(dim)
    full = np.zeros((upper.shape[0], dim, dim))
    full[:, rows, cols] = upper
    full[:, cols, rows] = upper
    return full


def read_g2o(path) -> PoseGraph:
    """Read a g2o file of SE(2) poses and XY landmarks (module docstring).

    Parameters
    ----------
    path : str or pathlib.Path

    Returns
    -------
    PoseGraph
        Vertices sorted by id; edges in file order, as row indices.

    Raises
    ------
    FileNotFoundError
    G2oError
        A malformed line (wrong field count, a number that does not parse or is not
        finite, a non-integer or negative id), an unsupported element type, a vertex
        id defined twice, an edge naming a vertex that is not defined or of the wrong
        kind, or an information matrix that is not positive semi-definite. The
        message names the file and line.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"g2o file not found: {path}")
    vertices: dict[str, dict[int, tuple[int, list[float]]]] = {"VERTEX_SE2": {}, "VERTEX_XY": {}}
    rows: dict[str, list] = {"EDGE_SE2": [], "EDGE_SE2_XY": [], "FIX": []}
    with open(path, encoding="utf-8") as fh:
        for lineno, line in enumerate(fh, 1):
            tok = line.split()
            if not tok or tok[0].startswith("#"):
                continue
            tag, rest = tok[0], tok[1:]
            if tag not in _FIELDS:
                raise G2oError(
                    f"{path}:{lineno}: unsupported element type {tag!r} "
                    f"(this reader knows {', '.join(_FIELDS)})"
                )
            values = _parse(path, lineno, tag, rest)
            if tag in vertices:
                vid = values[0]
                for kind, table in vertices.items():
                    if vid in table:
                        raise G2oError(
                            f"{path}:{lineno}: vertex id {vid} is already defined "
                            f"(line {table[vid][0]}, {kind})"
                        )
                vertices[tag][vid] = (lineno, values[1:])
            else:
                rows[tag].append((lineno, values))
    poses_by_id, landmarks_by_id = vertices["VERTEX_SE2"], vertices["VERTEX_XY"]
    pose_ids = np.array(sorted(poses_by_id), dtype=np.int64)
    landmark_ids = np.array(sorted(landmarks_by_id), dtype=np.int64)
    pose_row = {int(v): r for r, v in enumerate(pose_ids)}
    landmark_row = {int(v): r for r, v in enumerate(landmark_ids)}

    def lookup(table, kind, lineno, vid):
        if vid not in table:
            other = "VERTEX_XY" if kind == "VERTEX_SE2" else "VERTEX_SE2"
            if vid in (landmark_row if kind == "VERTEX_SE2" else pose_row):
                raise G2oError(f"{path}:{lineno}: vertex {vid} is a {other}, expected a {kind}")
            raise G2oError(f"{path}:{lineno}: vertex {vid} is not defined by any {kind} line")
        return table[vid]

    pp = rows["EDGE_SE2"]
    edges = [
        (lookup(pose_row, "VERTEX_SE2", ln, v[0]), lookup(pose_row, "VERTEX_SE2", ln, v[1]))
        for ln, v in pp
    ]
    pl = rows["EDGE_SE2_XY"]
    landmark_edges = [
        (lookup(pose_row, "VERTEX_SE2", ln, v[0]), lookup(landmark_row, "VERTEX_XY", ln, v[1]))
        for ln, v in pl
    ]
    fixed = [lookup(pose_row, "VERTEX_SE2", ln, v[0]) for ln, v in rows["FIX"]]
    pp_values = np.array([v[2:] for _, v in pp], dtype=float).reshape(-1, 9)
    pl_values = np.array([v[2:] for _, v in pl], dtype=float).reshape(-1, 5)
    info = _upper_to_full(pp_values[:, 3:], 3)
    landmark_info = _upper_to_full(pl_values[:, 2:], 2)
    for name, matrices, lines in (("EDGE_SE2", info, pp), ("EDGE_SE2_XY", landmark_info, pl)):
        bad = _bad_information(matrices)
        if bad is not None:
            raise G2oError(f"{path}:{lines[bad[0]][0]}: {name}: the information matrix {bad[1]}")
    return PoseGraph(
        poses=np.array([poses_by_id[i][1] for i in pose_ids], dtype=float).reshape(-1, 3),
        edges=np.array(edges, dtype=np.int64).reshape(-1, 2),
        measurements=pp_values[:, :3],
        information=info,
        landmarks=np.array([landmarks_by_id[i][1] for i in landmark_ids], dtype=float).reshape(
            -1, 2
        ),
        landmark_edges=np.array(landmark_edges, dtype=np.int64).reshape(-1, 2),
        landmark_measurements=pl_values[:, :2],
        landmark_information=landmark_info,
        pose_ids=pose_ids,
        landmark_ids=landmark_ids,
        fixed=np.array(sorted(set(fixed)), dtype=np.int64),
    )


def _parse(path, lineno, tag, rest) -> list:
    """The fields of one line: ids as int, the rest as finite floats."""
    if len(rest) != _FIELDS[tag]:
        raise G2oError(f"{path}:{lineno}: {tag} needs {_FIELDS[tag]} fields, got {len(rest)}")
    n_ids = 2 if tag.startswith("EDGE") else 1
    out: list = []
    for k, text in enumerate(rest):
        if k < n_ids:
            try:
                vid = int(text)
            except ValueError:
                raise G2oError(
                    f"{path}:{lineno}: {tag}: a vertex id must be an integer, got {text!r}"
                ) from None
            if vid < 0:
                raise G2oError(f"{path}:{lineno}: {tag}: a vertex id must be >= 0, got {vid}")
            out.append(vid)
            continue
        try:
            value = float(text)
        except ValueError:
            raise G2oError(
                f"{path}:{lineno}: {tag}: field {k + 1} is not a number: {text!r}"
            ) from None
        if not np.isfinite(value):
            raise G2oError(f"{path}:{lineno}: {tag}: field {k + 1} must be finite, got {text!r}")
        out.append(value)
    return out


def write_g2o(graph: PoseGraph, path) -> Path:
    """Write ``graph`` in the g2o format (vertices by row, then edges; floats round-trip exactly).

    Returns the path written. ``read_g2o(write_g2o(g, p))`` gives back ``g``'s arrays.
    """
    if not isinstance(graph, PoseGraph):
        raise TypeError(f"graph must be a PoseGraph, got {type(graph).__name__}")
    path = Path(path)
    iu3, iu2 = np.triu_indices(3), np.triu_indices(2)
    r = repr  # shortest text that parses back to the same float
    lines = [
        f"VERTEX_SE2 {i} {' '.join(r(float(v)) for v in p)}"
        for i, p in zip(graph.pose_ids, graph.poses, strict=True)
    ]
    lines += [
        f"VERTEX_XY {i} {' '.join(r(float(v)) for v in p)}"
        for i, p in zip(graph.landmark_ids, graph.landmarks, strict=True)
    ]
    lines += [f"FIX {graph.pose_ids[k]}" for k in graph.fixed]
    for (i, j), z, om in zip(graph.edges, graph.measurements, graph.information, strict=True):
        values = list(z) + list(om[iu3])
        lines.append(
            f"EDGE_SE2 {graph.pose_ids[i]} {graph.pose_ids[j]} "
            + " ".join(r(float(v)) for v in values)
        )
    for (i, k), z, om in zip(
        graph.landmark_edges, graph.landmark_measurements, graph.landmark_information, strict=True
    ):
        values = list(z) + list(om[iu2])
        lines.append(
            f"EDGE_SE2_XY {graph.pose_ids[i]} {graph.landmark_ids[k]} "
            + " ".join(r(float(v)) for v in values)
        )
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path
