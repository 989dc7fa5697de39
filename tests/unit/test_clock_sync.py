"""The force clock of native trials: glitches in the images leave the offset within a frame period
or are refused, never a silent shift; frozen cameras, flat force logs, an offset on the window's
edge and a low-confidence fit are named (tool/data/clock_sync.py via tool/data/ingest.py)."""

from __future__ import annotations

import copy
import json

import numpy as np
import pytest

from tactilepipe.core.config import load_params
from tactilepipe.core.errors import InputError
from tactilepipe.tool.data.ingest import ingest_trial, read_shard_info
from tactilepipe.tool.formats.raw import RawTrial, SensorFrames

INGEST = load_params()["tool_ingest"]
SIZE = 32
FPS, N_FRAMES = 30.0, 100
PERIOD_S = 1 / FPS
TRUE_SHIFT_S = 0.31          # the coarse force clock is this much early
# contact as faint as on a DIGIT: at 16 N the mean change over the frame is ~2 grey levels, a
# tenth of what dimming one frame by 20 % does
BLOB_DN_PER_N = 1.0


def force_curve(t):
    return 9 * np.exp(-((t - 1.1) / 0.25) ** 2) + 16 * np.exp(-((t - 2.3) / 0.3) ** 2)


def make_raw(glitch=None, seed: int = 0, force=force_curve) -> RawTrial:
    """Two noisy 48x64 cameras whose contact blob follows the force; the force log 0.5 s longer
    on both ends, stamped TRUE_SHIFT_S early. ``glitch(name, frames, stamps)`` edits both lists."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:48, 0:64]
    base = np.stack([90 + 40 * xx / 64, 110 + 30 * yy / 48, 150 + 0 * xx], -1).astype(np.float64)
    frames = {}
    for s, (name, gain) in enumerate((("digit_left", 1.0), ("digit_right", 0.7))):
        t = np.arange(N_FRAMES) / FPS + 0.002 * s
        imgs = []
        for ti in t:
            blob = gain * BLOB_DN_PER_N * force(ti) * np.exp(-((xx - 32) ** 2 + (yy - 24) ** 2) / 120.0)
            img = base + blob[..., None] + rng.normal(0, 2.0, base.shape)
            imgs.append(np.clip(img, 0, 255).astype(np.uint8))
        stamps = list((t * 1e9).astype(np.int64))
        if glitch is not None:
            glitch(name, imgs, stamps)
        frames[name] = SensorFrames(np.array(stamps, np.int64), (lambda im: lambda i: im[i])(imgs),
                                    [f"trial/{name}/frame_{i:06d}.png" for i in range(len(imgs))])
    ft = np.arange(-0.5, N_FRAMES / FPS + 0.5, 1 / 15)
    f = np.zeros((len(ft), 3))
    f[:, 2] = force(ft) + rng.normal(0, 0.03, len(ft))
    return RawTrial(trial="lab/t", tool="knife", kind="normal", orientation_deg=0.0, insertion_mm=10.0,
                    frames=frames, force_host_ns=((ft - TRUE_SHIFT_S) * 1e9).astype(np.int64), force_n=f,
                    source="lab/t", clock={"method": "serial_start+xcorr", "refine": True})


def shift_of(raw, tmp_path, ingest=INGEST) -> float:
    return ingest_trial(raw, tmp_path / "s.parquet", SIZE, ingest)["clock"]["refined_shift_s"]


def dim(k, factor):
    def glitch(name, imgs, stamps):
        if name == "digit_left":
            imgs[k] = (imgs[k] * factor).astype(np.uint8)
    return glitch


def black(k):
    def glitch(name, imgs, stamps):
        if name == "digit_right":
            imgs[k] = np.full_like(imgs[k], 14)      # near-black: above the all-black check
    return glitch


def dropped(ks):
    def glitch(name, imgs, stamps):
        if name == "digit_left":
            for k in sorted(ks, reverse=True):
                del imgs[k], stamps[k]
    return glitch


def test_a_clean_trial_finds_the_offset_within_a_few_ms(tmp_path):
    assert shift_of(make_raw(), tmp_path) == pytest.approx(TRUE_SHIFT_S, abs=0.005)


@pytest.mark.parametrize("glitch", [dim(0, 0.8), dim(1, 0.8), dim(40, 0.8), dim(99, 0.8), dim(3, 0.3),
                                    black(0), black(33), black(70), dropped([10]), dropped(range(30, 36)),
                                    dropped([0, 1])],
                         ids=["dim_first", "dim_second", "dim_mid", "dim_last", "dim_strong", "black_first",
                              "black_press", "black_mid", "drop_one", "drop_six", "drop_first_two"])
def test_one_glitch_leaves_the_offset_within_a_frame_period(tmp_path, glitch):
    clean = shift_of(make_raw(), tmp_path)
    assert abs(shift_of(make_raw(glitch), tmp_path) - clean) < PERIOD_S


def test_a_frozen_camera_is_refused(tmp_path):
    def frozen(name, imgs, stamps):
        if name == "digit_right":
            imgs[:] = [imgs[0]] * len(imgs)
    with pytest.raises(InputError, match=r"digit_right: frames 0-99 of 100 are bit-identical .* the camera froze"):
        shift_of(make_raw(frozen), tmp_path)
    assert not (tmp_path / "s.parquet").exists()


def test_a_camera_frozen_during_a_press_is_refused(tmp_path):
    def stall(name, imgs, stamps):
        if name == "digit_left":
            imgs[60:75] = [imgs[60]] * 15              # 2.0-2.5 s: the second press rises
    with pytest.raises(InputError, match=r"trial/digit_left/frame_000060.png: digit_left: frames 60-74"):
        shift_of(make_raw(stall), tmp_path)


def test_a_flat_force_log_leaves_the_trial_out_naming_why_or_is_refused_as_configured(tmp_path):
    """A trial left out never stops the build (a light press is lab data); on_low_score: refuse refuses it."""
    info = ingest_trial(make_raw(force=lambda t: 0 * t + 0.1), tmp_path / "s.parquet", SIZE, INGEST)
    assert info["clock"]["dropped"].startswith("clock not aligned: the force log is flat"), info["clock"]
    refuse = copy.deepcopy(INGEST)
    refuse["clock"]["on_low_score"] = "refuse"
    with pytest.raises(InputError, match=r"^lab/t: cannot align the force clock to the cameras: the force log is flat"):
        shift_of(make_raw(force=lambda t: 0 * t + 0.1), tmp_path, refuse)


def test_an_offset_on_the_edge_of_the_window_leaves_the_trial_out(tmp_path):
    ingest = copy.deepcopy(INGEST)
    ingest["max_offset_s"] = 0.2                      # the true offset (0.31 s) lies beyond
    info = ingest_trial(make_raw(), tmp_path / "s.parquet", SIZE, ingest)
    assert "on the edge of the search window" in info["clock"]["dropped"], info["clock"]
    assert info["clock"]["refined_shift_s"] == 0.0


def _unrelated(name, imgs, stamps):
    # images that do not follow the force: each camera's frames shuffled
    order = np.random.default_rng(1 if name == "digit_left" else 2).permutation(len(imgs))
    imgs[:] = [imgs[i] for i in order]


def test_a_low_confidence_fit_is_refused_or_falls_back_to_the_host_clock_as_configured(tmp_path):
    refuse = copy.deepcopy(INGEST)
    refuse["clock"]["on_low_score"] = "refuse"
    with pytest.raises(InputError, match=r"^lab/t: cannot align the force clock to the cameras"):
        shift_of(make_raw(_unrelated), tmp_path, refuse)
    ingest = copy.deepcopy(INGEST)
    ingest["clock"]["on_low_score"] = "host_clock"
    info = ingest_trial(make_raw(_unrelated), tmp_path / "s.parquet", SIZE, ingest)
    assert info["clock"]["refined_shift_s"] == 0.0 and info["clock"]["fallback"].startswith("host clock")
    assert read_shard_info(tmp_path / "s.parquet")["clock"]["fallback"] == info["clock"]["fallback"]


def test_a_low_confidence_trial_can_be_left_out_of_the_dataset_and_named_in_qc(tmp_path):
    from tactilepipe.tool.data.dataset import build_tool_dataset
    ingest = copy.deepcopy(INGEST)
    ingest["clock"]["on_low_score"] = "drop"
    bad = ingest_trial(make_raw(_unrelated), tmp_path / "bad.parquet", SIZE, ingest)
    assert bad["clock"]["dropped"].startswith("clock not aligned")
    good = ingest_trial(make_raw(seed=1), tmp_path / "good.parquet", SIZE, ingest)
    assert "dropped" not in good["clock"]
    sync = {"max_gap_s": 0.2, "pair_rate_hz": 0, "reference": "first", "contact_n": 0.5, "normal_sign": 1}   # this rig reads +Fz
    out = build_tool_dataset([tmp_path / "bad.parquet", tmp_path / "good.parquet"], good["kind"], tmp_path / "d", sync)
    assert [t["trial"] for t in out["trials"]] == [good["trial"]]
    qc = json.loads((tmp_path / "d" / "qc.json").read_text())
    assert [d["reason"] for d in qc["dropped_trials"]] == [bad["clock"]["dropped"]]


def test_the_shard_keeps_the_score_curve_for_the_qc_figure(tmp_path):
    info = ingest_trial(make_raw(), tmp_path / "s.parquet", SIZE, INGEST)
    curve = read_shard_info(tmp_path / "s.parquet")["clock"]["curve"]
    lags = curve["lag0_s"] + curve["step_s"] * np.arange(len(curve["score"]))
    assert lags[0] == pytest.approx(-INGEST["max_offset_s"]) and lags[-1] == pytest.approx(INGEST["max_offset_s"])
    best = lags[int(np.argmax(curve["score"]))]
    assert best == pytest.approx(info["clock"]["refined_shift_s"], abs=2 * curve["step_s"])   # kept to 3 decimals


def test_the_session_clock_figure_is_drawn_from_the_shards(tmp_path):
    from tactilepipe.tool.data.clock_report import clock_figure
    shards = []
    for k in range(2):
        shards.append(tmp_path / f"s{k}.parquet")
        ingest_trial(make_raw(seed=k), shards[-1], SIZE, INGEST)
    assert clock_figure(shards, tmp_path / "fig" / "clock_sync.png") == 2
    assert (tmp_path / "fig" / "clock_sync.png").stat().st_size > 1000


def test_the_clock_figure_has_a_cli_stage(tmp_path):
    from tactilepipe.cli.main import main
    ingest_trial(make_raw(), tmp_path / "s0.parquet", SIZE, INGEST)
    assert main(["tool-clock-figure", "--shards", str(tmp_path / "s0.parquet"), "--out", str(tmp_path / "c.png")]) == 0
    assert (tmp_path / "c.png").exists()
