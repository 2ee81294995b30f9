"""Their world and ours: an HPS tool's own gravity-aware world (WHAM's, GVHMR's ``tool_world_*`` frame keys)
against rotavat's camera (camera.yaml's up vector and ground) and its aligned people.

The tool gives each person-frame its root orientation twice, in the camera frame (``R_cam_root``) and in its
world (``R_world_root``); the body is the same, so ``R_theirworld_from_cam = R_world_root R_cam_rootᵀ`` and
its up axis in the camera frame is ``R_theirworld_from_camᵀ up_theirs``. With a static camera that vector is
one vector, the ground normal the tool believes in:

- :func:`their_up_cam` and :func:`angles_deg`: its angle to camera.yaml's ``up_cam``, per person-frame;
- :func:`wander_deg`: how far it moves about its own mean over a track (a static camera's should not);
- :func:`heading_fit`: their pelvis path against ours (world frames), after removing what no one can know
  of their world, its origin and heading: a rotation about the vertical and a translation, least squares,
  **no scale**, per track (each WHAM track has its own world). Their up is taken as their vertical, so a
  tilt between the worlds stays in the residual;
- :func:`tool_world_report`: all of it for a sequence (the input, its aligned output and the camera), a
  JSON-able dict with one row per track.

Pure numpy, vectorised over person-frames and tracks (``np.bincount`` sums); the report reads frames one
at a time. Angles are degrees at the report, radians nowhere here (no angle is taken in).

>>> up = their_up_cam(np.array([[np.pi, 0.0, 0.0]]), np.zeros((1, 3)), (0.0, 1.0, 0.0))
>>> np.round(up, 12).tolist()          # upside down in the camera, upright in their world: their up is -y
[[0.0, -1.0, 0.0]]
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence as Seq

import numpy as np

from ..geometry.camera import Camera
from ..geometry.rotations import axis_angle_to_matrix, rotation_between
from ..sequence import Sequence

__all__ = ["TOOL_WORLD_KEYS", "FIT", "their_up_cam", "angles_deg", "wander_deg", "heading_fit", "path_lengths_m",
           "spreads_m", "pelvis_cam", "tool_world_report", "tool_world_tracks", "tool_world_reports",
           "TOOL_WORLD_COLUMNS", "tool_world_markdown", "tool_world_line"]

# The per-person frame keys of a tool's world (docs/conventions.md, NPZ frames): orientations, then points.
TOOL_WORLD_KEYS = ("tool_cam_global_orient", "tool_world_global_orient", "tool_world_transl", "tool_world_pelvis")
FIT = ("heading and origin per track: a rotation about the vertical (their up onto ours) and a translation, "
       "least squares, no scale")
_WORLD_UP = np.array([0.0, 1.0, 0.0])  # rotavat's world: Y up (docs/conventions.md, "World frame")


# ---- pure functions ------------------------------------------------------------------------------------------
def _matrices(rotvec: np.ndarray) -> np.ndarray:
    """Axis-angle (..., 3) -> rotation matrices (..., 3, 3), float64."""
    rotvec = np.asarray(rotvec, dtype=np.float64)
    return axis_angle_to_matrix(rotvec, np.linalg.norm(rotvec, axis=-1))


def their_up_cam(root_cam: np.ndarray, root_world: np.ndarray, up_axis: Seq[float]) -> np.ndarray:
    """The tool's up in the camera frame, (N, 3) unit, from each person-frame's root orientation in the camera
    ``root_cam`` (N, 3) and in the tool's world ``root_world`` (N, 3) (axis-angle) and the tool's up axis (3,)
    in its world: ``R_theirworld_from_camᵀ up`` with ``R_theirworld_from_cam = R_world_root R_cam_rootᵀ``."""
    world_from_cam = _matrices(root_world) @ np.swapaxes(_matrices(root_cam), -1, -2)
    up = np.asarray(up_axis, dtype=np.float64)
    return np.einsum("nji,j->ni", world_from_cam, up / np.linalg.norm(up))


def angles_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angles (...,) in degrees between directions (..., 3) ``a`` and ``b`` (any length, broadcast); NaN for a zero
    vector. atan2 of the cross and dot products: exact near 0 and 180 degrees.

    >>> angles_deg(np.array([0.0, 1.0, 0.0]), np.array([[0.0, 1.0, 0.0], [0.0, 1.0, 1.0]])).round(9).tolist()
    [0.0, 45.0]
    """
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    cross = np.linalg.norm(np.cross(a, b), axis=-1)
    dot = np.sum(a * b, axis=-1)
    zero = (np.linalg.norm(a, axis=-1) == 0) | (np.linalg.norm(b, axis=-1) == 0)
    return np.where(zero, np.nan, np.degrees(np.arctan2(cross, dot)))


def _group_sums(values: np.ndarray, group: np.ndarray, n_groups: int) -> np.ndarray:
    """Per-group sums (G, C) of (N, C) ``values`` by (N,) group index."""
    values = np.asarray(values, dtype=np.float64).reshape(len(group), -1)
    return np.stack([np.bincount(group, values[:, c], minlength=n_groups) for c in range(values.shape[1])], axis=1)


def wander_deg(up_cam: np.ndarray, group: np.ndarray | None = None) -> np.ndarray:
    """(N,) degrees of each (N, 3) up vector from its group's mean direction (``group``: (N,) track index, one
    group without): how much a tool's up moves over a track. A static camera's is one vector: 0."""
    up = np.asarray(up_cam, dtype=np.float64)
    group = np.zeros(len(up), np.int64) if group is None else np.asarray(group, dtype=np.int64)
    if not len(up):
        return np.zeros(0)
    unit = up / np.linalg.norm(up, axis=-1, keepdims=True)
    mean = _group_sums(unit, group, int(group.max()) + 1)
    return angles_deg(unit, mean[group])


def _level(up_axis: Seq[float]) -> np.ndarray:
    """(3, 3) the shortest rotation taking ``up_axis`` onto +Y (a half turn about X for -Y)."""
    up = np.asarray(up_axis, dtype=np.float64)
    up = up / np.linalg.norm(up)
    if np.dot(up, _WORLD_UP) < -1.0 + 1e-12:
        return np.diag([1.0, -1.0, -1.0])
    axis, angle = rotation_between(up, _WORLD_UP)
    return axis_angle_to_matrix(axis, angle)


def heading_fit(theirs: np.ndarray, ours: np.ndarray, group: np.ndarray | None = None,
                up_axis: Seq[float] = (0.0, 1.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    """Per group (track), the rigid map ``ours ≈ R @ theirs + t`` without scale whose rotation turns their up
    onto rotavat's (+Y) and then only about it (the heading), least squares: (G, 3, 3) ``R`` and (G, 3) ``t``.

    theirs: (N, 3) points in the tool's world (its up ``up_axis``); ours: (N, 3) the same person-frames in
    rotavat's world (Y up), metres; group: (N,) group index 0..G-1 (one group without). A group whose path
    has no horizontal extent keeps heading 0.

    >>> theirs = np.array([[0.0, 1.0, 0.0], [1.0, 1.0, 0.0], [1.0, 1.0, 2.0]])
    >>> turn = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])        # 90 degrees about +Y
    >>> R, t = heading_fit(theirs, theirs @ turn.T + [3.0, -1.0, 5.0])
    >>> np.allclose(R[0], turn), np.round(t[0], 12).tolist()
    (True, [3.0, -1.0, 5.0])
    """
    theirs, ours = np.asarray(theirs, dtype=np.float64), np.asarray(ours, dtype=np.float64)
    group = np.zeros(len(theirs), np.int64) if group is None else np.asarray(group, dtype=np.int64)
    n_groups = int(group.max()) + 1 if len(group) else 0
    level = _level(up_axis)
    a = theirs @ level.T
    count = np.maximum(np.bincount(group, minlength=n_groups), 1)[:, None]
    ca, cb = _group_sums(a, group, n_groups) / count, _group_sums(ours, group, n_groups) / count
    da, db = a - ca[group], ours - cb[group]
    # R_y(h) = [[cos, 0, sin], [0, 1, 0], [-sin, 0, cos]]: sum(db . R_y da) = cos h S_dot + sin h S_cross
    s_dot = np.bincount(group, db[:, 0] * da[:, 0] + db[:, 2] * da[:, 2], minlength=n_groups)
    s_cross = np.bincount(group, db[:, 0] * da[:, 2] - db[:, 2] * da[:, 0], minlength=n_groups)
    heading = np.arctan2(s_cross, s_dot)
    c, s = np.cos(heading), np.sin(heading)
    zero, one = np.zeros_like(c), np.ones_like(c)
    yaw = np.stack([np.stack([c, zero, s], -1), np.stack([zero, one, zero], -1), np.stack([-s, zero, c], -1)], -2)
    R = yaw @ level
    t = cb - np.einsum("gij,gj->gi", yaw, ca)
    return R, t


def path_lengths_m(points: np.ndarray, group: np.ndarray | None = None) -> np.ndarray:
    """(G,) length (m) of each group's path: the sum of the steps between its consecutive rows of (N, 3)
    ``points`` (a group's rows in time order, groups interleaved or not; ``group``: (N,) index 0..G-1, one
    group without).

    >>> path_lengths_m(np.array([[0.0, 0, 0], [9, 9, 9], [3, 4, 0], [9, 9, 10]]), np.array([0, 1, 0, 1])).tolist()
    [5.0, 1.0]
    """
    p = np.asarray(points, dtype=np.float64)
    group = np.zeros(len(p), np.int64) if group is None else np.asarray(group, dtype=np.int64)
    n_groups = int(group.max()) + 1 if len(group) else 0
    if len(p) < 2:
        return np.zeros(n_groups)
    order = np.argsort(group, kind="stable")  # each group's rows together, in their order
    p, group = p[order], group[order]
    steps = np.linalg.norm(np.diff(p, axis=0), axis=-1)
    same = group[1:] == group[:-1]
    return np.bincount(group[1:][same], steps[same], minlength=n_groups)


def spreads_m(points: np.ndarray, group: np.ndarray | None = None) -> np.ndarray:
    """(G,) each group's spread (m): the RMS distance of its (N, 3) ``points`` from their centroid. Unlike a path's
    length it barely grows with frame-to-frame jitter, so the ratio of two spreads is the scale between two paths.

    >>> spreads_m(np.array([[0.0, 0, 0], [2, 0, 0], [5, 5, 5], [5, 5, 5]]), np.array([0, 0, 1, 1])).tolist()
    [1.0, 0.0]
    """
    p = np.asarray(points, dtype=np.float64)
    group = np.zeros(len(p), np.int64) if group is None else np.asarray(group, dtype=np.int64)
    n_groups = int(group.max()) + 1 if len(group) else 0
    count = np.maximum(np.bincount(group, minlength=n_groups), 1)
    centre = _group_sums(p, group, n_groups) / count[:, None]
    return np.sqrt(np.bincount(group, np.sum((p - centre[group]) ** 2, axis=1), minlength=n_groups) / count)


def _stats(values: np.ndarray) -> dict[str, float] | None:
    """{median, p90, max} of the finite ``values``, floats; None when there is none."""
    v = np.asarray(values, dtype=np.float64)
    v = v[np.isfinite(v)]
    if not len(v):
        return None
    return {"median": float(np.median(v)), "p90": float(np.percentile(v, 90)), "max": float(v.max())}


# ---- a sequence's numbers --------------------------------------------------------------------------------------
def pelvis_cam(frame_data: Mapping[str, np.ndarray]) -> np.ndarray | None:
    """(P, 3) the frame's root joint, camera frame: ``smpl_pelvis``, else joint 0 of ``joints``, else None."""
    if frame_data.get("smpl_pelvis") is not None:
        return np.asarray(frame_data["smpl_pelvis"], dtype=np.float64)
    joints = frame_data.get("joints")
    return None if joints is None else np.asarray(joints[:, 0], dtype=np.float64)


def tool_world_tracks(seq: Sequence) -> dict[str, np.ndarray] | None:
    """Every person-frame of ``seq`` with a tool's world, as columns (rows in frame order): ``frame`` (N,) frame
    index in ``seq.frame_names``, ``person_id`` (N,), ``root_cam``, ``root_world`` (N, 3) axis-angle,
    ``pelvis_theirs`` (N, 3) (NaN without ``tool_world_pelvis``), ``pelvis_cam`` (N, 3) this sequence's root
    joint (NaN without one) and ``low_cam`` (N,): its lowest vertex's height above its pelvis along their up
    (NaN without vertices). None when no frame has the tool's keys."""
    meta = (seq.meta or {}).get("tool_world") or {}
    if not meta:  # import writes the block whenever it keeps a tool's world (align copies it): no frame to read
        return None
    up_axis = meta.get("up_axis", (0.0, 1.0, 0.0))
    cols: dict[str, list] = {k: [] for k in ("frame", "person_id", "root_cam", "root_world", "pelvis_theirs",
                                             "pelvis_cam", "low_cam")}
    for index, name in enumerate(seq.frame_names):
        frame = seq.read_frame(name)
        data = frame.data
        P = frame.n_people
        if not P or data.get("tool_world_global_orient") is None or data.get("tool_cam_global_orient") is None:
            continue
        nan3 = np.full((P, 3), np.nan)
        pelvis = pelvis_cam(data)
        up = their_up_cam(data["tool_cam_global_orient"], data["tool_world_global_orient"], up_axis)
        verts = data.get("vertices")
        low = np.full(P, np.nan)
        if verts is not None and pelvis is not None and verts.shape[1]:
            low = np.einsum("pvc,pc->pv", np.asarray(verts, dtype=np.float64) - pelvis[:, None], up).min(axis=1)
        cols["frame"].append(np.full(P, index))
        cols["person_id"].append(frame.person_ids)
        cols["root_cam"].append(np.asarray(data["tool_cam_global_orient"], dtype=np.float64))
        cols["root_world"].append(np.asarray(data["tool_world_global_orient"], dtype=np.float64))
        cols["pelvis_theirs"].append(np.asarray(data.get("tool_world_pelvis", nan3), dtype=np.float64))
        cols["pelvis_cam"].append(nan3 if pelvis is None else pelvis)
        cols["low_cam"].append(low)
    if not cols["frame"]:
        return None
    return {k: np.concatenate(v) for k, v in cols.items()}


def _ours_world(aligned: Sequence, camera: Camera, frames: np.ndarray, ids: np.ndarray,
                names: tuple[str, ...]) -> np.ndarray:
    """(N, 3) the aligned sequence's root joint (world) for each (frame index into ``names``, person id); NaN where
    it has no such frame, person or root joint."""
    out = np.full((len(frames), 3), np.nan)
    for index in np.unique(frames):
        name = names[index]
        if name not in aligned.frame_names:
            continue
        frame = aligned.read_frame(name)
        pelvis = pelvis_cam(frame.data)
        if pelvis is None or not frame.n_people:
            continue
        rows = np.flatnonzero(frames == index)
        where = {int(pid): p for p, pid in enumerate(frame.person_ids)}
        picks = np.array([where.get(int(pid), -1) for pid in ids[rows]])
        found = picks >= 0
        out[rows[found]] = camera.world_from_cam(pelvis[picks[found]])
    return out


def tool_world_report(input_seq: Sequence, aligned_seq: Sequence | None = None,
                      camera: Camera | None = None) -> dict | None:
    """Their world against ours, for one sequence: a JSON-able dict, or None when ``input_seq`` holds no tool world.

    input_seq: the import (WHAM, GVHMR: ``tool_*`` keys and meta.yaml's ``tool_world``), read for the tool's
    orientations, its pelvis path and (when it is not itself an aligned sequence) its bodies, for their ground;
    aligned_seq: its ``rotavat align`` output (rotavat's pelvis path in the world), or None; camera: rotavat's
    camera (its ``up_cam``; default the aligned sequence's camera.yaml, else the input's).

    Keys: ``tool``, ``up_axis``, ``person_frames``, ``tracks``; ``up_angle_deg`` {median, p90, max}: their up
    against camera.yaml's per person-frame; ``up_wander_deg`` {median, p90, max}: each person-frame's up
    against its track's mean (a static camera: 0); ``trajectory`` (None without both pelvis paths): ``fit``
    (:data:`FIT`), ``person_frames``, ``rms_m`` (pooled over tracks), ``path_length_ratio`` (median over
    tracks of their path's length over ours: jitter lengthens a path) and ``spread_ratio`` (the same of
    :func:`spreads_m`: the scale between the paths); ``pelvis_height_m`` (None without bodies): medians ``theirs``
    (above their ground, the track's lowest vertex along their up, as their renderers put it) and ``ours``
    (above rotavat's ground, world Y) and ``difference`` (theirs − ours); ``per_track``: one row per person
    id; ``notes``: what could not be measured and why.
    """
    cols = tool_world_tracks(input_seq)
    if cols is None:
        return None
    camera = camera or (aligned_seq.camera if aligned_seq is not None else None) or input_seq.camera
    meta = (input_seq.meta or {}).get("tool_world") or {}
    up_axis = [float(v) for v in meta.get("up_axis", (0.0, 1.0, 0.0))]
    notes: list[str] = []
    ids, group = np.unique(cols["person_id"], return_inverse=True)
    n_tracks = len(ids)
    up_cam = their_up_cam(cols["root_cam"], cols["root_world"], up_axis)
    angle = angles_deg(up_cam, camera.up_cam) if camera is not None else np.full(len(group), np.nan)
    if camera is None:
        notes.append("no camera.yaml: neither the angle to rotavat's up nor rotavat's path is measured")
    wander = wander_deg(up_cam, group)

    ours = np.full((len(group), 3), np.nan)
    if aligned_seq is not None and camera is not None:
        ours = _ours_world(aligned_seq, camera, cols["frame"], cols["person_id"], input_seq.frame_names)
    elif aligned_seq is None:
        notes.append("no aligned sequence: their path is not compared with rotavat's")
    theirs = cols["pelvis_theirs"]
    paired = np.isfinite(theirs).all(axis=1) & np.isfinite(ours).all(axis=1)
    if not np.isfinite(theirs).all(axis=1).any():
        notes.append("no tool_world_pelvis (import with --smpl-model): their path is not compared")

    up = np.asarray(up_axis) / np.linalg.norm(up_axis)
    height_theirs = np.full(len(group), np.nan)
    if "aligned_from" in (input_seq.meta or {}):
        notes.append("the input is an aligned sequence: its bodies are rotavat's, so their ground is not measured")
    elif np.isfinite(cols["low_cam"]).any() and np.isfinite(theirs).all(axis=1).any():
        along = theirs @ up  # their pelvis along their up
        lowest = np.where(np.isfinite(along + cols["low_cam"]), along + cols["low_cam"], np.inf)
        ground = np.full(n_tracks, np.inf)
        np.minimum.at(ground, group, lowest)
        height_theirs = along - np.where(np.isfinite(ground), ground, np.nan)[group]
    height_ours = ours[:, 1]

    rows = []
    rms_sq, ratio, spread, headings = (np.full(n_tracks, np.nan) for _ in range(4))
    len_theirs, len_ours = np.full(n_tracks, np.nan), np.full(n_tracks, np.nan)
    if paired.any():
        sel = np.flatnonzero(paired)
        g = group[sel]
        R, t = heading_fit(theirs[sel], ours[sel], g, up_axis)
        fitted = np.einsum("nij,nj->ni", R[g], theirs[sel]) + t[g]
        sq = np.sum((fitted - ours[sel]) ** 2, axis=1)
        n = np.bincount(g, minlength=n_tracks)
        rms_sq = np.where(n > 0, np.bincount(g, sq, minlength=n_tracks) / np.maximum(n, 1), np.nan)
        tracked = n > 0
        len_theirs = np.where(tracked, path_lengths_m(theirs[sel], g), np.nan)
        len_ours = np.where(tracked, path_lengths_m(ours[sel], g), np.nan)
        spread_ours = spreads_m(ours[sel], g)
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = np.where((n > 1) & (len_ours > 0), len_theirs / len_ours, np.nan)
            spread = np.where((n > 1) & (spread_ours > 0), spreads_m(theirs[sel], g) / spread_ours, np.nan)
        headings = np.where(tracked, np.degrees(np.arctan2(R[:, 0, 2], R[:, 0, 0])), np.nan)
    for k, pid in enumerate(ids.tolist()):  # the rows: the numbers above, per track
        mine = group == k
        rows.append({"person_id": int(pid), "frames": int(mine.sum()),
                     "up_angle_deg_median": _median(angle[mine]), "up_wander_deg_max": _max(wander[mine]),
                     "paired_frames": int((mine & paired).sum()), "rms_m": _float(np.sqrt(rms_sq[k])),
                     "heading_deg": _float(headings[k]), "path_length_theirs_m": _float(len_theirs[k]),
                     "path_length_ours_m": _float(len_ours[k]), "path_length_ratio": _float(ratio[k]),
                     "spread_ratio": _float(spread[k]),
                     "pelvis_height_theirs_m": _median(height_theirs[mine]),
                     "pelvis_height_ours_m": _median(height_ours[mine])})

    trajectory = None
    if paired.any():
        trajectory = {"fit": FIT, "person_frames": int(paired.sum()),
                      "rms_m": float(np.sqrt(np.nansum(rms_sq * np.bincount(group[paired], minlength=n_tracks))
                                             / paired.sum())),
                      "path_length_ratio": _median(ratio), "spread_ratio": _median(spread)}
    heights = None
    both = np.isfinite(height_theirs) & np.isfinite(height_ours)
    if np.isfinite(height_theirs).any():
        heights = {"theirs": _median(height_theirs), "ours": _median(height_ours),
                   "difference": _median(height_theirs[both] - height_ours[both])}
    return {"tool": meta.get("tool"), "up_axis": up_axis, "person_frames": int(len(group)), "tracks": int(n_tracks),
            "up_angle_deg": _stats(angle), "up_wander_deg": _stats(wander), "trajectory": trajectory,
            "pelvis_height_m": heights, "per_track": rows, "notes": notes}


def _float(value: float) -> float | None:
    """A finite float, else None (JSON has no NaN)."""
    return float(value) if np.isfinite(value) else None


def _median(values: np.ndarray) -> float | None:
    v = np.asarray(values, dtype=np.float64)
    v = v[np.isfinite(v)]
    return float(np.median(v)) if len(v) else None


def _max(values: np.ndarray) -> float | None:
    v = np.asarray(values, dtype=np.float64)
    v = v[np.isfinite(v)]
    return float(v.max()) if len(v) else None


# metrics.md's columns of a report: (column, report field, sub-field), in order.
TOOL_WORLD_COLUMNS = (("their_up_deg", "up_angle_deg", "median"), ("their_up_p90_deg", "up_angle_deg", "p90"),
                      ("their_up_wander_deg", "up_wander_deg", "max"), ("their_path_rms_m", "trajectory", "rms_m"),
                      ("their_path_spread", "trajectory", "spread_ratio"),
                      ("their_path_length", "trajectory", "path_length_ratio"),
                      ("their_pelvis_h_m", "pelvis_height_m", "theirs"), ("our_pelvis_h_m", "pelvis_height_m", "ours"))


def tool_world_reports(seqs: Seq[Sequence], camera: Camera | None = None,
                       camera_from: str | None = None) -> list[dict | None]:
    """:func:`tool_world_report` of each of ``seqs`` (None for one without a tool's world), as ``rotavat eval``
    pairs them: an aligned sequence (meta.yaml ``aligned_from``) with itself, any other with the first aligned
    sequence given alongside (its align output), else alone. ``camera``: the camera their up is measured
    against (the ground truth's, named ``camera_from``), default the aligned partner's, else the sequence's own.
    Each report gains ``camera_from`` (``aligned``, ``own``, or the given name)."""
    aligned = [seq for seq in seqs if (seq.meta or {}).get("aligned_from") is not None]
    reports: list[dict | None] = []
    for seq in seqs:
        partner = seq if any(seq is a for a in aligned) else (aligned[0] if aligned else None)
        report = tool_world_report(seq, partner, camera)
        if report is not None:
            report["camera_from"] = (camera_from if camera is not None else
                                     "aligned" if partner is not None and partner.camera is not None else
                                     "own" if seq.camera is not None else None)
        reports.append(report)
    return reports


def _cell(report: dict, field: str, sub: str) -> float | None:
    """One number of a report, None where it was not measured."""
    block = report.get(field)
    return None if not isinstance(block, dict) else block.get(sub)


def tool_world_markdown(rows: Seq[tuple[str, dict | None]]) -> list[str]:
    """metrics.md lines of the reports of ``rows`` ((label, report)): a table, [] when no row has a report."""
    rows = [(label, report) for label, report in rows if report is not None]
    if not rows:
        return []
    lines = ["", "Their world and ours: the tool's own gravity-aware world (WHAM, GVHMR) against rotavat's camera "
             "and aligned people (docs/formats.md, \"Their world and ours\"; empty: not measured):", "",
             "| sequence | tool | camera | " + " | ".join(c for c, _, _ in TOOL_WORLD_COLUMNS) + " |",
             "|---" * (3 + len(TOOL_WORLD_COLUMNS)) + "|"]
    for label, report in rows:
        cells = [_cell(report, field, sub) for _, field, sub in TOOL_WORLD_COLUMNS]
        lines.append(f"| `{label}` | {report.get('tool')} | {report.get('camera_from') or '–'} | "
                     + " | ".join("" if v is None else f"{v:.2f}" for v in cells) + " |")
    return lines


def tool_world_line(label: str, report: dict) -> str:
    """One sentence of a report for the terminal."""
    up = report.get("up_angle_deg") or {}
    words = [f"{label}: {report.get('tool')}'s own world"]
    if up.get("median") is not None:
        words.append(f"its up {up['median']:.1f}° from rotavat's (p90 {up['p90']:.1f}°)")
    traj = report.get("trajectory") or {}
    if traj.get("rms_m") is not None:
        words.append(f"its pelvis path {traj['rms_m']:.2f} m RMS from rotavat's after a heading fit")
    return ", ".join(words)
