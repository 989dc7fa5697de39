"""Find the trials of a recording session and open each one as a RawTrial, whatever its format.

A session folder raw/tool/<session>/ holds trials in one of three layouts:
- native (what our rig and the simulator write): <trial>/meta.json + digit_*/ + force.log
- the public dataset of study 000: data_normal/<trial>/ and data_shear/<trial>/ (tactile1,
  tactile2, force); tools and poses, which that layout does not record, come from the
  session's trials.csv (trial,tool,orientation_deg,insertion_mm), required
- ROS bags: <trial>.bag (ROS1) or <trial>/metadata.yaml (ROS2 sqlite3/mcap), each with a
  <trial>.meta.json sidecar; topic names from params (tool_ingest.ros_topics)
"""

from __future__ import annotations

import csv
import io
from pathlib import Path

import numpy as np

from tactilepipe.core.csvtext import read_text_table
from tactilepipe.core.errors import InputError
from tactilepipe.tool.formats.native_layout import check_tool_name
from tactilepipe.tool.formats.raw import RawTrial, SensorFrames

PUBLIC_KINDS = {"data_normal": "normal", "data_shear": "shear"}
PUBLIC_RATE_HZ = 15.0          # the public rig samples frames and force together at 15 FPS


def trial_format(path: str | Path) -> str | None:
    """native, public or ros for a trial's path (None when it is not a trial)."""
    path = Path(path)
    if path.is_dir() and (path / "meta.json").exists():
        return "native"
    if path.is_dir() and path.parent.name in PUBLIC_KINDS:
        return "public"
    if path.suffix == ".bag" or (path.is_dir() and (path / "metadata.yaml").exists()):
        return "ros"
    return None


def list_trials(session_dir: str | Path) -> list[tuple[str, Path, str]]:
    """(trial name, path, format) of every trial in a session, sorted by name."""
    session_dir = Path(session_dir)
    if not session_dir.is_dir():
        raise InputError(session_dir, "session folder not found")
    found = []
    for path in sorted(session_dir.iterdir()):
        if path.is_dir() and path.name in PUBLIC_KINDS:
            found += [(f"{path.name}-{t.name}", t, "public") for t in sorted(path.iterdir()) if t.is_dir()]
        elif (fmt := trial_format(path)) is not None:
            found.append((path.stem if path.is_file() else path.name, path, fmt))
    public = [path for _, path, fmt in found if fmt == "public"]
    if public:
        check_public_session(session_dir, public)
    if not found:
        raise InputError(session_dir, "no trials found (native trial folders, data_normal/ or data_shear/, "
                                      "or ROS bags with .meta.json sidecars)")
    return found


TRIALS_CSV = "trials.csv"
TRIALS_HEADER = ("trial", "tool", "orientation_deg", "insertion_mm")


def read_trials_csv(session_dir: str | Path) -> dict[str, dict]:
    """trials.csv of a public-layout session: trial -> tool, orientation_deg, insertion_mm.

    The public layout does not record which tool a trial used; every split by tool (and the
    report) needs it, so the file is required. A trial is named by its folder (t0) or, where
    data_normal/ and data_shear/ reuse a name, by kind folder and name (data_normal/t0). Rows
    with an empty tool or pose (the template `tactilepipe study000-unpack` writes) are left out:
    check_public_session names those trials as lacking a tool.
    """
    path = Path(session_dir) / TRIALS_CSV
    if not path.exists():
        raise InputError(path, f"missing: a public-layout session needs {TRIALS_CSV} "
                               f"({','.join(TRIALS_HEADER)}): the layout does not record the tool of a trial")
    reader = csv.DictReader(io.StringIO(read_text_table(path, TRIALS_CSV), newline=""))
    reader.fieldnames = [f.strip() for f in reader.fieldnames or []]
    if not set(TRIALS_HEADER) <= set(reader.fieldnames):
        raise InputError(path, f"header must hold {','.join(TRIALS_HEADER)} (found {reader.fieldnames})", "line 1")
    out: dict[str, dict] = {}
    listed: set[str] = set()
    for line, row in enumerate(reader, start=2):
        values = {k: (row.get(k) or "").strip() for k in TRIALS_HEADER}
        if not values["trial"]:
            raise InputError(path, "trial must not be empty", f"line {line}")
        if values["trial"] in listed:
            raise InputError(path, f"trial {values['trial']} is listed again", f"line {line}")
        listed.add(values["trial"])
        if not all(values.values()):
            continue                  # a template row not filled in yet: the trial lacks a tool (or pose)
        check_tool_name(values["tool"], path, f"line {line}")
        try:
            meta = {"tool": values["tool"], "orientation_deg": float(values["orientation_deg"]),
                    "insertion_mm": float(values["insertion_mm"])}
        except ValueError as exc:
            raise InputError(path, f"expected {','.join(TRIALS_HEADER)} ({exc})", f"line {line}") from None
        out[values["trial"]] = meta
    return out


def public_trial_meta(table: dict[str, dict], trial_dir: Path) -> dict | None:
    return table.get(f"{trial_dir.parent.name}/{trial_dir.name}", table.get(trial_dir.name))


def check_public_session(session_dir: Path, trial_dirs: list[Path]) -> None:
    """InputError naming trials.csv and every public trial it gives no tool for (before any job runs)."""
    table = read_trials_csv(session_dir)
    lacking = [f"{t.parent.name}/{t.name}" for t in trial_dirs if public_trial_meta(table, t) is None]
    if lacking:
        shown = ", ".join(lacking[:10]) + (f" and {len(lacking) - 10} more" if len(lacking) > 10 else "")
        raise InputError(session_dir / TRIALS_CSV, f"no tool for {len(lacking)} of {len(trial_dirs)} public "
                                                  f"trials: {shown}; complete their rows "
                                                  f"({','.join(TRIALS_HEADER)})")


def open_public_trial(trial_dir: Path) -> RawTrial:
    from tactilepipe.tool.formats.public_layout import read_public_trial
    kind = PUBLIC_KINDS[trial_dir.parent.name]
    data = read_public_trial(trial_dir, kind)
    n = len(data["force_n"])
    host_ns = (np.asarray(data["index"], np.int64) * (1e9 / PUBLIC_RATE_HZ)).astype(np.int64)
    # the public labels are magnitudes; put them back in the Nano17 frame (a press reads Fz < 0)
    force = np.zeros((n, 3))
    if kind == "normal":
        force[:, 2] = -np.asarray(data["force_n"])
    else:
        force[:, 0] = data["force_n"]
    session_dir = trial_dir.parent.parent
    check_public_session(session_dir, [trial_dir])
    meta = public_trial_meta(read_trials_csv(session_dir), trial_dir)
    # frame i is the i-th kept, its file's NNNN is index[i] (labels dropped below 0 N, numbers skipped)
    index = np.asarray(data["index"], np.int64)
    frames = {name: SensorFrames(host_ns, (lambda imgs: lambda i: imgs[i])(data[key]),
                                 [f"{trial_dir}/{sub} frame {k}" for k in index], index)
              for name, key, sub in (("digit_left", "frames_left", "tactile1"), ("digit_right", "frames_right", "tactile2"))}
    return RawTrial(trial=f"{session_dir.name}/{trial_dir.parent.name}-{trial_dir.name}", kind=kind,
                    frames=frames, force_host_ns=host_ns, force_n=force, source=str(trial_dir),
                    clock={"method": "public_layout_paired_by_index", "offset_s": 0.0},
                    drops={"public: below 0 N": int(data.get("dropped", 0))},
                    reference={"digit_left": data["reference_left"], "digit_right": data["reference_right"]}, **meta)


def trial_files(path: str | Path, fmt: str, session_dir: str | Path) -> list[str]:
    """Every file reading the trial at ``path`` opens: its own files, and the session's files it
    takes facts from (native: nano17.cal; public: trials.csv; ROS: the bag's sidecar meta.json).
    The workflow declares exactly these as the trial's inputs."""
    path, session_dir = Path(path), Path(session_dir)
    files = [str(p) for p in sorted(path.rglob("*")) if p.is_file()] if path.is_dir() else [str(path)]
    if fmt == "public":
        files.append(str(session_dir / TRIALS_CSV))
    elif fmt == "native":
        files.append(str(session_dir / "nano17.cal"))
    else:
        from tactilepipe.tool.formats.rosbag import sidecar_path
        if sidecar_path(path).is_file():
            files.append(str(sidecar_path(path)))
    return files


def open_trial(path: str | Path, fmt: str, ros_topics: dict | None = None) -> RawTrial:
    path = Path(path)
    if fmt == "native":
        from tactilepipe.tool.formats.native_import import read_native_trial
        return read_native_trial(path)
    if fmt == "public":
        return open_public_trial(path)
    if fmt == "ros":
        from tactilepipe.tool.formats.rosbag import DEFAULT_TOPICS, read_ros_trial, read_sidecar_meta
        meta = read_sidecar_meta(path)
        raw = read_ros_trial(path, meta, ros_topics or DEFAULT_TOPICS)
        raw.trial = f"{path.parent.name}/{raw.trial.split('/')[-1]}"
        return raw
    raise InputError(path, f"unknown trial format '{fmt}'")
