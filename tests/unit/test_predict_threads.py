"""`tactilepipe predict` takes its threads from params.yaml (predict group) and gives the caller's
setting back (the rate itself: benchmarks/bench_predict_load.py)."""

from __future__ import annotations

import io

import torch

from tactilepipe.core.config import load_params
from tactilepipe.tool.model.network import build_model, PAPER_WIDTH
from tactilepipe.tool.model.stream import stream_predictions
from tactilepipe.tool.model.checkpoint import CHECKPOINT_FORMAT

from support.sessions import make_native_session
from support.tool_data import quick_cfg


def test_predict_streams_on_the_configured_threads_and_restores_them(tmp_path, monkeypatch):
    p = load_params()
    trial = make_native_session(tmp_path) / "t00"
    cfg = quick_cfg(image_size=16)
    meta = {"variant": "full", "depth": 18, "image_size": 16, "normalise": "minmax",
            "label_stats": {"min": 0.0, "max": 30.0, "mean": 5.0, "std": 5.0}}
    torch.save({"format": CHECKPOINT_FORMAT, "model": build_model("full", 18, 16, "sigmoid", PAPER_WIDTH).state_dict(),
                "config": cfg.model_dump(), "meta": meta}, tmp_path / "m.pt")
    seen = []
    real = torch.set_num_threads
    monkeypatch.setattr(torch, "set_num_threads", lambda n: (seen.append(n), real(n)))
    before = torch.get_num_threads()
    out = io.StringIO()
    summary = stream_predictions(tmp_path / "m.pt", trial, "native", p, limit=5, out=out)
    assert summary["pairs"] == 5 and out.getvalue().startswith("pair,left_frame,right_frame,t_s,prediction_n,latency_ms")
    assert seen == [p["predict"]["num_threads"], before] and torch.get_num_threads() == before
