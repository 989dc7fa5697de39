"""Inputs independently written recordings contain that must work (or be noted): VGA frames,
PNG frames in the public layout, a byte-order mark in frames.csv, frame files beyond
frames.csv (counted), frame numbers the camera skipped (counted), landscape frames (noted in QC;
one orientation per dataset)."""

from __future__ import annotations

import shutil

import cv2
import pytest

from tactilepipe.core.errors import InputError
from tactilepipe.tool.data.dataset import build_tool_dataset
from tactilepipe.tool.formats.trials import open_trial
from tactilepipe.tool.data.ingest import ingest_trial
from tactilepipe.tool.report.data import qc_markdown

from support.sessions import (INGEST, N_FRAMES, SIZE, SYNC, digit_frame, finger_frame, make_native_session,
                              make_public_session)
from support.project import REPO


@pytest.fixture
def native(tmp_path):
    return make_native_session(tmp_path / "raw with spaces") / "t00"


@pytest.fixture
def public(tmp_path):
    return make_public_session(tmp_path / "pub lab") / "data_normal" / "t0"


def test_a_vga_native_trial_is_read(native, tmp_path):
    for s in ("digit_left", "digit_right"):
        for i in range(N_FRAMES):
            cv2.imwrite(str(native / s / f"frame_{i:06d}.png"), finger_frame(s, digit_frame(i, 640, 480)))
    info = ingest_trial(open_trial(native, "native"), tmp_path / "s.parquet", SIZE, INGEST)
    assert info["frame_size"] == {"digit_left": [480, 640], "digit_right": [480, 640]}


def test_frame_files_beyond_frames_csv_are_counted(native, tmp_path):
    shutil.copy(native / "digit_left" / "frame_000000.png", native / "digit_left" / "frame_000099.png")
    info = ingest_trial(open_trial(native, "native"), tmp_path / "s.parquet", SIZE, INGEST)
    assert info["drops"]["digit_left: frame files not in frames.csv"] == 1
    assert "digit_right: frame files not in frames.csv" not in info["drops"]


def test_frames_csv_with_a_byte_order_mark_is_read(native, tmp_path):
    path = native / "digit_right" / "frames.csv"
    path.write_bytes(b"\xef\xbb\xbf" + path.read_bytes())
    info = ingest_trial(open_trial(native, "native"), tmp_path / "s.parquet", SIZE, INGEST)
    assert info["frames"]["digit_right"] == N_FRAMES


def test_png_frames_in_the_public_layout_are_read(public, tmp_path):
    for side in ("tactile1", "tactile2"):
        for jpg in (public / side).glob("*.jpg"):
            cv2.imwrite(str(jpg.with_suffix(".png")), cv2.imread(str(jpg)))
            jpg.unlink()
    info = ingest_trial(open_trial(public, "public"), tmp_path / "s.parquet", SIZE, INGEST)
    assert info["frames"] == {"digit_left": 6, "digit_right": 6}


def test_landscape_frames_are_noted_and_not_mixed_with_portrait_ones(native, public, tmp_path):
    ingest_trial(open_trial(public, "public"), tmp_path / "pub.parquet", SIZE, INGEST)     # 64 x 48
    qc = build_tool_dataset([tmp_path / "pub.parquet"], "normal", tmp_path / "data", {**SYNC, "normal_sign": -1})
    note = qc_markdown({"kind": "normal", "trials": qc["trials"], "pairs": qc["pairs"], "image_size": SIZE}, "normal")
    assert "Frames recorded at 64x48 (width x height), resized to 32 x 32 px: the aspect ratio is not kept" in note
    ingest_trial(open_trial(native, "native"), tmp_path / "nat.parquet", SIZE, INGEST)     # 240 x 320
    with pytest.raises(InputError, match=r"frames are landscape, those of .* are portrait"):
        build_tool_dataset([tmp_path / "nat.parquet", tmp_path / "pub.parquet"], "normal", tmp_path / "mixed", SYNC)


def test_numbers_yaml_1_1_reads_as_strings_are_numbers_where_the_schema_wants_one(tmp_path):
    from tactilepipe.core.config import load_params
    from tactilepipe.core.errors import ConfigError
    text = (REPO / "params.yaml").read_text()
    assert "  tol: 0.0001" in text
    path = tmp_path / "params.yaml"
    path.write_text(text.replace("  tol: 0.0001", "  tol: 1e-4"))
    assert load_params(path)["mlp"]["tol"] == 1e-4
    path.write_text(text.replace("  tol: 0.0001", "  tol: 1e-4x"))          # still not a number
    with pytest.raises(ConfigError, match=r"'mlp.tol'"):
        load_params(path)


def _skip_frames(sensor_dir, numbers) -> None:
    """The camera dropped these frames: no row in frames.csv, no PNG."""
    lines = (sensor_dir / "frames.csv").read_text().splitlines()
    kept = [ln for ln in lines[1:] if int(ln.split(",")[0]) not in set(numbers)]
    (sensor_dir / "frames.csv").write_text("\n".join([lines[0], *kept]) + "\n")
    for n in numbers:
        (sensor_dir / f"frame_{n:06d}.png").unlink()


def test_frame_numbers_the_camera_skipped_are_counted_and_the_others_kept(native, tmp_path):
    from tactilepipe.tool.formats.native_layout import read_frame_table
    _skip_frames(native / "digit_left", [3, 4, 5])
    numbers, stamps = read_frame_table(native / "digit_left")
    assert list(numbers[:4]) == [0, 1, 2, 6] and len(stamps) == N_FRAMES - 3
    raw = open_trial(native, "native")
    left = raw.frames["digit_left"]
    assert left.number(3) == 6 and left.source[3].endswith("frame_000006.png")
    assert (left.load(3) == cv2.imread(left.source[3])).all()          # the 4th frame kept is file 6
    assert raw.frames["digit_right"].number(3) == 3
    info = ingest_trial(raw, tmp_path / "s.parquet", SIZE, INGEST)
    assert info["drops"]["digit_left: frames skipped by the camera"] == 3
    assert "digit_right: frames skipped by the camera" not in info["drops"]
    assert info["frames"] == {"digit_left": N_FRAMES - 3, "digit_right": N_FRAMES}


def test_leading_frames_the_camera_skipped_are_counted_too(native, tmp_path):
    _skip_frames(native / "digit_right", [0, 1])
    raw = open_trial(native, "native")
    assert raw.drops["digit_right: frames skipped by the camera"] == 2
    assert raw.frames["digit_right"].source[0].endswith("frame_000002.png")


def test_a_public_frame_is_named_by_its_files_index_when_an_earlier_label_was_dropped(tmp_path):
    from support.public_formats import write_public_trial
    frames = [digit_frame(i, 48, 64) for i in range(6)]
    write_public_trial(tmp_path / "pub", "t0", frames, frames, [3.0, -2.0, 6.0, 9.0, 6.0, 3.0], "normal")
    (tmp_path / "pub" / "trials.csv").write_text("trial,tool,orientation_deg,insertion_mm\nt0,knife,5,10\n")
    raw = open_trial(tmp_path / "pub" / "data_normal" / "t0", "public")
    left = raw.frames["digit_left"]
    assert raw.drops == {"public: below 0 N": 1}
    assert left.number(1) == 2 and left.source[1].endswith("tactile1 frame 2")
