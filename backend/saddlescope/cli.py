"""The ``saddlescope`` command (CONTRACTS section 3).

Each command parses its arguments and calls one function elsewhere; bad input ends with one clear
sentence on stderr and a non-zero exit status, never a traceback.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from saddlescope.core.errors import InputError, SaddleScopeError


def _size(text: str) -> tuple[int, int]:
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"size must look like 1920x1080, got {text!r}") from None
    if w < 64 or h < 64:
        raise argparse.ArgumentTypeError(f"size {text!r} is too small (at least 64x64)")
    return w, h


def _speed_range(text: str) -> tuple[float, float]:
    try:
        lo, hi = (float(v) for v in text.split("-"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"speed must look like 4-6 (m/s), got {text!r}") from None
    return lo, hi


def _pattern(text: str) -> tuple[int, int]:
    try:
        c, r = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"pattern must look like 9x6 (inner corners), got {text!r}") from None
    return c, r


def _board_option_text(text: str) -> tuple[str, str]:
    """``NAME=VALUE`` of --board-option (checked against the kinds' fields when the command runs)."""
    name, sep, value = text.partition("=")
    if not (sep and name and value):
        raise argparse.ArgumentTypeError(f"a board option looks like NAME=VALUE (e.g. circle_mm=10), got {text!r}")
    return name, value


def _board_options(args: argparse.Namespace) -> dict:
    """The board's own fields from --dictionary, --marker and every --board-option, typed as its kind declares.

    Raises
    ------
    InputError
        A field no registered kind declares, or a value not of its type.
    """
    from saddlescope.core.calibration.boards import board_option

    options = {"dictionary": args.dictionary, "marker_mm": args.marker}
    for name, text in args.board_option:
        options[name] = board_option(name).parse(text)
    return {name: value for name, value in options.items() if value is not None}


def _add_board_arguments(s) -> None:
    """The board's kind and fields, shared by ``calibrate`` and ``check-calibration``."""
    s.add_argument("--board", default=None, choices=_BoardKinds(), metavar="KIND",  # a metavar: no listing at start
                   help="the board's kind (default checkerboard; an unknown one gets the list)")
    s.add_argument("--dictionary", default=None, help="ChArUco dictionary (default DICT_4X4_50)")
    s.add_argument("--marker", type=float, default=None, help="ChArUco marker size in mm")
    s.add_argument("--board-option", dest="board_option", type=_board_option_text, action="append", default=[],
                   metavar="NAME=VALUE", help="a field of the board's kind (GET /api/board-types lists them), "
                                              "e.g. circle_mm=10")


def _intrinsics_source(text: str) -> tuple[str, str]:
    """``NAME=FILE`` or ``FILE`` of --intrinsics (NAME "" for every camera the file names)."""
    name, sep, file = text.partition("=")
    return (name, file) if sep and name and file else ("", text)


def _camera_source(text: str) -> tuple[str, str]:
    name, sep, source = text.partition("=")
    if not sep or not name or not source:
        raise argparse.ArgumentTypeError(
            f"--camera takes NAME=SOURCE (a video or an image glob), got {text!r}")
    return name, source


def _labels(text: str) -> tuple[str, ...]:
    labels = tuple(s.strip() for s in text.split(","))
    if len(labels) != 3 or not all(labels):
        raise argparse.ArgumentTypeError(f"--markers takes three labels separated by commas, got {text!r}")
    return labels


def _offset(text: str) -> tuple[float, float, float]:
    try:
        dx, dy, dz = (float(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"--offset takes three numbers in mm, e.g. 0,-150,40, got {text!r}") from None
    return dx, dy, dz


def _calibrate_wand(args, cameras: dict[str, str]) -> int:
    """``saddlescope calibrate --wand LENGTH_M``: poses and scale from a wand, lenses from close-ups or given."""
    from saddlescope.core.calibration.boards import DEFAULT_BOARD_KIND, make_board
    from saddlescope.io.calibration_files import calibrate_wand_sources, intrinsics_for_cameras

    board = None
    if args.close_up:
        if args.pattern is None or args.square is None:
            print("saddlescope calibrate: --close-up board clips need --pattern and --square", file=sys.stderr)
            return 2
        board = make_board(args.board or DEFAULT_BOARD_KIND, args.pattern, args.square, **_board_options(args))
    result = calibrate_wand_sources(cameras, wand_length_m=args.wand,
                                    intrinsics=intrinsics_for_cameras(args.intrinsics, list(cameras)) or None,
                                    close_ups=dict(args.close_up) or None, board=board, toml_out=args.toml_out)
    _write_json(result, args.json_out)
    return 0


def _similar(args) -> int:
    """`saddlescope similar`: one pair's answer, or the matrix of every pair of many recordings."""
    from saddlescope.io import similarity_matrix as matrix_files
    from saddlescope.io.mocap.labels import parse_label_map
    from saddlescope.services.similarity import compare as similarity

    markers = [m.strip() for m in args.markers.split(",") if m.strip()] if args.markers else None
    label_map = parse_label_map(args.label_map)
    paths = [Path(f) for f in args.files]
    if len(paths) == 2 and not any(p.is_dir() for p in paths):
        result = similarity.compare_files(paths[0], paths[1], markers=markers, up=args.up, label_map=label_map,
                                          alignment=args.alignment)
    else:
        result = similarity.similarity_matrix(matrix_files.recording_paths(paths), markers=markers, up=args.up,
                                              label_map=label_map)
        if args.csv_out:
            matrix_files.write_matrix_csv(result, args.csv_out)
        if args.png_out:
            matrix_files.write_matrix_png(result, args.png_out)
    _write_json(result, args.json_out)
    if args.json_out:
        print(json.dumps(result, indent=2))
    return 0


def _write_json(data: dict, out: str | None) -> None:
    text = json.dumps(data, indent=2, allow_nan=False)
    if out:
        Path(out).parent.mkdir(parents=True, exist_ok=True)
        Path(out).write_text(text + "\n")
    else:
        print(text)


def _add_check_parser(sub) -> None:
    """`saddlescope check-calibration`: calibration clips judged before anyone rides (issue 35)."""
    s = sub.add_parser("check-calibration", help="check calibration clips: where the board went in each camera's "
                                                  "view, and whether to film again (exit status 1)")
    s.add_argument("clips", nargs="*", metavar="CLIP",
                   help="NAME=VIDEO or VIDEO (named by its file name, e.g. left.mp4 is the left camera)")
    s.add_argument("--ride", default=None, help="a ride bundle folder: its calibration clips and board")
    s.add_argument("--pattern", type=_pattern, default=None, help="the board's inner corners CxR, e.g. 9x6")
    s.add_argument("--square", type=float, default=None, help="square size in mm")
    _add_board_arguments(s)
    s.add_argument("--fps", dest="sample_fps", type=float, default=None, help="frames looked at a second (default 3)")
    s.add_argument("--wand", type=float, default=None, metavar="LENGTH_M",
                   help="the clips film a wand of this length (m) waved through the riding area: where its ends went")
    s.add_argument("--json", dest="json_out", default=None, help="also write the whole check here")


def _check_sources(args: argparse.Namespace) -> tuple[dict[str, Path], dict, float | None]:
    """The clips to check, the board they show and, for a wand's clips, the wand's length (m)."""
    board: dict = {}
    paths: dict[str, Path] = {}
    wand_m = args.wand
    if args.ride:
        meta = json.loads((Path(args.ride) / "ride.json").read_text(encoding="utf-8"))
        board = dict(meta.get("board") or {})
        cal = meta.get("calibration") or {}
        if cal.get("method") == "wand" and wand_m is None:  # board+wand: the board walk's clips, unless --wand
            wand_m = cal.get("wand_length_m")
        folder = "wand" if wand_m is not None else "calibration"
        paths = {p.stem: p for p in sorted((Path(args.ride) / folder).glob("*.*"))}
    for clip in args.clips:
        name, sep, source = clip.partition("=")
        path = Path(source if sep else clip)
        paths[name if sep else path.stem] = path
    given = {"kind": args.board, "inner_corners": list(args.pattern) if args.pattern else None,
             "square_mm": args.square, **_board_options(args)}
    board.update({k: v for k, v in given.items() if v is not None})
    if not paths:
        raise InputError("give the calibration clips (CLIP ... or --ride BUNDLE)")
    if wand_m is None and ("inner_corners" not in board or "square_mm" not in board):
        raise InputError("say which board the clips show: --pattern CxR and --square MM (or --ride BUNDLE), "
                         "or --wand LENGTH_M for a wand's clips")
    return paths, board, wand_m


def _check_calibration(args: argparse.Namespace) -> int:
    """Run `check-calibration`: print the verdict and each camera's sentences; 1 when to film again."""
    from saddlescope.services.rigs.calibration_check import (
        SAMPLE_FPS,
        check_calibration_clips,
        check_document,
        check_wand_clips,
    )

    paths, board, wand_m = _check_sources(args)
    if wand_m is not None:
        check = check_wand_clips(paths, wand_m, on_progress=_print_progress,
                                 **({"sample_fps": args.sample_fps} if args.sample_fps else {}))
    else:
        check = check_calibration_clips(paths, board, sample_fps=args.sample_fps or SAMPLE_FPS,
                                        on_progress=_print_progress)
    document = check_document(check)
    if args.json_out:
        _write_json(document, args.json_out)
    for name, camera in document["cameras"].items():
        print(f"{name}: {check.what} in {camera['views']} of {camera['frames_sampled']} frames looked at")
        for finding in camera["findings"]:
            print(f"  {finding['detail']}")
    print(f"{document['verdict']} ({document['seconds']:g} s)")
    return 1 if check.film_again else 0


def _add_synth_parser(sub) -> None:
    """`saddlescope synth`: its options (the arena's rigs, gaits, skin, frame clocks, flash)."""
    s = sub.add_parser("synth", help="write a synthetic ride bundle with truth.json")
    s.add_argument("out", help="output folder")
    s.add_argument("--gait", default="canter", choices=["walk", "sitting_trot", "rising_trot", "canter"])
    s.add_argument("--seed", type=int, default=0)
    s.add_argument("--size", type=_size, default=None, help="WxH, overrides the rig's resolution")
    s.add_argument("--fps", type=float, default=None, help="overrides the rig's frame rate")
    s.add_argument("--duration", type=float, default=None, help="motion clip length in seconds")
    s.add_argument("--rig", default="thesis", choices=["thesis", "wide", "wide_partial"],
                   help="wide_partial: 1280x720 cameras 1.8 m apart whose side cameras see part of the crossing")
    s.add_argument("--board-band", type=float, default=None,
                   help="carry the calibration board only through this central share (0-1] of the volume")
    s.add_argument("--speed", type=_speed_range, default=None, help="LO-HI m/s, overrides the gait's speed band")
    s.add_argument("--skin", default="stride_locked", choices=["stride_locked", "noise", "none"],
                   help="the markers' skin sliding: locked to the stride (default, as on a real flank), "
                        "small random noise only, or none (markers fixed to the saddle body)")
    s.add_argument("--layout", default="thesis", choices=["thesis", "triangle"],
                   help="markers 1-3 on the flank: a shallow V as in the thesis (default), or a triangle with "
                        "the middle marker about 10 cm below the others (fixes the saddle's roll far better)")
    s.add_argument("--variable-frame-rate", action="store_true",
                   help="the middle and right cameras record like phones: jittered frame intervals and "
                        "dropped frames, each frame stamped with its instant")
    s.add_argument("--no-flash", action="store_true",
                   help="no sync flash in the clips: the cameras are synchronised from the markers' motion")
    s.add_argument("--boot", type=float, default=0.0, metavar="SHARE",
                   help="a rider's boot swings over the rear marker for this share (0-0.25) of every stride")
    s.add_argument("--readout-ms", type=float, default=0.0,
                   help="a phone's rolling shutter: rows exposed one after another over this many ms (0-40)")
    s.add_argument("--crf", type=int, default=20, help="x264 compression of the clips (18 fine, 28 a phone's)")
    s.add_argument("--passes", type=int, default=1,
                   help="the horse passes the cameras this many times (1-6) in the one motion clip, out of view "
                        "for a few seconds between passes")
    s.add_argument("--calibration", default="board", choices=["board", "wand", "board+wand"],
                   help="board: the board walk; wand: a wand waved through the volume and close-up boards; "
                        "board+wand: the board walk and a wand walked along the track, which refines it")
    s.add_argument("--wand-seconds", type=float, default=24.0, help="how long the wand is filmed (s)")


class _BoardKinds:
    """The calibration board kinds, imported only when `calibrate` checks or lists them.

    The registry fills as the board modules import, and they pull OpenCV and scipy in: 3 s of every
    command's start-up (`saddlescope --help` included) before this was lazy.
    """

    @staticmethod
    def _kinds() -> list[str]:
        from saddlescope.core.calibration.boards import BOARD_KINDS

        return BOARD_KINDS

    def __contains__(self, kind: object) -> bool:
        return kind in self._kinds()

    def __iter__(self):
        return iter(self._kinds())


# `saddlescope bench --only`'s choices (bench.SECTION_NAMES, named here so the parser imports no numpy)
_BENCH_SECTIONS = ("detection", "calibration", "calibration_check", "wand", "speed", "footage", "floor",
                   "accuracy", "rolling_shutter", "similarity", "service", "coverage", "dashboard")


def _add_calibrate_parser(sub) -> None:
    """``saddlescope calibrate``: cameras from image globs or videos, known lenses held."""
    s = sub.add_parser("calibrate", help="calibrate cameras from image globs or videos, or the rig from a wand")
    s.add_argument("--pattern", type=_pattern, default=None, help="inner corners CxR, e.g. 9x6")
    s.add_argument("--square", type=float, default=None, help="square size in mm")
    s.add_argument("--wand", type=float, default=None, metavar="LENGTH_M",
                   help="the --camera clips film a wand of this length (m, between its two markers' centres) "
                        "waved through the riding area: poses and scale from the wand, lenses from --close-up "
                        "board clips or --intrinsics")
    s.add_argument("--close-up", dest="close_up", type=_camera_source, action="append", default=[],
                   metavar="NAME=SOURCE", help="with --wand: a board filmed close to camera NAME, for its lens")
    _add_board_arguments(s)
    s.add_argument("--camera", type=_camera_source, action="append", required=True, metavar="NAME=SOURCE")
    s.add_argument("--json", dest="json_out", default=None)
    s.add_argument("--toml", dest="toml_out", default=None, help="also write an anipose-style TOML")
    s.add_argument("--intrinsics", type=_intrinsics_source, action="append", default=[], metavar="[NAME=]FILE",
                   help="known intrinsics (an earlier calibration's JSON or TOML, anipose / caliscope, or a lens "
                        "profile JSON): held, only the poses fitted; NAME= picks the camera")


def _add_similar_parser(sub) -> None:
    """``saddlescope similar``: how alike two rides or recordings move, or the matrix of many."""
    s = sub.add_parser("similar", help="how alike two analysed rides (result JSON) or C3D/TRC recordings move; "
                                       "over more recordings or a folder, the matrix of every pair")
    s.add_argument("files", nargs="+", metavar="FILE",
                   help="two result JSONs of `saddlescope analyze`, or C3D / TRC files or folders of them")
    s.add_argument("--markers", default=None,
                   help="C3D/TRC: the labels to compare, L1,L2,...; results: saddle, M1, M2, M3 or all")
    s.add_argument("--map", dest="label_map", action="append", default=None, metavar="A=B",
                   help="C3D/TRC: label A of the first file is label B of the second (repeatable)")
    s.add_argument("--up", default=None, choices=["x", "y", "z"],
                   help="C3D/TRC: the vertical axis (the alignment then only turns about it)")
    s.add_argument("--alignment", default=None, choices=["cycle_phase", "subsequence_dtw"],
                   help="C3D/TRC pair: force the time alignment (default: cycle phase where both are periodic)")
    s.add_argument("--json", dest="json_out", default=None, help="also write the answer here")
    s.add_argument("--csv", dest="csv_out", default=None, help="many recordings: write the matrix as CSV")
    s.add_argument("--png", dest="png_out", default=None, help="many recordings: write the matrix as a heat map")


def build_parser() -> argparse.ArgumentParser:
    """The ``saddlescope`` command's argument parser, one sub-command per task."""
    p = argparse.ArgumentParser(prog="saddlescope", description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")

    s = sub.add_parser("demo", help="make a synthetic ride if none exists, process it, serve the dashboard")
    s.add_argument("--no-serve", action="store_true", help="process, print the indicators as JSON, exit")
    s.add_argument("--host", default="127.0.0.1")
    s.add_argument("--port", type=int, default=8000)

    s = sub.add_parser("serve", help="the API and the dashboard")
    s.add_argument("--host", default="127.0.0.1")
    s.add_argument("--port", type=int, default=8000)

    sub.add_parser("worker", help="a Celery worker (needs SADDLESCOPE_BROKER_URL)")

    s = sub.add_parser("sweep", help="remove abandoned uploads and partial writes (workers do it hourly)")
    s.add_argument("--older-than-h", type=float, default=None,
                   help="left untouched this many hours (default: SADDLESCOPE_UPLOAD_EXPIRY_S)")

    _add_synth_parser(sub)
    _add_check_parser(sub)

    s = sub.add_parser("analyze", help="run the whole pipeline locally on a ride bundle (folder or zip)")
    s.add_argument("ride")
    s.add_argument("--json", dest="json_out", default=None, help="write the result here (else stdout)")
    s.add_argument("--sync", default=None, choices=["flash", "motion"],
                   help="how the cameras are synchronised (default: ride.json's; without a flash the markers' "
                        "motion is used anyway)")

    _add_calibrate_parser(sub)

    s = sub.add_parser("import", help="read a C3D or TRC motion-capture file: its labels, rate, units, warnings")
    s.add_argument("file")
    s.add_argument("--json", dest="json_out", default=None)

    _add_similar_parser(sub)

    s = sub.add_parser("analyze-mocap", help="analyse a C3D or TRC file as a ride: three markers, a point")
    s.add_argument("file")
    s.add_argument("--markers", type=_labels, required=True, metavar="L1,L2,L3",
                   help="the labels standing for the horse markers M1, M2, M3")
    s.add_argument("--point", default=None, metavar="S", help="the label of the point to report (the saddle's)")
    s.add_argument("--offset", type=_offset, default=(0.0, 0.0, 0.0), metavar="DX,DY,DZ",
                   help="without --point: the point's offsets (mm) from the markers' centroid in their body "
                        "frame (x from L1 to L2, z normal to the three markers' plane); default 0,0,0")
    s.add_argument("--up", default=None, help="the lab's vertical axis: x, y, z or -x, ... (default: the file's "
                                              "own, else z for C3D and y for TRC)")
    s.add_argument("--strides", type=int, default=None, help="whole strides analysed (default 2)")
    s.add_argument("--gait", default=None, choices=["walk", "sitting_trot", "rising_trot", "canter"])
    s.add_argument("--json", dest="json_out", default=None, help="write the result here (else stdout)")

    s = sub.add_parser("bench", help="performance benchmarks, ratios measured side by side")
    s.add_argument("--json", dest="json_out", default=None)
    s.add_argument("--quick", action="store_true", help="smaller inputs, for a smoke test")
    s.add_argument("--only", metavar="SECTION[,SECTION]", help=f"measure these alone: {', '.join(_BENCH_SECTIONS)}")
    return p


def run(args: argparse.Namespace) -> int:
    """Run the sub-command `args` names; returns the process's exit status."""
    cmd = args.command
    if cmd == "synth":
        from saddlescope.arena import RenderOptions
        from saddlescope.io.synth_writer import write_ride_bundle

        path = write_ride_bundle(Path(args.out), gait=args.gait, seed=args.seed, rig=args.rig,
                                 size=args.size, fps=args.fps, duration_s=args.duration,
                                 board_band=args.board_band, speed_range_m_s=args.speed,
                                 options=RenderOptions(skin_motion=args.skin, marker_layout=args.layout,
                                                       variable_frame_rate=args.variable_frame_rate,
                                                       flash=not args.no_flash, boot_share=args.boot,
                                                       readout_s=args.readout_ms / 1000.0, crf=args.crf,
                                                       passes=args.passes),
                                 calibration=args.calibration, wand_s=args.wand_seconds)
        print(f"wrote synthetic ride bundle {path}", file=sys.stderr)
        return 0
    if cmd == "analyze":
        from saddlescope.services.analysis.ride_bundle import analyze_bundle

        overrides = {"sync": {"method": args.sync}} if args.sync else None
        result = analyze_bundle(Path(args.ride), on_progress=_print_progress, meta_overrides=overrides)
        _write_json(result, args.json_out)
        return 0
    if cmd == "calibrate":
        return _calibrate(args)
    if cmd == "import":
        from saddlescope.io.mocap import read_mocap

        _write_json(read_mocap(Path(args.file)).summary(), args.json_out)
        return 0
    if cmd == "similar":
        return _similar(args)
    if cmd == "check-calibration":
        return _check_calibration(args)
    if cmd == "analyze-mocap":
        from saddlescope.services.analysis.mocap import analyze_mocap_file

        result = analyze_mocap_file(Path(args.file), args.markers, point=args.point, offset_mm=args.offset,
                                    up=args.up, strides=args.strides, gait=args.gait)
        _write_json(result, args.json_out)
        if args.json_out:
            s, ind = result["source"], result["indicators"]
            print(f"{s['file']}: period {result['period_s']:.3f} s, speed {ind['vel_x_avg_kmh']:.2f} km/h, "
                  f"{s['up']} up; result in {args.json_out}", file=sys.stderr)
        return 0
    if cmd == "bench":
        from saddlescope.bench import run_benchmarks, sections_named

        try:
            sections_named(args.only)
        except ValueError as exc:
            print(f"saddlescope bench: {exc}", file=sys.stderr)
            return 2
        result = run_benchmarks(quick=args.quick, only=args.only)
        _write_json(result, args.json_out)
        if args.json_out:
            print(json.dumps(result, indent=2))
        return 0
    if cmd in ("demo", "serve", "worker", "sweep"):
        from saddlescope.server import PortInUse

        try:
            return _run_service(args)
        except PortInUse as exc:  # one plain sentence, no bind error or traceback
            print(f"saddlescope {cmd}: {exc}", file=sys.stderr)
            return 2
    raise AssertionError(cmd)


def _calibrate(args: argparse.Namespace) -> int:
    """``saddlescope calibrate``: a board's clips (or a wand's) to a calibration document."""
    from saddlescope.core.calibration.boards import DEFAULT_BOARD_KIND
    from saddlescope.io.calibration_files import calibrate_sources, intrinsics_for_cameras

    cameras = dict(args.camera)
    if args.wand is not None:
        return _calibrate_wand(args, cameras)
    if args.pattern is None or args.square is None:
        print("saddlescope calibrate: --pattern and --square are required (the board's inner corners and "
              "square size), unless --wand gives a wand's length", file=sys.stderr)
        return 2
    result = calibrate_sources(cameras, pattern=args.pattern, square_mm=args.square,
                               board_kind=args.board or DEFAULT_BOARD_KIND, board_options=_board_options(args),
                               toml_out=args.toml_out,
                               intrinsics=intrinsics_for_cameras(args.intrinsics, list(cameras)) or None)
    _write_json(result, args.json_out)
    return 0


def _run_service(args: argparse.Namespace) -> int:
    """The commands of the service itself: demo, serve, worker, sweep."""
    cmd = args.command
    if cmd == "demo":
        from saddlescope.demo import run_demo

        return run_demo(serve=not args.no_serve, host=args.host, port=args.port)
    if cmd == "serve":
        from saddlescope.server import serve

        serve(host=args.host, port=args.port)
        return 0
    if cmd == "sweep":
        from saddlescope.db.session import session_factory_for
        from saddlescope.services.uploads.intake import sweep_abandoned
        from saddlescope.settings import get_settings
        from saddlescope.storage import open_storage

        settings = get_settings()
        max_age_s = args.older_than_h * 3600 if args.older_than_h is not None else settings.upload_expiry_s
        swept = sweep_abandoned(session_factory_for(settings.database_url), open_storage(settings),
                                max_age_s=max_age_s)
        print(", ".join(f"{what}: {n}" for what, n in swept.items()))
        return 0
    from saddlescope_worker.app import run_worker

    return run_worker()


def _print_progress(fraction: float, stage: str) -> None:
    print(f"[{fraction * 100:5.1f} %] {stage}", file=sys.stderr, flush=True)


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``saddlescope``: parse `argv` (the command line when None) and run; returns the exit status."""
    args = build_parser().parse_args(argv)
    from saddlescope.io.malloc import limit_frame_memory

    limit_frame_memory()  # before any thread starts: decoded frames are given back when freed (issue 39)
    try:
        return run(args)
    except SaddleScopeError as exc:
        print(f"saddlescope {args.command}: {exc}", file=sys.stderr)
        return 2
    except FileNotFoundError as exc:
        print(f"saddlescope {args.command}: file not found: {exc.filename or exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())
