"""Ride bundles (CONTRACTS section 1): open a folder or a .zip, validate ``ride.json``, find the clips.

``open_bundle(path)`` returns a :class:`RideBundle` whose clip paths all exist. A zip is checked in place,
then only the members its ride.json uses are extracted into a temporary folder (`used_members`: members
nothing names are never unpacked), refusing members that would escape it (absolute paths, ``..``,
symlinks), archives with too many members, and archives or used members that unpack to more than a size
limit or at a suspicious compression ratio (zip bombs, padding). Every refusal is a :class:`BundleError`
naming the file and the field or member at fault.

``open_zip_stream(stream, name)`` opens a zip read through a seekable stream (a bucket's object read by
ranges) without unpacking it: the same checks and messages, and `zip_bundle_files` streams its members.

``write_bundle_zip(bundle_dir, zip_path)`` writes the zip a ride export or an upload uses.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import stat
import tempfile
import zipfile
import zlib
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath
from types import SimpleNamespace
from typing import Any, BinaryIO, TypeVar

from saddlescope.core.calibration.boards import board_from_meta
from saddlescope.core.errors import BundleError, InputError
from saddlescope.core.findings import Finding
from saddlescope.core.pipeline.inputs import calibration_spec
from saddlescope.core.types import CLIP_KINDS, WAND_CLIP_KINDS, Board
from saddlescope.io.result_schema import validate_ride_meta

__all__ = [
    "RideBundle", "ZipMember", "open_bundle", "open_zip_stream", "used_members", "write_bundle_zip", "zip_bundle_files",
    "MAX_FILES",
    "MAX_BYTES", "MAX_RATIO",
]

RIDE_JSON = "ride.json"
TRUTH_JSON = "truth.json"
MAX_FILES = 50_000  # 12 clips of numbered images at 30 fps: over 2 minutes each
MAX_BYTES = 8 * 1024**3
MAX_RATIO = 200.0  # video and images barely compress; zeros compress ~1000:1
_RATIO_MIN_BYTES = 1024**2  # tiny members (ride.json) may compress well without being bombs
# The whole archive, too: many members each under _RATIO_MIN_BYTES of padding must not fill the disk.
MAX_TOTAL_RATIO = 20.0
_TOTAL_RATIO_MIN_BYTES = 64 * 1024**2  # a bundle unpacking to less may compress as it likes
# A real member (a frame, a clip) takes at least a kB in the archive; empty padding members take ~100 B.
_MEMBERS_FREE = 1000
_ARCHIVE_BYTES_PER_MEMBER = 1024
_MAX_JSON_BYTES = 16 * 1024**2
_CHUNK = 1024**2
_IMAGE_SUFFIXES = frozenset({".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp", ".pgm", ".ppm"})
_STORED_SUFFIXES = _IMAGE_SUFFIXES | {".mp4", ".mov", ".m4v", ".avi", ".mkv", ".webm", ".zip"}
_DRIVE = re.compile(r"^[A-Za-z]:")


@dataclass(frozen=True, eq=False)
class RideBundle:
    """A validated ride bundle.

    Attributes
    ----------
    root : Path
        Folder holding ``ride.json`` (a temporary folder for a zip; see :meth:`close`).
    meta : dict
        The parsed ``ride.json``.
    board : Board
        The calibration board.
    clip_paths : dict of str to dict of str to Path
        ``clip_paths[kind][camera]``, kind in calibration/plumb/static/motion and a wand calibration's
        wand/close_up (those present), each an
        existing video file or folder of numbered images.
    truth : dict or None
        The parsed ``truth.json`` of a synthetic ride (result format), else None.
    extra_clip_paths : dict of str to dict of str to Path
        ``extra_clips`` of ``ride.json``: name -> camera -> path.
    calibration_file : Path or None
        A rig TOML/JSON to use instead of the calibration clips.
    warnings : tuple of Finding
        Things that are allowed but worth telling the user (no plumb clips).
    source : Path or None
        The folder or zip that was opened.
    """

    root: Path
    meta: dict
    board: Board
    clip_paths: dict[str, dict[str, Path]]
    truth: dict | None = None
    extra_clip_paths: dict[str, dict[str, Path]] = field(default_factory=dict)
    calibration_file: Path | None = None
    warnings: tuple[Finding, ...] = ()
    source: Path | None = None
    temp_dir: Path | None = field(default=None, repr=False)
    archive: zipfile.ZipFile | None = field(default=None, repr=False)  # a zip read in place (`open_zip_stream`)

    @property
    def gait(self) -> str:
        """The ride's gait, as meta.json names it."""
        return self.meta["gait"]

    @property
    def direction(self) -> str:
        """The ride's direction on the circle, as meta.json names it."""
        return self.meta["direction"]

    @property
    def calibration_method(self) -> str:
        """How the clips calibrate the rig: ``"board"``, ``"wand"`` or ``"board+wand"`` (issue 35).

        The board walk (default), a wand with close-up boards, or the board walk refined by a wand.
        """
        return calibration_spec(self.meta).method

    @property
    def sync_method(self) -> str:
        """How the clips are synchronised (``sync.method`` of meta.json)."""
        return self.meta["sync"]["method"]

    def sync_offsets(self, kind: str) -> dict[str, float] | None:
        """Known frame offsets of a clip set (``sync.method == "offsets"``), else None."""
        if self.sync_method != "offsets":
            return None
        offsets = self.meta["sync"]["offsets"].get(kind)
        return {role: float(v) for role, v in offsets.items()} if offsets is not None else None

    def has_clips(self, kind: str) -> bool:
        """Whether the bundle holds clips of `kind` (the ride's or an extra set)."""
        return kind in self.clip_paths or kind in self.extra_clip_paths

    def clip(self, kind: str, camera: str) -> Path:
        """Path of one clip (video file or image folder).

        Raises
        ------
        BundleError
            The bundle has no such clip set or camera.
        """
        per_camera = self.clip_paths.get(kind, self.extra_clip_paths.get(kind))
        if per_camera is None:
            known = ", ".join([*self.clip_paths, *self.extra_clip_paths])
            raise BundleError(f"ride bundle {self.root.name}: no {kind} clips (it has {known})")
        if camera not in per_camera:
            raise BundleError(f"ride bundle {self.root.name}: the {kind} clips have no {camera!r} camera "
                              f"(they have {', '.join(per_camera)})")
        return per_camera[camera]

    def close(self) -> None:
        """Remove the temporary folder a zip was extracted to, or close the zip read in place."""
        if self.archive is not None:
            self.archive.close()
        if self.temp_dir is not None:
            shutil.rmtree(self.temp_dir, ignore_errors=True)

    def __enter__(self) -> RideBundle:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def open_bundle(path: str | Path, *, extract_to: str | Path | None = None, max_files: int = MAX_FILES,
                max_bytes: int = MAX_BYTES, max_ratio: float = MAX_RATIO) -> RideBundle:
    """Open and validate a ride bundle: a folder, a .zip of it, or the folder's ``ride.json``.

    Parameters
    ----------
    path : path-like
        Bundle folder, zip archive, or ``ride.json`` file.
    extract_to : path-like, optional
        Empty or new folder to extract a zip into; by default a temporary folder that
        :meth:`RideBundle.close` removes.
    max_files, max_bytes, max_ratio
        Limits for a zip: member count, total uncompressed bytes, uncompressed/compressed ratio of a
        member over 1 MiB.

    Raises
    ------
    BundleError
        Unsafe or corrupt zip, missing or invalid ``ride.json`` (naming the field), unknown camera
        role, gait or format, a referenced clip or file that does not exist.
    """
    path = Path(path)
    if not path.exists():
        raise BundleError(f"{path}: no such ride bundle (folder or .zip)")
    if path.is_dir():
        return _open_folder(_find_root(path), source=path)
    if path.name == RIDE_JSON:
        return _open_folder(path.parent, source=path)
    if not zipfile.is_zipfile(path):
        raise BundleError(f"{path.name}: a ride bundle must be a folder or a .zip archive")
    if extract_to is None:
        dest = Path(tempfile.mkdtemp(prefix="saddlescope-ride-"))
        temp_dir: Path | None = dest
    else:
        dest = Path(extract_to)
        if dest.exists() and any(dest.iterdir()):
            raise BundleError(f"{dest}: the folder to extract {path.name} into is not empty")
        dest.mkdir(parents=True, exist_ok=True)
        temp_dir = None
    try:
        _extract_used(path, dest, max_files=max_files, max_bytes=max_bytes, max_ratio=max_ratio)
        return _open_folder(_find_root(dest, label=path.name), source=path, temp_dir=temp_dir)
    except BaseException:
        if temp_dir is not None:
            shutil.rmtree(temp_dir, ignore_errors=True)
        raise


# A folder on disk or inside a zip read in place (`ZipMember` answers the `Path` questions asked here).
_Folder = TypeVar("_Folder", Path, "ZipMember")


def _find_root(folder: _Folder, *, label: str | None = None) -> _Folder:
    """The folder itself, or its single subfolder, whichever holds ride.json (zips often nest one)."""
    if (folder / RIDE_JSON).is_file():
        return folder
    subdirs = [p for p in folder.iterdir() if p.is_dir() and not p.name.startswith(("__MACOSX", "."))]
    if len(subdirs) == 1 and (subdirs[0] / RIDE_JSON).is_file():
        return subdirs[0]
    raise BundleError(f"{label or folder}: no {RIDE_JSON} (is this a ride bundle?)")


# -------------------------------------------------------------------------------------------- zip


def _member_parts(info: zipfile.ZipInfo, zip_name: str) -> tuple[str, ...]:
    name = info.filename.replace("\\", "/")
    if name.startswith("/") or _DRIVE.match(name):
        raise BundleError(f"{zip_name}: member {info.filename!r} has an absolute path")
    parts = tuple(p for p in PurePosixPath(name).parts if p not in ("", "."))
    if ".." in parts:
        raise BundleError(f"{zip_name}: member {info.filename!r} has a '..' component (it would be "
                          "written outside the bundle)")
    return parts


def _check_totals(infos: list[zipfile.ZipInfo], zip_name: str, archive_bytes: int | None) -> None:
    """Refuse padding: more members, or more bytes unpacked, than an archive of this size can honestly hold."""
    if archive_bytes is None:
        return
    allowed = _MEMBERS_FREE + archive_bytes // _ARCHIVE_BYTES_PER_MEMBER
    if len(infos) > allowed:
        raise BundleError(f"{zip_name}: {len(infos)} members in a {archive_bytes / 1e3:.0f} kB archive, more "
                          f"than the {allowed} such an archive may hold (padding?)")
    total = sum(info.file_size for info in infos)
    if total > _TOTAL_RATIO_MIN_BYTES and total > MAX_TOTAL_RATIO * max(archive_bytes, 1):
        raise BundleError(f"{zip_name}: unpacks to {total / 1e6:.0f} MB, {total / max(archive_bytes, 1):.0f} "
                          f"times its {archive_bytes / 1e6:.1f} MB compressed size (the limit is "
                          f"{MAX_TOTAL_RATIO:.0f} times; padding or a zip bomb?)")


def _check_zip(zf: zipfile.ZipFile, zip_name: str, *, max_files: int, max_bytes: int,
               max_ratio: float, archive_bytes: int | None = None) -> list[tuple[zipfile.ZipInfo, tuple[str, ...]]]:
    """Vet every member before anything is written."""
    infos = zf.infolist()
    if len(infos) > max_files:
        raise BundleError(f"{zip_name}: {len(infos)} members, more than the limit of {max_files}")
    members = []
    seen: set[str] = set()
    total = 0
    for info in infos:
        parts = _member_parts(info, zip_name)
        if not parts:
            continue
        mode = info.external_attr >> 16
        if stat.S_ISLNK(mode):
            raise BundleError(f"{zip_name}: member {info.filename!r} is a symbolic link (not allowed)")
        # Unix type bits, where set (Python's writestr leaves them 0), must say file or folder.
        if info.create_system == 3 and stat.S_IFMT(mode) not in (0, stat.S_IFREG, stat.S_IFDIR):
            raise BundleError(f"{zip_name}: member {info.filename!r} is not a regular file or folder")
        if info.flag_bits & 0x1:
            raise BundleError(f"{zip_name}: member {info.filename!r} is encrypted")
        key = "/".join(parts).lower()  # case-insensitive file systems would merge these
        if key in seen:
            raise BundleError(f"{zip_name}: member {info.filename!r} appears twice")
        seen.add(key)
        total += info.file_size
        if total > max_bytes:
            raise BundleError(f"{zip_name}: unpacks to more than the limit of {max_bytes / 1e6:.0f} MB "
                              f"(member {info.filename!r} alone is {info.file_size / 1e6:.0f} MB)")
        if info.file_size > _RATIO_MIN_BYTES and info.file_size > max_ratio * max(info.compress_size, 1):
            raise BundleError(f"{zip_name}: member {info.filename!r} compresses "
                              f"{info.file_size / max(info.compress_size, 1):.0f}:1, over the limit of "
                              f"{max_ratio:.0f}:1 (a zip bomb?)")
        members.append((info, parts))
    _check_totals(infos, zip_name, archive_bytes)
    return members


_ZIP_ERRORS = (zipfile.BadZipFile, zlib.error, EOFError, NotImplementedError)


def _extract_used(zip_path: Path, dest: Path, *, max_files: int, max_bytes: int, max_ratio: float) -> None:
    """Unpack the members the bundle uses (`used_members`), checked in place first; nothing else is written."""
    name = zip_path.name
    try:
        with zipfile.ZipFile(zip_path) as zf:
            members = _check_zip(zf, name, max_files=max_files, max_bytes=max_bytes, max_ratio=max_ratio,
                                 archive_bytes=zip_path.stat().st_size)
            root = _find_root(ZipMember(_ZipTree(zf, name, members), ()), label=name)
            in_place = _open_folder(root, source=None)  # type: ignore[arg-type]
            written_total = 0
            for member in used_members(in_place, max_bytes=max_bytes):
                info = member.info
                target = dest.joinpath(*member.parts)
                target.parent.mkdir(parents=True, exist_ok=True)
                written = 0
                with zf.open(info) as src, open(target, "wb") as out:
                    while chunk := src.read(_CHUNK):
                        written += len(chunk)
                        written_total += len(chunk)
                        # Headers can lie about sizes: count what really comes out.
                        if written > info.file_size or written_total > max_bytes:
                            raise BundleError(f"{name}: member {info.filename!r} unpacks to more than its "
                                              "header says (a zip bomb?)")
                        out.write(chunk)
    except _ZIP_ERRORS as exc:
        raise BundleError(f"{name}: corrupt or unsupported zip archive ({exc})") from exc
    except OSError as exc:
        raise BundleError(f"{name}: cannot be extracted ({exc.strerror or exc})") from exc


def used_members(bundle: RideBundle, *, max_bytes: int = MAX_BYTES) -> list[ZipMember]:
    """The files of a zip bundle checked in place that its ride.json uses, in path order, size-checked.

    ride.json, truth.json, the calibration file, each clip file and the images of each clip folder: a
    member nothing names (padding, notes, a second copy) is never unpacked nor stored. Together they may
    unpack to at most `max_bytes`, and, past `_TOTAL_RATIO_MIN_BYTES`, to at most `MAX_TOTAL_RATIO` times
    their compressed size (video and images barely compress; padding of zeros does ~1000:1).
    """
    root = bundle.root
    if not isinstance(root, ZipMember):
        raise ValueError("used_members reads a zip bundle checked in place")
    files: dict[tuple[str, ...], ZipMember] = {}
    named = [root / RIDE_JSON, root / TRUTH_JSON, bundle.calibration_file,
             *(path for sets in (bundle.clip_paths, bundle.extra_clip_paths)
               for per_camera in sets.values() for path in per_camera.values())]
    for path in named:
        if not isinstance(path, ZipMember) or not path.exists():
            continue
        inside = [path] if path.is_file() else [
            image for image in path.iterdir() if image.is_file() and image.suffix.lower() in _IMAGE_SUFFIXES]
        files.update((member.parts, member) for member in inside)
    used = [files[parts] for parts in sorted(files)]
    _check_unpacked(used, root.tree.name, max_bytes=max_bytes)
    return used


def _check_unpacked(used: list[ZipMember], zip_name: str, *, max_bytes: int) -> None:
    """Refuse used members that unpack to more than `max_bytes`, or to padding.

    Padding is a compression ratio no video or image has, counted over all of them: many small members of
    zeros are padding too.
    """
    unpacked = sum(member.info.file_size for member in used)
    packed = max(sum(member.info.compress_size for member in used), 1)
    if unpacked > max_bytes:
        raise BundleError(f"{zip_name}: the clips ride.json names unpack to {unpacked / 1e6:.0f} MB, more "
                             f"than the limit of {max_bytes / 1e6:.0f} MB")
    if unpacked > _TOTAL_RATIO_MIN_BYTES and unpacked > MAX_TOTAL_RATIO * packed:
        raise BundleError(f"{zip_name}: the clips ride.json names unpack to {unpacked / 1e6:.0f} MB, "
                          f"{unpacked / packed:.0f} times their {packed / 1e6:.1f} MB compressed size (the "
                          f"limit is {MAX_TOTAL_RATIO:.0f} times: video and images barely compress; padding?)")


# ------------------------------------------------------------------------------- zip read in place


class _ZipTree:
    """The folders and files a zip's vetted members would unpack to (folders implied by their paths)."""

    def __init__(self, zf: zipfile.ZipFile, name: str,
                 members: list[tuple[zipfile.ZipInfo, tuple[str, ...]]]) -> None:
        self.zf, self.name = zf, name
        self.files = {parts: info for info, parts in members if not info.is_dir()}
        self.children: dict[tuple[str, ...], set[tuple[str, ...]]] = {(): set()}
        for info, parts in members:
            upto = len(parts) if info.is_dir() else len(parts) - 1
            for depth in range(upto + 1):
                self.children.setdefault(parts[:depth], set())
                if depth:
                    self.children[parts[:depth - 1]].add(parts[:depth])
            if not info.is_dir():
                self.children[parts[:-1]].add(parts)
        clash = next((parts for parts in self.files if parts in self.children), None)
        if clash is not None:  # unpacking would fail to make the folder (or the file) there
            raise BundleError(f"{name}: cannot be extracted (member {'/'.join(clash)!r} is both a file and a "
                              "folder)")


class ZipMember:
    """A file or folder inside a zip read in place, answering the few `Path` questions a bundle's checks ask.

    What `open_bundle` would find in the unpacked folder, read from the zip's directory instead.
    """

    def __init__(self, tree: _ZipTree, parts: tuple[str, ...]) -> None:
        self.tree, self.parts = tree, parts

    def __truediv__(self, name: str) -> ZipMember:
        return self.joinpath(name)

    def joinpath(self, *names: str) -> ZipMember:
        """The member under this one at the path `names`."""
        more = tuple(p for name in names for p in str(name).split("/") if p not in ("", "."))
        return ZipMember(self.tree, self.parts + more)

    @property
    def name(self) -> str:
        """The member's last path component."""
        return self.parts[-1] if self.parts else ""

    @property
    def suffix(self) -> str:
        """The last component's extension, dot included."""
        return PurePosixPath(self.name).suffix if self.parts else ""

    @property
    def stem(self) -> str:
        """The last component without its extension."""
        return PurePosixPath(self.name).stem if self.parts else ""

    @property
    def info(self) -> zipfile.ZipInfo:
        """The zip's entry for this member."""
        return self.tree.files[self.parts]

    def is_file(self) -> bool:
        """Whether the member is a file in the zip."""
        return self.parts in self.tree.files

    def is_dir(self) -> bool:
        """Whether the member is a folder in the zip (an entry or a prefix of one)."""
        return self.parts in self.tree.children and not self.is_file()

    def exists(self) -> bool:
        """Whether the member is in the zip, as a file or a folder."""
        return self.is_file() or self.is_dir()

    def iterdir(self) -> list[ZipMember]:
        """The members directly under this folder."""
        return [ZipMember(self.tree, parts) for parts in sorted(self.tree.children.get(self.parts, ()))]

    def stat(self) -> SimpleNamespace:
        """The member's size, as ``os.stat_result.st_size`` would give it."""
        return SimpleNamespace(st_size=self.info.file_size if self.is_file() else 0)

    def read_bytes(self) -> bytes:
        """The member's bytes, unpacked."""
        return self.tree.zf.read(self.info)

    def read_text(self, encoding: str = "utf-8") -> str:
        """The member's text, decoded with `encoding`."""
        return self.read_bytes().decode(encoding)

    def resolve(self) -> ZipMember:
        """The member itself: a zip has no links to follow."""
        return self  # a zip holds no links (`_check_zip` refuses them)

    def is_relative_to(self, other: ZipMember) -> bool:
        """Whether this member is `other` or lies under it."""
        return self.parts[:len(other.parts)] == other.parts

    def relative_to(self, other: ZipMember) -> PurePosixPath:
        """The member's path relative to `other`."""
        if not self.is_relative_to(other):
            raise ValueError(f"{self} is not inside {other}")
        return PurePosixPath(*self.parts[len(other.parts):])

    def files_below(self) -> list[ZipMember]:
        """Every file inside this folder, in path order (the order `tree_digest` reads an unpacked folder)."""
        depth = len(self.parts)
        return [ZipMember(self.tree, parts) for parts in sorted(self.tree.files) if parts[:depth] == self.parts]

    def __str__(self) -> str:
        return "/".join((self.tree.name, *self.parts))

    def __repr__(self) -> str:
        return f"ZipMember({str(self)!r})"


def open_zip_stream(stream: BinaryIO, name: str, *, max_files: int = MAX_FILES, max_bytes: int = MAX_BYTES,
                    max_ratio: float = MAX_RATIO) -> RideBundle:
    """Open and validate a ride bundle zip read through a seekable `stream`, without unpacking it.

    The checks and messages of `open_bundle` for a zip, naming it `name`. The bundle's root and clip paths
    are `ZipMember`s; `zip_bundle_files` reads their bytes. Closing the bundle closes the zip (not `stream`).

    Raises
    ------
    BundleError
        As `open_bundle` does for the same zip.
    """
    if not zipfile.is_zipfile(stream):
        raise BundleError(f"{name}: a ride bundle must be a folder or a .zip archive")
    archive_bytes = stream.seek(0, os.SEEK_END)
    stream.seek(0)
    zf = None
    try:
        zf = zipfile.ZipFile(stream)
        members = _check_zip(zf, name, max_files=max_files, max_bytes=max_bytes, max_ratio=max_ratio,
                             archive_bytes=archive_bytes)
        root = _find_root(ZipMember(_ZipTree(zf, name, members), ()), label=name)
        return _open_folder(root, source=None, archive=zf)  # type: ignore[arg-type]
    except BaseException as exc:
        if zf is not None:
            zf.close()
        if isinstance(exc, _ZIP_ERRORS):
            raise BundleError(f"{name}: corrupt or unsupported zip archive ({exc})") from exc
        raise


def zip_bundle_files(bundle: RideBundle, *, max_bytes: int = MAX_BYTES) -> Iterator[tuple[ZipMember, Iterator[bytes]]]:
    """Each file a bundle from `open_zip_stream` uses (`used_members`), in path order, with its bytes in chunks.

    Read a file's chunks before taking the next file. Bytes that disagree with the member's header or CRC
    are a `BundleError`, as when `open_bundle` unpacks the zip.
    """
    root = bundle.root
    if bundle.archive is None or not isinstance(root, ZipMember):
        raise ValueError("zip_bundle_files reads a bundle opened by open_zip_stream")
    archive, name = bundle.archive, root.tree.name
    total = 0

    def chunks(info: zipfile.ZipInfo) -> Iterator[bytes]:
        nonlocal total
        written = 0
        try:
            with archive.open(info) as source:
                while chunk := source.read(_CHUNK):
                    written += len(chunk)
                    total += len(chunk)
                    if written > info.file_size or total > max_bytes:  # headers can lie about sizes
                        raise BundleError(f"{name}: member {info.filename!r} unpacks to more than its "
                                          "header says (a zip bomb?)")
                    yield chunk
        except _ZIP_ERRORS as exc:
            raise BundleError(f"{name}: corrupt or unsupported zip archive ({exc})") from exc

    for member in used_members(bundle, max_bytes=max_bytes):
        yield member, chunks(member.info)


# ----------------------------------------------------------------------------------------- folder


def _storable_text(value: Any, where: str) -> None:
    r"""Refuse a lone UTF-16 surrogate ("\\ud800" in JSON) or NUL in any text: no database can store it."""
    if isinstance(value, str):
        if "\x00" in value or any("\ud800" <= c <= "\udfff" for c in value):
            raise BundleError(f"{where}: text may not contain a NUL character or a lone UTF-16 surrogate "
                              "(e.g. \\ud800); it is not valid Unicode")
    elif isinstance(value, dict):
        for key, item in value.items():
            _storable_text(key, where)
            _storable_text(item, f"{where} {key}")
    elif isinstance(value, list):
        for item in value:
            _storable_text(item, where)


def _read_json(path: Path, label: str) -> Any:
    if path.stat().st_size > _MAX_JSON_BYTES:
        raise BundleError(f"{label}: {path.stat().st_size / 1e6:.0f} MB is too large for a JSON side file")
    try:
        value = json.loads(path.read_text(encoding="utf-8"))
        _storable_text(value, label)
        return value
    except UnicodeDecodeError as exc:
        raise BundleError(f"{label}: not UTF-8 text ({exc.reason})") from exc
    except json.JSONDecodeError as exc:
        raise BundleError(f"{label}: not valid JSON ({exc.msg} at line {exc.lineno}, "
                          f"column {exc.colno})") from exc


def _inside(root: Path, rel: str, where: str) -> Path:
    """A path named in ride.json, checked to exist inside the bundle."""
    parts = PurePosixPath(rel.replace("\\", "/")).parts
    if rel.startswith(("/", "\\")) or _DRIVE.match(rel) or ".." in parts:
        raise BundleError(f"{RIDE_JSON}: {where} {rel!r} must be a relative path inside the bundle")
    target = root.joinpath(*parts)
    if not target.exists():
        raise BundleError(f"{RIDE_JSON}: {where} {rel!r} does not exist in the bundle")
    # A symlink may not lead out of the bundle.
    if not target.resolve().is_relative_to(root.resolve()):
        raise BundleError(f"{RIDE_JSON}: {where} {rel!r} points outside the bundle")
    return target


def _clip_path(root: Path, rel: str, where: str) -> Path:
    target = _inside(root, rel, where)
    if target.is_dir():
        images = [p for p in target.iterdir()
                  if p.suffix.lower() in _IMAGE_SUFFIXES and any(c.isdigit() for c in p.stem)]
        if not images:
            raise BundleError(f"{RIDE_JSON}: {where} {rel!r} is a folder without numbered images "
                              f"({', '.join(sorted(_IMAGE_SUFFIXES))})")
    elif target.stat().st_size == 0:
        raise BundleError(f"{RIDE_JSON}: {where} {rel!r} is an empty file")
    return target


def _board(meta: dict) -> Board:
    try:
        return board_from_meta(meta["board"])
    except InputError as exc:
        raise BundleError(f"{RIDE_JSON}: {exc}") from None


def _open_folder(root: Path, *, source: Path | None, temp_dir: Path | None = None,
                 archive: zipfile.ZipFile | None = None) -> RideBundle:
    ride_json = root / RIDE_JSON
    if not ride_json.is_file():
        raise BundleError(f"{root}: no {RIDE_JSON} (is this a ride bundle?)")
    meta = _read_json(ride_json, RIDE_JSON)
    validate_ride_meta(meta, source=RIDE_JSON)

    clip_paths = {kind: {role: _clip_path(root, rel, f"clips.{kind}.{role}")
                         for role, rel in meta["clips"][kind].items()}
                  for kind in CLIP_KINDS + WAND_CLIP_KINDS if kind in meta["clips"]}
    extra = {name: {role: _clip_path(root, rel, f"extra_clips.{name}.{role}") for role, rel in cams.items()}
             for name, cams in (meta.get("extra_clips") or {}).items()}
    clash = set(extra) & set(CLIP_KINDS + WAND_CLIP_KINDS)
    if clash:
        raise BundleError(f"{RIDE_JSON}: extra_clips may not reuse the clip kind {sorted(clash)[0]!r}")

    calibration_file = None
    if meta.get("calibration_file"):
        calibration_file = _inside(root, meta["calibration_file"], "calibration_file")
        if calibration_file.suffix.lower() not in (".toml", ".json") or not calibration_file.is_file():
            raise BundleError(f"{RIDE_JSON}: calibration_file {meta['calibration_file']!r} must be a "
                              ".toml or .json rig file")

    warnings: list[Finding] = []
    if "plumb" not in clip_paths:
        warnings.append(Finding("plumb.missing",
                                "no plumb clips: the vertical (gravity) cannot be measured from a plumb line"))

    truth = None
    if (root / TRUTH_JSON).is_file():
        truth = _read_json(root / TRUTH_JSON, TRUTH_JSON)
        if not isinstance(truth, dict):
            raise BundleError(f"{TRUTH_JSON}: must hold a JSON object (a result document)")

    return RideBundle(root=root, meta=meta, board=_board(meta), clip_paths=clip_paths, truth=truth,
                      extra_clip_paths=extra, calibration_file=calibration_file, warnings=tuple(warnings),
                      source=source, temp_dir=temp_dir, archive=archive)


# ----------------------------------------------------------------------------------------- writer


def write_bundle_zip(bundle_dir: str | Path, zip_path: str | Path, *, validate: bool = True) -> Path:
    """Zip a ride bundle folder (paths relative to it; media stored, text deflated).

    Parameters
    ----------
    bundle_dir : path-like
        Folder with ``ride.json`` at its top.
    zip_path : path-like
        Output archive; written to a temporary name first, then renamed.
    validate : bool
        Open the bundle first, so a broken bundle is never exported.

    Raises
    ------
    BundleError
        No ride.json, an invalid bundle (with ``validate``), or a symlink leading out of the folder.
    """
    bundle_dir = Path(bundle_dir)
    zip_path = Path(zip_path)
    if not (bundle_dir / RIDE_JSON).is_file():
        raise BundleError(f"{bundle_dir}: no {RIDE_JSON} (is this a ride bundle?)")
    if validate:
        open_bundle(bundle_dir)
    root = bundle_dir.resolve()
    files = []
    for dirpath, dirnames, filenames in os.walk(root):
        dirnames.sort()
        for fname in sorted(filenames):
            full = Path(dirpath) / fname
            if full.resolve() == zip_path.resolve():
                continue
            if not full.resolve().is_relative_to(root):
                raise BundleError(f"{bundle_dir}: {full.relative_to(root)} is a link to outside the bundle")
            files.append(full)
    zip_path.parent.mkdir(parents=True, exist_ok=True)
    partial = zip_path.with_name(zip_path.name + ".part")
    with zipfile.ZipFile(partial, "w", allowZip64=True) as zf:
        for full in files:
            arcname = full.relative_to(root).as_posix()
            method = zipfile.ZIP_STORED if full.suffix.lower() in _STORED_SUFFIXES else zipfile.ZIP_DEFLATED
            zf.write(full, arcname, compress_type=method)
    os.replace(partial, zip_path)
    return zip_path


def read_bundle_calibration(path: str | Path) -> tuple[Any, list[Finding]]:
    """The rig of a bundle's ``calibration_file`` in mm, and notes on how its units were read.

    A ``.json`` is SaddleScope's calibration object (mm); a ``.toml`` is anipose's, Pose2Sim's,
    FreeMoCap's or caliscope's, each read in its own unit
    (:func:`saddlescope.io.calibration_files.read_calibration_toml`).

    Parameters
    ----------
    path : str or Path
        The calibration file.

    Returns
    -------
    rig : Rig
        The cameras, translations in mm.
    notes : list of Finding
        For the result's findings, where the file did not state its unit.
    """
    path = Path(path)
    if path.suffix.lower() == ".toml":
        from saddlescope.io.calibration_files import read_calibration_toml

        return read_calibration_toml(path)
    from saddlescope.io.rig_document import rig_from_dict

    return rig_from_dict(_read_json(path, "calibration_file")), []
