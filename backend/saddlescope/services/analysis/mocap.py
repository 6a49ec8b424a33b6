"""Use case: a motion-capture file (C3D or TRC) analysed as a ride, without cameras.

Three of the file's markers stand for the horse markers M1-M3 and a point is reported as the saddle
point S: another marker of the file (its place in the three markers' body frame is its median
over the frames where all four are seen), or a point given by its offsets (mm) from the three
markers' centroid in their body frame (x from the first marker to the second, z normal to the
three markers' plane, x x (third - first) direction, y = z x x). The lab's vertical is ``up``
("z", "-y", ...): given, else the file's own statement (C3D POINT:Y_SCREEN), else +z for C3D and
+y for TRC (OpenSim's convention). The kinematics and vibration stages then run as on a filmed ride
(:func:`saddlescope.core.saddle.saddle_kinematics`, :func:`~saddlescope.core.saddle.kinematics_indicators`)
and the result document gets a ``source`` object naming the file and these choices.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from saddlescope.core.errors import InputError, KinematicsError
from saddlescope.core.findings import Finding
from saddlescope.core.kinematics.saddle_point import body_frame
from saddlescope.core.params import PipelineParams
from saddlescope.core.pipeline.detection import RideTracks
from saddlescope.core.pipeline.result import assemble_result
from saddlescope.core.saddle import kinematics_indicators, saddle_kinematics
from saddlescope.core.types import MarkerTracks, Rig
from saddlescope.io.mocap import MocapData, read_mocap
from saddlescope.io.result_document import result_to_document
from saddlescope.io.result_schema import result_problems

__all__ = ["MocapChoice", "analyze_mocap", "analyze_mocap_file", "mocap_suffix", "parse_up_axis", "store_mocap_ride"]

_AXES = {"x": 0, "y": 1, "z": 2}


@dataclass(frozen=True)
class MocapChoice:
    """What to analyse in a motion-capture file.

    Attributes
    ----------
    markers : tuple of str, length 3
        The labels standing for the horse markers M1, M2, M3.
    point : str or None
        The label of the point to report as S, or None for a point given by ``offset_mm``.
    offset_mm : tuple of float, length 3
        With no ``point``: S's offsets from the three markers' centroid in their body frame (mm).
    up : str or None
        The lab's vertical ("z", "+z", "-y", ...), None for the file's own (see the module note).
    strides : int or None
        Whole strides analysed (None: the pipeline's default, 2).
    gait : str or None
        Narrows the stride frequencies searched (walk, sitting_trot, rising_trot, canter).
    """

    # Three each, as the file's user typed them: analyze_mocap checks the counts with a clear error.
    markers: tuple[str, ...]
    point: str | None = None
    offset_mm: tuple[float, ...] = (0.0, 0.0, 0.0)
    up: str | None = None
    strides: int | None = None
    gait: str | None = None


def parse_up_axis(text: str) -> tuple[int, float]:
    """The axis index and sign of an up direction such as "z", "+Z" or "-y".

    Parameters
    ----------
    text : str
        The direction.

    Returns
    -------
    tuple of (int, float)
        The axis index (0, 1, 2) and its sign (+1 or -1).
    """
    t = str(text).strip().lower()
    sign = -1.0 if t.startswith("-") else 1.0
    axis = t.lstrip("+-")
    if axis not in _AXES or len(t) - len(axis) > 1:
        raise InputError(f"the vertical axis must be x, y or z (optionally signed, e.g. -y), got {text!r}")
    return _AXES[axis], sign


def _up_of(data: MocapData, up: str | None) -> tuple[str, str]:
    """The vertical used ("+z") and why, as a short phrase."""
    if up:
        axis, sign = parse_up_axis(up)
        return f"{'+' if sign > 0 else '-'}{'xyz'[axis]}", "as asked"
    if data.up_axis:
        return data.up_axis, "as the file states (POINT:Y_SCREEN)"
    if data.source_format == "trc":
        return "+y", "OpenSim's convention for TRC files, which state none"
    return "+z", "the C3D default"


def _lab_to_rig(points_mm: np.ndarray, up: str) -> np.ndarray:
    """Rotation (3, 3) from lab axes to the pipeline's camera-like axes (x travel, y down, z lateral).

    ``points_mm`` (F, 3, 3) are the three markers: their centroid's horizontal displacement sets x.
    The analysis drops the lateral (camera depth) axis when it looks for the stride, as with cameras.
    """
    axis, sign = parse_up_axis(up)
    down = np.zeros(3)
    down[axis] = -sign
    seen = np.flatnonzero(np.all(np.isfinite(points_mm), axis=(1, 2)))
    centroid = points_mm[seen].mean(axis=1)
    travel = centroid[-1] - centroid[0] if seen.size >= 2 else np.zeros(3)
    travel = travel - (travel @ down) * down
    if np.linalg.norm(travel) < 1e-9:  # no travel: motion_frame says so later; any horizontal axis here
        travel = np.eye(3)[(axis + 1) % 3]
    x = travel / np.linalg.norm(travel)
    return np.vstack([x, down, np.cross(x, down)])


def _point_body_coordinates(data: MocapData, markers_mm: np.ndarray, choice: MocapChoice) -> tuple[np.ndarray, str]:
    """S relative to the markers' centroid in their body frame (3,) mm, and how it was defined."""
    if choice.point is None:
        offset = np.asarray(choice.offset_mm, dtype=np.float64).reshape(-1)
        if offset.shape != (3,) or not np.all(np.isfinite(offset)):
            raise InputError(f"the point's offsets must be three numbers (mm), got {choice.offset_mm!r}")
        return offset, "offsets from the markers' centroid in their body frame"
    if choice.point in choice.markers:
        raise InputError(f"the point {choice.point!r} is one of the three markers; choose another label or "
                         "give offsets from the markers' centroid")
    point = data.points[:, data.index(choice.point)] * (1000.0 if data.units == "m" else 1.0)
    both = np.all(np.isfinite(markers_mm), axis=(1, 2)) & np.all(np.isfinite(point), axis=1)
    if not both.any():
        raise InputError(f"the point {choice.point!r} is never seen with the three markers")
    R = body_frame(markers_mm[both])  # (F, 3, 3), columns = body axes
    rel = point[both] - markers_mm[both].mean(axis=1)
    return np.median(np.einsum("fji,fj->fi", R, rel), axis=0), f"the marker {choice.point!r}"


def _static_tracks(markers_rig: np.ndarray, body_mm: np.ndarray, t_s: np.ndarray) -> MarkerTracks:
    """A one-frame "static shot": the markers' median layout and S placed by its body coordinates."""
    seen = np.all(np.isfinite(markers_rig), axis=(1, 2))
    d = np.linalg.norm(markers_rig[seen][:, [0, 0, 1]] - markers_rig[seen][:, [1, 2, 2]], axis=2)
    ref = markers_rig[seen][int(np.argmin(np.sum((d - np.median(d, axis=0)) ** 2, axis=1)))]
    s = ref.mean(axis=0) + body_frame(ref) @ body_mm
    return MarkerTracks(("M1", "M2", "M3", "S"), np.array([float(t_s[0])]), np.vstack([ref, s])[None])


def _check_choice(data: MocapData, choice: MocapChoice) -> list[int]:
    if len(choice.markers) != 3 or len(set(choice.markers)) != 3:
        raise InputError(f"name three different markers for M1, M2, M3, got {list(choice.markers)}")
    if choice.strides is not None and not 1 <= int(choice.strides) <= 20:
        raise InputError(f"strides must be between 1 and 20, got {choice.strides}")
    return [data.index(label) for label in choice.markers]


def analyze_mocap(data: MocapData, choice: MocapChoice, *, params: PipelineParams | None = None) -> dict:
    """Analyse marker trajectories read from a motion-capture file as a ride.

    Parameters
    ----------
    data : MocapData
        The file's trajectories.
    choice : MocapChoice
        The three markers, the point, the vertical, the strides.
    params : PipelineParams, optional
        The analysis's choices (``choice.strides`` sets ``n_periods``).

    Returns
    -------
    dict
        The result document (CONTRACTS section 2, without cameras: empty ``calibration`` and ``sync``)
        with a ``source`` object: ``kind`` "mocap", ``format``, ``file``, ``markers``, ``point``,
        ``point_body_mm``, ``up``, ``up_reason``, ``units``, ``rate_hz``, ``warnings``.
    """
    t_start = time.perf_counter()
    params = params or PipelineParams()
    if choice.strides is not None:
        params = replace(params, n_periods=int(choice.strides))
    idx = _check_choice(data, choice)
    scale = 1000.0 if data.units == "m" else 1.0
    markers_mm = data.points[:, idx] * scale
    body_mm, point_text = _point_body_coordinates(data, markers_mm, choice)
    up, up_reason = _up_of(data, choice.up)
    rot = _lab_to_rig(markers_mm, up)
    markers_rig = markers_mm @ rot.T
    t_s = np.arange(data.n_frames) / data.rate_hz
    if not np.all(np.isfinite(markers_rig), axis=(1, 2)).any():
        raise InputError(f"the markers {', '.join(choice.markers)} are never seen together in the file")
    motion = MarkerTracks(("M1", "M2", "M3"), t_s, markers_rig)
    static = _static_tracks(markers_rig, body_mm, t_s)
    t0 = time.perf_counter()
    try:
        kin = saddle_kinematics(motion, static, None, params, horse_idx=[0, 1, 2], saddle_idx=3, gait=choice.gait,
                                down_hint=np.array([0.0, 1.0, 0.0]))
    except KinematicsError as exc:
        hint = " (or analyse fewer strides)" if "shorter than" in str(exc) else ""
        raise KinematicsError(f"{data.source}: {exc}{hint}") from None
    gravity = Finding("gravity.lab_vertical", f"gravity along the lab's vertical, {up} up ({up_reason})")
    # the lab's vertical is gravity: the down hint's finding does not apply
    kin = replace(kin, flags=tuple(f for f in kin.flags if f.code != "gravity.from_hint"),
                  frame=replace(kin.frame, gravity_source="lab_vertical"))
    timings = {"kinematics": round(time.perf_counter() - t0, 4)}
    t0 = time.perf_counter()
    harm, indicators = kinematics_indicators(kin, params)
    timings["indicators"] = round(time.perf_counter() - t0, 4)
    timings["total"] = round(time.perf_counter() - t_start, 4)
    found = RideTracks(tracks3d={"static": static, "motion": motion}, horse_idx=[0, 1, 2], saddle_idx=3)
    meta = {"gait": choice.gait, "direction": None}
    result = assemble_result(meta, Rig({}), {}, {}, found, kin, harm, indicators, float(data.rate_hz), timings,
                             params, list(kin.flags), list(data.warnings) + [gravity])
    document = result_to_document(result)
    document["source"] = {
        "kind": "mocap", "format": data.source_format, "file": data.source, "markers": list(choice.markers),
        "point": choice.point, "point_definition": point_text, "point_body_mm": [float(v) for v in body_mm],
        "up": up, "up_reason": up_reason, "units": data.units, "rate_hz": float(data.rate_hz),
        "frames": data.n_frames, "warnings": [str(w) for w in data.warnings]}
    document["quality"]["calibration_ok"] = None  # no cameras
    _validate(document)
    return document


def _validate(document: dict) -> None:
    """The result document's checks, but for the cameras' calibration and sync a mocap file has not."""
    problems = [p for p in result_problems(document)
                if not any(word in p for word in ("calibration", "sync"))]
    if problems:
        raise InputError("the mocap result document is invalid: " + "; ".join(problems[:5]))


def analyze_mocap_file(path: str | Path, markers: Sequence[str], *, point: str | None = None,
                       offset_mm: Sequence[float] = (0.0, 0.0, 0.0), up: str | None = None,
                       strides: int | None = None, gait: str | None = None) -> dict:
    """Read a C3D or TRC file and analyse it as a ride (see :func:`analyze_mocap`).

    Parameters
    ----------
    path : str or Path
        The file.
    markers : sequence of 3 str
        The labels standing for M1, M2, M3.
    point, offset_mm, up, strides, gait
        See :class:`MocapChoice`.

    Returns
    -------
    dict
        The result document with its ``source``.
    """
    choice = MocapChoice(tuple(markers), point, tuple(float(v) for v in offset_mm), up, strides, gait)
    return analyze_mocap(read_mocap(path), choice)


_SUFFIXES = (".c3d", ".trc")


def mocap_suffix(filename: str | None) -> str:
    """The file type (".c3d" or ".trc") of an uploaded file's name, or an InputError saying what is accepted."""
    suffix = Path(filename or "").suffix.lower()
    if suffix not in _SUFFIXES:
        raise InputError(f"the file {filename or '(no name)'!r} is not a motion-capture file: send a .c3d or .trc "
                         "file (its name tells which)")
    return suffix


def store_mocap_ride(sessions, storage, staged_key: str, filename: str | None, choice: MocapChoice, *,
                     club_id: int, ride: dict, code_version: str | None = None) -> int:
    """Analyse an uploaded C3D or TRC file and store it as an analysed ride of the club.

    Parameters
    ----------
    sessions : sessionmaker
        The database's sessions.
    storage : Storage
        Files; the upload is at ``staged_key`` (removed here).
    staged_key : str
        Where the uploaded bytes are.
    filename : str or None
        The client's file name (its extension says C3D or TRC).
    choice : MocapChoice
        The markers, point, vertical and strides.
    club_id : int
        The club the ride belongs to.
    ride : dict
        ``horse_id``, ``rider_id``, ``gait``, ``direction``, ``ridden_on``, ``notes`` of the new ride.
    code_version : str, optional
        Stored with the result.

    Returns
    -------
    int
        The new ride's id. Nothing is stored when the file is refused (the error says why).
    """
    import tempfile

    from saddlescope.db.repositories import RideRepository
    from saddlescope.db.session import session_scope
    from saddlescope.services.results.documents import commit_result

    try:
        suffix = mocap_suffix(filename)
        name = Path(filename or "upload").stem[:80] or "upload"
        with tempfile.TemporaryDirectory(prefix="mocap-") as tmp:
            local = Path(tmp) / f"{name}{suffix}"
            storage.fetch(staged_key, local)
            document = analyze_mocap(read_mocap(local), replace(choice, gait=choice.gait or ride.get("gait")))
            data = local.read_bytes()
    finally:
        storage.delete(staged_key)
    with session_scope(sessions) as session:
        row = RideRepository(session, club_id=club_id).add(
            horse_id=ride["horse_id"], rider_id=ride["rider_id"], gait=ride["gait"], direction=ride["direction"],
            ridden_on=ride["ridden_on"], notes=ride.get("notes") or "",
            meta={"source": document["source"], "_created_by": ride.get("created_by")},
            saddle_id=ride.get("saddle_id"), pad=ride.get("pad"), rider_weight_kg=ride.get("rider_weight_kg"))
        ride_id = row.id
    file_key = f"rides/{ride_id}/mocap/{name}{suffix}"
    storage.write_bytes(file_key, data)
    document["source"]["stored_as"] = file_key
    # the one writer of results: the indicators' columns and the too-uncertain verdict derived as for video
    commit_result(sessions, storage, club_id=club_id, ride_id=ride_id, job_id=None, document=document,
                  code_version=code_version)
    return ride_id
