"""Use cases of results: a ride's indicators and plotted series, and its exports (JSON, CSV, xlsx, C3D, TRC)."""

from __future__ import annotations

import datetime as dt
import hashlib
import io
import json
import logging
import math
import re
import secrets
import tempfile
import threading
from collections import OrderedDict
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any, TypeVar

import numpy as np
from sqlalchemy.orm import Session, sessionmaker

from saddlescope.core.errors import InputError
from saddlescope.core.vibration import indicator_unit
from saddlescope.db.models import Result
from saddlescope.db.repositories import (
    AnalyticsRepository,
    HorseRepository,
    NotFound,
    ResultRepository,
    RideFilter,
    RideRepository,
)
from saddlescope.db.session import session_scope
from saddlescope.services.results.passes_view import passes_view
from saddlescope.services.results.quality_notes import document_findings, quality_notes, quality_summary
from saddlescope.services.results.series import DERIVED_FORMAT, DERIVED_SERIES, derived_series, strides_analysed
from saddlescope.services.rides.registration import refresh_ride_status
from saddlescope.storage import Storage

__all__ = [
    "ANGULAR_PER_FRAME", "DERIVED_SERIES", "EXPORT_FORMATS", "MARKER_LABELS", "SADDLE_LABEL", "SERIES", "TABLE_FORMATS",
    "commit_result", "decimate", "export_horse", "export_ride", "export_rides", "indicator_table_bytes",
    "PAGE_POINTS", "page_key", "page_of_document", "result_document", "series_key", "store_with_result",
    "stored_derived_series", "view_of_page",
    "analysed_result", "result_view", "result_view_json", "tracks_mm", "uncertain_reason_of", "view_of_document",
]

log = logging.getLogger(__name__)

EXPORT_FORMATS = {
    "json": "application/json",
    "csv": "text/csv; charset=utf-8",
    "xlsx": "application/vnd.openxmlformats-officedocument.spreadsheetml.sheet",
    "c3d": "application/octet-stream",
    "trc": "text/plain; charset=utf-8",
}
TABLE_FORMATS = ("csv", "xlsx")
SERIES = (
    ("t_s", "saddle", "t_s"),
    ("position_m", "saddle", "position_m"),
    ("velocity_m_s", "saddle", "velocity_m_s"),
    ("acceleration_m_s2", "saddle", "acceleration_m_s2"),
    ("omega_rad_s", "angular", "omega_rad_s"),
    ("alpha_rad_s2", "angular", "alpha_rad_s2"),
)
# DERIVED_SERIES (services/results/series.py: S's fitted position, measured velocity and acceleration and
# the residuals, the weighted vertical acceleration ...): always in the view, None when the result cannot give them.
# Per-frame series of the angular kinematics, served when the result has them.
ANGULAR_PER_FRAME = ("omega_versions_rad_s", "omega_versions_excluded", "singularity_index_per_frame")
MARKER_LABELS = ("M1", "M2", "M3")
SADDLE_LABEL = "S"


def result_document(session: Session, storage: Storage, ride_id: int, *, club_id: int) -> dict[str, Any]:
    """The full stored result document (CONTRACTS section 2) of an analysed ride of the club."""
    return _read_analysed(session, ride_id, club_id, lambda _result, key: json.loads(storage.read_bytes(key)))


def decimate(values: list, step: int) -> list:
    """Every `step`-th item of `values` (all of them for a step of 1)."""
    return values[::step] if step > 1 else values


def _series(doc: dict[str, Any], step: int, n: int, derived: dict[str, Any]) -> dict[str, list | None]:
    """The plotted series of the document and its `derived` series, every `step`-th of its `n` samples."""
    series: dict[str, list | None] = {
        name: decimate((doc.get(group) or {}).get(key) or [], step) for name, group, key in SERIES
    }
    markers = doc.get("markers") or {}
    if markers.get("position_m"):
        series["markers_position_m"] = decimate(markers["position_m"], step)
    angular = doc.get("angular") or {}
    for key in ANGULAR_PER_FRAME:
        if isinstance(angular.get(key), list) and len(angular[key]) == n:  # per frame: decimated alike
            series[key] = decimate(angular[key], step)
    stored = derived.get("series") or {}
    for name in DERIVED_SERIES:
        values = stored.get(name)
        series[name] = decimate(values, step) if isinstance(values, list) and len(values) == n else None
    return series


# The ride page asks for this many points (views/ride.js): its series are stored decimated for it, with
# the document less its per-sample arrays (`page_of_document`), so the page's first load reads ~1 MB of
# JSON, not the whole document (6.6 MB at 10,000 samples per curve) and its derived series.
PAGE_POINTS = 2000
_PER_SAMPLE = {"saddle": ("t_s", "position_m", "velocity_m_s", "acceleration_m_s2"),
               "angular": ("omega_rad_s", "alpha_rad_s2", *ANGULAR_PER_FRAME), "markers": ("position_m",)}


def page_of_document(doc: dict[str, Any], derived: dict[str, Any], max_points: int) -> dict[str, Any]:
    """What a view of `doc` needs at `max_points`: its series decimated, and the document without them.

    ``{"format", "max_points", "samples", "step", "document", "series", "spectrum"}``; `derived` is the
    document's derived series (`derived_series`).
    """
    if max_points < 10:
        raise InputError(f"max_points must be at least 10, got {max_points}")
    n = len((doc.get("saddle") or {}).get("t_s") or [])
    step = max(1, math.ceil(n / max_points))
    light = dict(doc)
    for group, keys in _PER_SAMPLE.items():
        if isinstance(doc.get(group), dict):
            light[group] = {k: v for k, v in doc[group].items() if k not in keys}
    return {"format": DERIVED_FORMAT, "max_points": max_points, "samples": n, "step": step, "document": light,
            "series": _series(doc, step, n, derived), "spectrum": derived.get("spectrum")}


def view_of_document(doc: dict[str, Any], result, ride_id: int, max_points: int,
                     derived: dict[str, Any] | None = None) -> dict[str, Any]:
    """What the dashboard shows of result document `doc` (its shape is `saddlescope.api.schemas.ResultOut`).

    `result` is the ride's result row (its job, code version and time). Series are decimated to at
    most `max_points` samples; the indicators come with their units. `derived` is the document's
    derived series as stored with it (`stored_derived_series`); computed here when not given.
    """
    return view_of_page(page_of_document(doc, derived_series(doc) if derived is None else derived, max_points),
                        result, ride_id)


def view_of_page(page: dict[str, Any], result, ride_id: int) -> dict[str, Any]:
    """`view_of_document` of a `page_of_document` (as computed, or as stored with the result)."""
    doc, series, step, n = page["document"], page["series"], page["step"], page["samples"]
    markers = doc.get("markers") or {}
    indicators = dict(doc.get("indicators") or {})
    calibration = doc.get("calibration") or {}
    quality = doc.get("quality") or {}
    # the rig's findings are usually among the result's already: each once
    findings = document_findings(doc)
    severity, summary = quality_summary(findings)
    return {
        "ride_id": ride_id,
        "job_id": result.job_id,
        "code_version": result.code_version,
        "created_at": result.created_at,
        "fps": doc.get("fps"),
        "period_s": doc.get("period_s"),
        "window": doc.get("window"),
        "indicators": indicators,
        # 95 % intervals beside the indicators (issue 27; absent from results made before them)
        "indicators_interval_95": dict(doc.get("indicators_interval_95") or {}),
        "units": {key: indicator_unit(key) for key in indicators},
        "quality": quality,
        # every flag in plain words (services/results/quality_notes.py): what the page and the report say
        "quality_notes": quality_notes(findings),
        "quality_summary": {"severity": severity, "message": summary},
        "strides_analysed": strides_analysed(doc),
        # a ride of several passes: strides per pass and their spread (issue 38; None for one pass)
        "passes": passes_view(doc),
        "spectrum": page["spectrum"],
        "calibration_checks": calibration.get("checks") or {},
        "calibration_flags": calibration.get("flags") or [],
        "series": series,
        # the curve fits' goodness and 95 % intervals (thesis 5.5): a few numbers per marker and axis
        "fits": markers.get("fits") or {},
        "decimation": {"step": step, "samples": n, "max_points": page["max_points"]},
    }


def series_key(result_key: str) -> str:
    """Where a result document's derived series are stored: beside it (``….json`` -> ``….series.json``)."""
    stem = result_key[: -len(".json")] if result_key.endswith(".json") else result_key
    return f"{stem}.series.json"


def page_key(result_key: str) -> str:
    """Where the ride page's view of a result is stored (`page_of_document`): ``….json`` -> ``….page.json``."""
    return series_key(result_key).removesuffix(".series.json") + ".page.json"


def _write_json(storage: Storage, key: str, value: dict[str, Any]) -> None:
    storage.write_bytes(key, json.dumps(value, allow_nan=False, separators=(",", ":"), default=_json_default).encode())


def _write_derived(storage: Storage, result_key: str, derived: dict[str, Any]) -> None:
    _write_json(storage, series_key(result_key), derived)


def _write_page(storage: Storage, result_key: str, doc: dict[str, Any], derived: dict[str, Any]) -> None:
    _write_json(storage, page_key(result_key), page_of_document(doc, derived, PAGE_POINTS))
    if not storage.exists(result_key):  # a re-analysis removed the document meanwhile
        storage.delete(page_key(result_key))


def _stored_page(storage: Storage, result_key: str) -> dict[str, Any] | None:
    """The stored page of the result under `result_key`, or None (not stored, another format, unreadable)."""
    try:
        page = json.loads(storage.read_bytes(page_key(result_key)))
    except (FileNotFoundError, ValueError):
        return None
    return page if isinstance(page, dict) and page.get("format") == DERIVED_FORMAT else None


def _view_of_stored(storage: Storage, result, ride_id: int, max_points: int) -> dict[str, Any]:
    """The view of a result row's document: from its stored page at `PAGE_POINTS`, else from the document.

    A result stored before its page and series were gets them stored here (a lazy backfill).
    """
    if max_points == PAGE_POINTS:
        page = _stored_page(storage, result.result_key)
        if page is not None:
            return view_of_page(page, result, ride_id)
    doc = json.loads(storage.read_bytes(result.result_key))
    derived = stored_derived_series(storage, result.result_key, doc)
    if max_points == PAGE_POINTS:
        _write_page(storage, result.result_key, doc, derived)
    return view_of_document(doc, result, ride_id, max_points, derived)


def store_with_result(storage: Storage, result_key: str, doc: dict[str, Any]) -> None:
    """Store result `doc`'s derived series and ride page beside it, as `commit_result` does (for the bench)."""
    derived = derived_series(doc)
    _write_derived(storage, result_key, derived)
    _write_page(storage, result_key, doc, derived)


def stored_derived_series(storage: Storage, result_key: str, doc: dict[str, Any]) -> dict[str, Any]:
    """The derived series of the result document `doc` stored under `result_key` (`derived_series`).

    Read from storage where `commit_result` put them. A result stored before they were (or in an older
    format) has them computed here once and stored (a lazy backfill): the next reader reads them. A
    backfill racing a re-analysis that removed its document meanwhile removes what it wrote.
    """
    key = series_key(result_key)
    n = len((doc.get("saddle") or {}).get("t_s") or [])
    if storage.exists(key):
        try:
            stored = json.loads(storage.read_bytes(key))
        except FileNotFoundError:
            stored = None  # removed by a re-analysis meanwhile: the caller's document is gone too
        except ValueError:
            stored = None  # a torn or foreign file: computed again and replaced
            log.warning("the stored series %s are unreadable; computing them again", key)
        if isinstance(stored, dict) and stored.get("format") == DERIVED_FORMAT and stored.get("samples") == n:
            return stored
    derived = derived_series(doc)
    _write_derived(storage, result_key, derived)
    if not storage.exists(result_key):
        storage.delete(key)
    return derived


def analysed_result(session: Session, storage: Storage, ride_id: int, *, club_id: int) -> Result:
    """The result row of an analysed ride of the club (NotFound until it has one)."""

    def stored(result: Result, key: str) -> Result:
        if not storage.exists(key):
            raise FileNotFoundError(key)
        return result

    return _read_analysed(session, ride_id, club_id, stored)


# A re-analysis writes its document under a new key, swaps the row to it in one transaction and deletes
# the old document after the commit (`commit_result`), so a reader that read the row just before the swap
# may find its key gone: it reads the row again (the new result). A few times: re-analyses in a row.
_SWAPPED_READS = 5
T = TypeVar("T")


def _read_analysed(session: Session, ride_id: int, club_id: int, read: Callable[[Result, str], T]) -> T:
    """`read` of the ride's result row and its document's key (raising `FileNotFoundError` when gone meanwhile)."""
    for _ in range(_SWAPPED_READS):
        RideRepository(session, club_id=club_id).get(ride_id)
        result = ResultRepository(session, club_id=club_id).for_ride(ride_id)
        if result is None or result.result_key is None:
            break
        try:
            return read(result, result.result_key)
        except FileNotFoundError:
            session.rollback()  # a new snapshot (SQLite) and no cached row: see the swap's commit
    raise NotFound(f"ride {ride_id} has no result yet (it has not been analysed)")


def result_view(
    session: Session, storage: Storage, ride_id: int, *, club_id: int, max_points: int = 2000
) -> dict[str, Any]:
    """What the dashboard shows of a ride: indicators with units, quality flags, decimated series.

    Series are taken every ``step``-th sample so that none has more than `max_points` samples
    (``decimation.step``; the indicators are always computed from the full series).
    """
    return _read_analysed(session, ride_id, club_id,
                          lambda result, _key: _view_of_stored(storage, result, ride_id, max_points))


class _BytesCache:
    """A small thread-safe LRU of encoded views, bounded by total bytes."""

    def __init__(self, max_bytes: int) -> None:
        self.max_bytes = max_bytes
        self._items: OrderedDict[str, bytes] = OrderedDict()
        self._size = 0
        self._lock = threading.Lock()

    def get(self, key: str) -> bytes | None:
        with self._lock:
            data = self._items.get(key)
            if data is not None:
                self._items.move_to_end(key)
            return data

    def put(self, key: str, data: bytes) -> None:
        if len(data) > self.max_bytes // 4:
            return  # one huge view must not push out everything else
        with self._lock:
            if key in self._items:
                return
            self._items[key] = data
            self._size += len(data)
            while self._size > self.max_bytes:
                _, old = self._items.popitem(last=False)
                self._size -= len(old)


_VIEWS = _BytesCache(64 * 1024**2)


def _json_default(value: Any) -> Any:
    if isinstance(value, dt.datetime | dt.date):
        return value.isoformat()
    raise TypeError(f"{type(value).__name__} is not JSON serialisable")


def result_view_json(
    session: Session, storage: Storage, ride_id: int, *, club_id: int, max_points: int = 2000
) -> tuple[bytes, str]:
    """`result_view` encoded as JSON bytes, and its entity tag.

    The access check (the ride and its result in this club) runs on every call; the encoded view is
    cached per result and `max_points`, so many readers of one ride cost a database lookup each, not
    a parse and an encoding of the whole result document.
    """

    def encoded(result: Result, _key: str) -> tuple[bytes, str]:
        etag = hashlib.sha256(
            f"{result.id}|{result.result_key}|{result.created_at.isoformat()}|{max_points}".encode()
        ).hexdigest()[:32]
        data = _VIEWS.get(etag)
        if data is None:
            view = _view_of_stored(storage, result, ride_id, max_points)
            data = json.dumps(view, default=_json_default, allow_nan=False, separators=(",", ":")).encode()
            _VIEWS.put(etag, data)
        return data, etag

    return _read_analysed(session, ride_id, club_id, encoded)


def _ride_rows(
    session: Session, ride_ids: list[int] | None, *, club_id: int, rides: RideFilter | None = None
) -> list[dict[str, Any]]:
    """The export's rows: a ride's metadata, its saddle by name and the rider's weight on it, its indicators.

    The columns are `io.export.METADATA_COLUMNS` and `OPTIONAL_METADATA`; ids are left out.
    """
    rows = AnalyticsRepository(session, club_id=club_id).indicator_rows(rides=rides)
    if ride_ids is not None:
        wanted = set(ride_ids)
        rows = [r for r in rows if r["ride_id"] in wanted]
    weights = RideRepository(session, club_id=club_id).rider_weights_kg()
    for row in rows:
        for internal in ("horse_id", "saddle_id"):  # ids: the export names the horse and the saddle
            row.pop(internal, None)
        row["rider_weight_kg"] = weights.get(row["ride_id"])
    return rows


def indicator_table_bytes(rows: list[dict[str, Any]], fmt: str) -> bytes:
    """Indicators of rides as CSV or xlsx bytes (`saddlescope.io.export`)."""
    from saddlescope.io.export import indicators_to_csv, indicators_to_xlsx

    buffer = io.BytesIO()
    if fmt == "csv":
        indicators_to_csv(rows, buffer)
    elif fmt == "xlsx":
        indicators_to_xlsx(rows, buffer)
    else:
        raise InputError(f"indicator tables are exported as {' or '.join(TABLE_FORMATS)}, not {fmt!r}")
    return buffer.getvalue()


def tracks_mm(doc: dict[str, Any]) -> tuple[tuple[str, ...], np.ndarray, float]:
    """The 3-D tracks of the markers and the saddle point S, for a motion-capture file.

    Parameters
    ----------
    doc : dict
        A result document (CONTRACTS section 2): ``saddle.position_m``, ``markers.position_m``, ``fps``.

    Returns
    -------
    labels : tuple of str
        The M track names: the markers' (``M1``, ...; when their tracks span every frame), then ``S``.
    points_mm : ndarray of shape (F, M, 3)
        Positions in the motion frame, mm (NaN where a marker was not seen).
    rate_hz : float
        Frames per second.
    """
    saddle = doc.get("saddle") or {}
    position = saddle.get("position_m") or []
    if not position:
        raise NotFound("the result holds no saddle track to export")
    saddle_mm = np.asarray(position, dtype=np.float64).reshape(-1, 3) * 1e3
    labels: list[str] = []
    parts = []
    markers = (doc.get("markers") or {}).get("position_m")
    if markers:
        m = np.asarray(markers, dtype=np.float64) * 1e3  # (F, 3 markers, 3)
        if m.ndim == 3 and m.shape[0] == saddle_mm.shape[0] and m.shape[2] == 3:
            names = (doc.get("markers") or {}).get("names") or MARKER_LABELS
            labels += [str(n) for n in names][: m.shape[1]]
            parts.append(m)
    labels.append(SADDLE_LABEL)
    parts.append(saddle_mm[:, None, :])
    rate = float(doc.get("fps") or 0.0)
    if not rate > 0:
        raise InputError("the result has no frame rate; cannot export tracks")
    return tuple(labels), np.concatenate(parts, axis=1), rate


def export_ride(
    session: Session, storage: Storage, ride_id: int, fmt: str, *, club_id: int
) -> tuple[bytes, str]:
    """A ride's export as (bytes, file name)."""
    if fmt not in EXPORT_FORMATS:
        raise InputError(f"unknown export format {fmt!r}; choose one of {', '.join(EXPORT_FORMATS)}")
    doc = result_document(session, storage, ride_id, club_id=club_id)
    stem = f"ride-{ride_id}"
    if fmt == "json":
        return json.dumps(doc, indent=1, allow_nan=False).encode(), f"{stem}-result.json"
    if fmt in TABLE_FORMATS:
        return indicator_table_bytes(
            _ride_rows(session, [ride_id], club_id=club_id), fmt
        ), f"{stem}-indicators.{fmt}"
    from saddlescope.io.mocap import write_c3d, write_trc

    labels, points_mm, rate = tracks_mm(doc)
    with tempfile.TemporaryDirectory(prefix="saddlescope-export-") as tmp:
        path = Path(tmp) / f"{stem}.{fmt}"
        if fmt == "c3d":
            write_c3d(path, labels, points_mm, rate)
        else:
            write_trc(path, labels, points_mm, rate, units="mm")
        return path.read_bytes(), f"{stem}-tracks.{fmt}"


def export_rides(
    session: Session, fmt: str, *, club_id: int, rides: RideFilter | None = None
) -> tuple[bytes, str]:
    """Indicators of the club's analysed rides (matching the ride list filters) as CSV or xlsx."""
    if fmt not in TABLE_FORMATS:
        raise InputError(f"indicator tables are exported as {' or '.join(TABLE_FORMATS)}, not {fmt!r}")
    return indicator_table_bytes(_ride_rows(session, None, club_id=club_id, rides=rides), fmt), f"rides.{fmt}"


def uncertain_reason_of(document: Mapping[str, Any]) -> str | None:
    """Why a result document's ride is too uncertain for a decision (``quality.decision.reason``), or None.

    The one place the verdict is read from a document: the result row's ``uncertain_reason`` (what the
    leaderboards filter on) is derived from it by :func:`commit_result`, the one writer of results.
    """
    decision = (document.get("quality") or {}).get("decision") or {}
    reason = decision.get("reason") if decision.get("too_uncertain", decision.get("reason") is not None) else None
    return str(reason) if reason else None


def commit_result(sessions: sessionmaker[Session], storage: Storage, *, club_id: int, ride_id: int,
                  job_id: int | None, document: dict[str, Any], code_version: str | None,
                  attempt: int | None = None, host: str | None = None) -> str:
    """Store a ride's new result document and make it the ride's result atomically; returns its key.

    The document goes under a new key (naming the job and its attempt) first, its derived series (the
    ride page's fitted curves, residuals and weighted acceleration: seconds to fit, so computed here,
    not in a page's request) beside it; the result row is swapped to it in one transaction; only then
    is the previous document deleted. Until the commit
    readers get the old result, and a failed commit leaves it (and removes the new document). With
    `attempt` and `host`, the swap happens only while that attempt still holds job `job_id` (its row
    locked until the commit); a stale worker's result is refused (`JobFenced`) and its document removed.

    This is the one writer of results: an analysed clip set, a re-analysis and a motion-capture file all
    store theirs here, so the indicators' columns and the too-uncertain verdict are derived in one place
    (:func:`uncertain_reason_of`) and the ride's status is refreshed in the same transaction.
    """
    from saddlescope.db.repositories import JobRepository
    from saddlescope.services.jobs.fencing import JobFenced

    run = f"{job_id}-{attempt}-" if job_id is not None and attempt is not None else ""
    key = f"rides/{ride_id}/results/{run}{secrets.token_hex(8)}.json"
    derived = derived_series(document)
    storage.write_bytes(key, json.dumps(document, allow_nan=False).encode())
    try:
        _write_derived(storage, key, derived)
        _write_page(storage, key, document, derived)
        with session_scope(sessions) as session:
            if job_id is not None and attempt is not None and host is not None and not JobRepository(
                    session).hold(job_id, attempt=attempt, host=host):
                log.warning("job %s: result of attempt %s on %s refused: the job was taken over", job_id,
                            attempt, host)
                raise JobFenced(job_id, attempt)
            results = ResultRepository(session)
            old = results.for_ride(ride_id)
            old_key = old.result_key if old is not None else None
            results.replace_for_ride(club_id=club_id, ride_id=ride_id, job_id=job_id,
                                     indicators=document.get("indicators", {}), result_key=key,
                                     code_version=code_version, job_attempt=attempt,
                                     uncertain_reason=uncertain_reason_of(document))
            refresh_ride_status(session, ride_id)
    except BaseException:
        for written in (key, series_key(key), page_key(key)):
            storage.delete(written)
        raise
    if old_key and old_key != key:
        for stale in (old_key, series_key(old_key), page_key(old_key)):
            storage.delete(stale)
    return key


def export_horse(session: Session, horse_id: int, fmt: str, *, club_id: int) -> tuple[bytes, str]:
    """All of a horse's analysed rides (one row per ride, every gait) as CSV or xlsx, and the file's name."""
    horse = HorseRepository(session, club_id=club_id).get(horse_id)  # another club's horse: NotFound (404)
    if fmt not in TABLE_FORMATS:
        raise InputError(f"indicator tables are exported as {' or '.join(TABLE_FORMATS)}, not {fmt!r}")
    rows = _ride_rows(session, None, club_id=club_id, rides=RideFilter(horse_id=horse_id))
    if not rows:
        raise NotFound(f"{horse.name} has no analysed rides to export yet")
    stem = re.sub(r"[^A-Za-z0-9]+", "-", horse.name).strip("-").lower() or f"horse-{horse_id}"
    return indicator_table_bytes(rows, fmt), f"{stem}-rides.{fmt}"
