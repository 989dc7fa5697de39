"""`tactilepipe record` and `tactilepipe live`: the study-000 rig's two DIGITs and Arduino (docs/rig.md)."""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

from tactilepipe.cli.registry import arg, command
from tactilepipe.rig.settings import BAUD, MODES
from tactilepipe.tool import checks as tool_checks

# the cross-key checks a stage runs on params.yaml by hand: its study's (the workflow runs every
# study's: tactilepipe/studies.py)
TOOL_CHECKS = (tool_checks.check,)

CAMERA_HELP = "a /dev/video* node, the DIGIT's serial number (e.g. D20262), or a video file / image sequence " \
              "(frame_%%06d.png) played at the mode's rate"

# from the rig's plain settings: every CLI call builds every parser, and a pipeline stage must not
# load the rig's device code (OpenCV capture, pyserial)
MODE_NAMES = tuple(MODES)


def seconds(text: str) -> float:
    """--seconds: a finite length above 0 (a negative or NaN one would record a trial of nothing)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number of seconds") from None
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"{text} is not a length: give a finite number of seconds above 0")
    return value


def finite(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"{text} is not a finite number")
    return value


def two_cameras(left: str, right: str) -> tuple[str, str]:
    """The two fingers' sources (after a serial number is resolved to its node): one camera given
    for both would record (or estimate on) one finger's view twice."""
    if Path(left).resolve() == Path(right).resolve():
        from tactilepipe.core.errors import ArgumentError
        raise ArgumentError(f"--left and --right are the same camera ({left}): each finger needs its own DIGIT")
    return left, right


@command("record", "record trials in the rig's layout from two DIGITs and the Nano17's Arduino",
         description="Record one trial, or a series with a prompt between trials, into SESSION (raw/tool/<session>/, "
                     "the rig's layout: docs/rig.md). A trial that stops half-way is set aside under "
                     "raw/tool/incomplete/<session>/, never added.",
         formatter_class=argparse.ArgumentDefaultsHelpFormatter,
         args=(arg("--list-digits", action="store_true", help="list the DIGITs plugged in (serial, node) and exit"),
               arg("--session", help="session folder, e.g. raw/tool/2026-11-26-screwdrivers"),
               arg("--left", help=f"left finger's camera: {CAMERA_HELP}"),
               arg("--right", help=f"right finger's camera: {CAMERA_HELP}"),
               arg("--mode", choices=MODE_NAMES, default="qvga60", help="DIGIT stream mode (width x height @ fps)"),
               arg("--port", help="the Arduino's serial port, e.g. /dev/ttyACM0"),
               arg("--baud", type=int, default=BAUD, help="the firmware's baud rate"),
               arg("--calibration", help="the Nano17's ATI .cal file (copied into the session once)"),
               arg("--tool", help="tool name: lowercase letters, digits and _ (e.g. screwdriver_1)"),
               arg("--kind", choices=["normal", "shear"], help="pressing (normal) or sliding (shear) trials"),
               arg("--orientation-deg", type=float, default=0.0, help="tilt of the tool axis in the grasp"),
               arg("--insertion-mm", type=float, default=0.0,
                   help="mm from the gel's fingertip edge to the butt end of the handle"),
               arg("--seconds", type=seconds, help="length of each trial"),
               arg("--trials", type=int, default=1, help="how many trials to record, with a prompt before each"),
               arg("--trial", help="the trial's name (default: <tool>_<kind>_<NNN>, the next free number)"),
               arg("--no-prompt", action="store_true", help="start each trial at once (no Enter)")))
def cmd_record(args, p) -> int | None:
    from tactilepipe.rig.cameras import list_digits
    if args.list_digits:
        digits = list_digits()
        for d in digits:
            print(f"{d.serial}\t{d.node}\t{d.manufacturer} DIGIT rev {d.revision}")
        if not digits:
            print("no DIGIT found (is it plugged in, and is /sys/class/video4linux readable?)", file=sys.stderr)
        return None
    from tactilepipe.core.errors import ArgumentError
    from tactilepipe.rig.cameras import resolve_source
    from tactilepipe.rig.record import (Devices, TrialIncomplete, check_plain_name, check_session_path,
                                        install_calibration, next_trial_name, record_trial)
    from tactilepipe.tool.formats.native_layout import TrialMeta, check_tool_name
    missing = [f"--{n.replace('_', '-')}" for n in ("session", "left", "right", "port", "tool", "kind", "seconds")
               if getattr(args, n) is None]
    if missing:
        raise ArgumentError(f"record needs {', '.join(missing)} (or --list-digits)")
    if args.trial and args.trials != 1:
        raise ArgumentError("--trial names one trial; leave it out to record a series (--trials N)")
    check_tool_name(args.tool, "--tool")
    session = Path(args.session)
    check_session_path(session)
    if args.trial:
        check_plain_name(args.trial, "--trial")
    session.mkdir(parents=True, exist_ok=True)
    install_calibration(session, Path(args.calibration) if args.calibration else None)
    devices = Devices(*two_cameras(resolve_source(args.left), resolve_source(args.right)), args.port, args.mode,
                      args.baud)
    for k in range(args.trials):
        name = args.trial or next_trial_name(session, f"{args.tool}_{args.kind}")
        if not args.no_prompt:
            print(f"trial {k + 1}/{args.trials}: {name}. Open the gripper or hold the tool without contact at "
                  f"the tip (frame 0 is the zero-force reference), then press Enter (q Enter stops)",
                  file=sys.stderr, flush=True)
            if sys.stdin.readline().strip().lower() == "q":
                break
        meta = TrialMeta(trial=name, tool=args.tool, kind=args.kind, orientation_deg=args.orientation_deg,
                         insertion_mm=args.insertion_mm)
        try:
            folder = record_trial(session, meta, devices, args.seconds)
        except TrialIncomplete as exc:
            print(f"tactilepipe record: {exc}", file=sys.stderr)
            return 1
        print(f"recorded {folder}", file=sys.stderr)
    return None


@command("live", "estimate the tool force live from the two DIGITs",
         description="Load a trained checkpoint, take the zero-force reference pair, then estimate the force for "
                     "every frame pair the cameras deliver; print it with its latency and log it (docs/rig.md).",
         formatter_class=argparse.ArgumentDefaultsHelpFormatter,
         checks=TOOL_CHECKS,
         params=("tool_ingest.stored_size", "predict"),
         args=(arg("--checkpoint", required=True, help="e.g. results/default/tool_normal/models/full/best.pt"),
               arg("--left", required=True, help=f"left finger's camera: {CAMERA_HELP}"),
               arg("--right", required=True, help=f"right finger's camera: {CAMERA_HELP}"),
               arg("--mode", choices=MODE_NAMES, default="qvga60", help="DIGIT stream mode"),
               arg("--seconds", type=seconds, default=60.0, help="how long to run"),
               arg("--log", default="live/estimates.csv", help="the log of (host_ns, frames, estimate, latency)"),
               arg("--reference", help="a reference.npz saved by an earlier run, instead of taking one at start"),
               arg("--label-range", nargs=2, type=finite, metavar=("MIN_N", "MAX_N"),
                   help="a public-code normal-force checkpoint: the force range its outputs were scaled to")))
def cmd_live(args, p) -> int | None:
    from tactilepipe.core.errors import ArgumentError
    from tactilepipe.rig.cameras import resolve_source
    from tactilepipe.rig.live import run_live
    from tactilepipe.tool.model.stream import prepare_process
    if args.label_range and not args.label_range[0] < args.label_range[1]:
        raise ArgumentError(f"--label-range {args.label_range[0]:g} {args.label_range[1]:g}: give MIN_N then MAX_N, "
                            f"MIN_N below MAX_N (the outputs' 0 and 1 map to them)")
    sources = two_cameras(resolve_source(args.left), resolve_source(args.right))
    prepare_process(p)                               # before torch loads: the portable pins are read then
    print("keep the fingers out of contact: the first frame pair is the zero-force reference"
          if args.reference is None else f"reference pair from {args.reference}", file=sys.stderr)
    summary = run_live(Path(args.checkpoint), sources, args.mode, p,
                       args.seconds, Path(args.log), Path(args.reference) if args.reference else None,
                       args.label_range)
    return 0 if summary.pairs and not summary.not_a_force else 1
