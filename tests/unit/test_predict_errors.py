"""`tactilepipe predict` on a checkpoint or a trial that cannot go together: one clear error naming
the file, never a library's exception from deep inside."""

from __future__ import annotations

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
                "config": cfg.model_dump(), "meta": {**META, **meta}}, path)
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


# --- non-finite weights and estimates: refused where they enter and leave --------------------------------

def _predict_cli(ckpt, trial, capsys) -> tuple[int, str]:
    """`tactilepipe predict`'s exit status and stderr (its estimates go to the stdout it was
    imported with, which pytest does not capture: stream_predictions shows them)."""
    from tactilepipe.cli.main import main
    status = main(["predict", "--checkpoint", str(ckpt), "--trial", str(trial), "--limit", "2"])
    return status, capsys.readouterr().err


def test_a_checkpoint_with_nan_weights_is_refused_naming_the_file_and_the_tensor(trial, tmp_path, capsys):
    ckpt = _checkpoint(tmp_path / "nan.pt")
    raw = torch.load(ckpt, weights_only=True)
    name = next(k for k, v in raw["model"].items() if v.is_floating_point() and v.numel() > 3)
    raw["model"][name].view(-1)[:3] = float("nan")
    torch.save(raw, ckpt)
    status, err = _predict_cli(ckpt, trial, capsys)
    assert status == 2 and err.count("\n") == 1, err
    assert f"nan.pt: weights: tensor '{name}' holds 3 non-finite value(s) (NaN or inf)" in err, err
    out = io.StringIO()
    with pytest.raises(InputError):
        stream_predictions(ckpt, trial, "native", load_params(), limit=2, out=out)
    assert out.getvalue() == ""                          # refused before any estimate


def test_an_estimate_that_is_not_finite_is_never_printed_as_a_force(trial, tmp_path, capsys):
    # finite weights, but a label scale that overflows: the estimate is inf
    ckpt = _checkpoint(tmp_path / "m.pt", label_stats={"min": 0.0, "max": float("inf"), "mean": 0.0, "std": 1.0})
    status, err = _predict_cli(ckpt, trial, capsys)
    assert status == 2 and err.count("\n") == 1, err
    assert "frame pair 0 (left frame 0, right frame 0): the model's estimate is" in err and "not a force" in err, err
    out = io.StringIO()
    with pytest.raises(InputError, match="not a force"):
        stream_predictions(ckpt, trial, "native", load_params(), limit=2, out=out)
    out = out.getvalue()
    assert out.startswith("pair,left_frame,right_frame,t_s,prediction_n,latency_ms\n"), out
    assert "inf" not in out.lower() and "nan" not in out.lower(), out


def test_weights_that_diverged_are_never_written(tmp_path):
    from tactilepipe.core.errors import TactilepipeError
    from tactilepipe.tool.model.checkpoint import save_checkpoint
    state = build_model("full", 18, 16, "sigmoid", 8).state_dict()
    name = next(k for k, v in state.items() if v.is_floating_point())
    state[name].view(-1)[0] = float("inf")
    path = tmp_path / "last.pt"
    with pytest.raises(TactilepipeError, match=rf"last.pt: not written: the trained weights diverged, tensor "
                                               rf"'{name}' holds 1 non-finite"):
        save_checkpoint({"format": CHECKPOINT_FORMAT, "model": state, "meta": {"epoch": 3}}, path)
    assert not path.exists() and list(tmp_path.iterdir()) == []


def test_the_same_weights_are_the_same_file_bytes(tmp_path):
    # the atomic write's temporary has a random name; torch.save given a path names its archive
    # folder after it, and DVC would then see every rebuilt checkpoint as changed
    from tactilepipe.tool.model.checkpoint import save_checkpoint
    state = build_model("full", 18, 16, "sigmoid", 8).state_dict()
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    for folder in ("a", "b"):
        save_checkpoint({"format": CHECKPOINT_FORMAT, "model": state, "meta": {"epoch": 3}}, tmp_path / folder / "best.pt")
    assert (tmp_path / "a" / "best.pt").read_bytes() == (tmp_path / "b" / "best.pt").read_bytes()
