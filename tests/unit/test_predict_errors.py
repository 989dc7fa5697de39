"""`tactilepipe predict` on a checkpoint or a trial that cannot go together: one clear error naming
the file, never a library's exception from deep inside."""

from __future__ import annotations

import dataclasses
import io

import pytest
import torch

from support.sessions import make_native_session
from support.tool_data import quick_cfg
from tactilepipe.core.config import load_params
from tactilepipe.core.errors import InputError
from tactilepipe.tool.model.checkpoint import CHECKPOINT_FORMAT
from tactilepipe.tool.model.network import build_model
from tactilepipe.tool.model.stream import stream_predictions

META = {"variant": "full", "depth": 18, "image_size": 16, "normalise": "minmax", "width": 8,
        "label_stats": {"min": 0.0, "max": 30.0, "mean": 5.0, "std": 5.0}}


@pytest.fixture(scope="module")
def trial(tmp_path_factory):
    return make_native_session(tmp_path_factory.mktemp("predict")) / "t00"


def _checkpoint(path, weights_variant="full", **meta):
    cfg = quick_cfg(image_size=16, width=8)
    torch.save({"format": CHECKPOINT_FORMAT, "model": build_model(weights_variant, 18, 16, "sigmoid", 8).state_dict(),
                "config": dataclasses.asdict(cfg), "meta": {**META, **meta}}, path)
    return path


def test_weights_of_another_variant_than_the_metadata_names_are_refused(trial, tmp_path):
    ckpt = _checkpoint(tmp_path / "m.pt", weights_variant="single", variant="full")
    with pytest.raises(InputError, match=r"m.pt: its weights do not fit the model its metadata describes "
                                         r"\(variant full, depth 18, width 8\): Missing key"):
        stream_predictions(ckpt, trial, "native", load_params(), limit=2, out=io.StringIO())


def test_cameras_that_never_overlap_are_named(trial, tmp_path):
    import shutil
    moved = tmp_path / "moved"
    shutil.copytree(trial.parent, moved)
    index = moved / "t00" / "digit_right" / "frames.csv"
    lines = index.read_text().splitlines()
    index.write_text("\n".join([lines[0]] + [f"{i},{int(ns) + 100_000_000_000}" for i, ns in
                                             (line.split(",") for line in lines[1:])]) + "\n")   # 100 s later
    with pytest.raises(InputError, match=r"no frame pair: no digit_left frame lies within half a frame period .*"
                                         r"are both cameras on the host clock"):
        stream_predictions(_checkpoint(tmp_path / "m.pt"), moved / "t00", "native", load_params(), limit=2,
                           out=io.StringIO())


def test_frames_standing_the_other_way_than_the_training_frames_are_refused(trial, tmp_path):
    ckpt = _checkpoint(tmp_path / "m.pt", frame_orientation="landscape")
    with pytest.raises(InputError, match=r"frames are portrait \(240x320\), the model was trained on landscape frames"):
        stream_predictions(ckpt, trial, "native", load_params(), limit=2, out=io.StringIO())
    summary = stream_predictions(_checkpoint(tmp_path / "p.pt", frame_orientation="portrait"), trial, "native",
                                 load_params(), limit=2, out=io.StringIO())
    assert summary["pairs"] == 2
