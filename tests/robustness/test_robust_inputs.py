"""Inputs independently written recordings contain that must work (or be noted): VGA frames,
PNG frames in the public layout, a byte-order mark in frames.csv, frame files beyond
frames.csv (counted), landscape frames (noted in QC; one orientation per dataset)."""

from __future__ import annotations

import shutil

import cv2
import pytest

from tactilepipe.core.errors import InputError
from tactilepipe.tool.data.dataset import build_tool_dataset
from tactilepipe.tool.formats.trials import open_trial
from tactilepipe.tool.data.ingest import ingest_trial
from tactilepipe.tool.report.data import qc_markdown

from support.sessions import INGEST, N_FRAMES, SIZE, SYNC, digit_frame, make_native_session, make_public_session
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
            cv2.imwrite(str(native / s / f"frame_{i:06d}.png"), digit_frame(i, 640, 480))
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
