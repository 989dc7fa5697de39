"""Tool-force model and trainer: shapes and parameter counts at paper scale (no training), what
each variant reads, and short CPU training runs on a tiny synthetic dataset in the loader's format
(learning, determinism, resume after a crash, NaN handling, denormalised predictions)."""

from __future__ import annotations

import csv
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from pydantic import ValidationError
import torch

from tactilepipe.core.config import load_params
from tactilepipe.core.errors import ArgumentError, ConfigError, TactilepipeError
from tactilepipe.tool.data.loader import ToolFrames
from tactilepipe.tool.model.network import (MIN_IMAGE_SIZE, PAPER_WIDTH, TrimmedConv2d, build_model,
                                            count_parameters)
from tactilepipe.tool.model.train import scheduled_lr, train
from tactilepipe.core.tool_vocabulary import RESNET_DEPTHS as DEPTHS
from tactilepipe.tool.model.variants import NAMED_ARCHITECTURES as VARIANTS
from tactilepipe.tool.model.inference import latency_ms, load_model, predict

from support.project import REPO
from support.tool_data import S, TORCH_THREADS, make_dataset, make_split_dict, quick_cfg

# Exact counts of this implementation (independent of the image size); the paper says "about 57 M"
# for the full model on ResNet-101.
EXPECTED_PARAMS = {
    ("full", 18): 24_401_153, ("full", 34): 34_509_313, ("full", 50): 38_305_537, ("full", 101): 57_297_665,
    ("no_ref", 18): 24_400_001, ("no_ref", 34): 34_508_161, ("no_ref", 50): 38_304_385, ("no_ref", 101): 57_296_513,
    ("single", 18): 15_031_361, ("single", 34): 25_139_521, ("single", 50): 28_935_745, ("single", 101): 47_927_873,
    ("no_gam", 18): 14_565_633, ("no_gam", 34): 24_673_793, ("no_gam", 50): 28_470_017, ("no_gam", 101): 47_462_145,
}


@pytest.fixture(autouse=True)
def _test_threads():
    saved = torch.get_num_threads()
    torch.set_num_threads(TORCH_THREADS)
    yield
    torch.set_num_threads(saved)


# ----------------------------------------------------------------------------- architecture

def test_parameter_counts_at_paper_scale():
    counts = {}
    for variant in VARIANTS:
        for depth in DEPTHS:
            with torch.device("meta"):          # no memory, no init cost: counts only
                counts[variant, depth] = count_parameters(build_model(variant, depth, 224, "sigmoid", PAPER_WIDTH))
    print("\nparameters at 224 px (M)\n" + "variant  " + "".join(f"{d:>10}" for d in DEPTHS))
    for variant in VARIANTS:
        print(f"{variant:8} " + "".join(f"{counts[variant, d] / 1e6:10.2f}" for d in DEPTHS))
    assert counts == EXPECTED_PARAMS
    assert 50e6 < counts["full", 101] < 65e6                       # published: about 57 M
    # the fused-channel count sets the stem conv: 512 -> 64 (7x7) vs 256 -> 64 for a single finger
    assert counts["full", 18] - counts["single", 18] > 256 * 64 * 49
    # the no-reference model differs only in the first conv of each encoder (1 input channel less)
    assert counts["full", 101] - counts["no_ref", 101] == 2 * 64 * 9


@pytest.mark.parametrize("variant", list(VARIANTS))
def test_forward_shape_at_224_depth18(variant):
    torch.manual_seed(0)
    model = build_model(variant, 18, 224, "sigmoid", PAPER_WIDTH).eval()
    with torch.no_grad():
        out = model(torch.rand(1, 4, 224, 224))
    assert out.shape == (1,) and torch.isfinite(out).all()


def test_small_inputs_and_size_checks():
    for size in (MIN_IMAGE_SIZE, 32, 64):
        model = build_model("full", 18, size, "sigmoid", PAPER_WIDTH)
        out = model(torch.rand(2, 4, size, size))            # training mode works with 2 samples
        assert out.shape == (2,)
    with pytest.raises(ArgumentError, match="at least 8"):
        build_model("full", 18, MIN_IMAGE_SIZE - 1, "sigmoid", PAPER_WIDTH)
    with pytest.raises(ArgumentError, match=r"image_size 32\.0 must be a whole number"):
        build_model("full", 18, 32.0, "sigmoid", PAPER_WIDTH)
    model = build_model("full", 18, 32, "sigmoid", PAPER_WIDTH).eval()
    with pytest.raises(ValueError, match="32 px"):
        model(torch.rand(1, 4, 64, 64))
    with pytest.raises(ValueError, match="4, S, S"):
        model(torch.rand(1, 2, 32, 32))
    with pytest.raises(ArgumentError, match="unknown model variant 'tiny'"):
        build_model("tiny", 18, 32, "sigmoid", PAPER_WIDTH)
    with pytest.raises(ValueError, match="depth"):
        build_model("full", 152, 32, "sigmoid", PAPER_WIDTH)


def test_width_scales_every_layer_and_is_checked():
    with torch.device("meta"):
        paper = count_parameters(build_model("full", 18, 16, "sigmoid", PAPER_WIDTH))
        smoke = count_parameters(build_model("full", 18, 16, "sigmoid", 8))
    assert paper / smoke > 50                   # conv and linear weights scale with width squared
    model = build_model("no_gam", 34, 16, "sigmoid", 8)
    assert model.regressor.stem[0].out_channels == 8 and model.regressor.out_features == 64
    assert model(torch.rand(2, 4, 16, 16)).shape == (2,)
    for bad in (0, 8.0, True):
        with pytest.raises(ArgumentError, match="model width"):
            build_model("full", 18, 16, "sigmoid", bad)


def test_channels_last_gives_the_same_output():
    torch.manual_seed(0)
    model = build_model("full", 18, 32, "sigmoid", PAPER_WIDTH).eval()
    x = torch.rand(2, 4, 32, 32)
    with torch.no_grad():
        a = model(x)
        model = model.to(memory_format=torch.channels_last)
        b = model(x.contiguous(memory_format=torch.channels_last))
    assert torch.allclose(a, b, atol=1e-4, rtol=1e-4)


@pytest.mark.parametrize("kernel,stride", [(1, 1), (3, 1), (3, 2), (5, 1), (7, 1), (7, 2)])
def test_trimmed_conv_equals_the_full_convolution(kernel, stride):
    # every map size from 1 px (only the centre tap meets data) to larger than the kernel (nothing
    # to trim); output, input gradient and weight gradient must be those of the untrimmed conv
    torch.manual_seed(kernel * 10 + stride)
    conv = TrimmedConv2d(5, 6, kernel, stride, kernel // 2)
    for fmt in (torch.contiguous_format, torch.channels_last):
        conv = conv.to(memory_format=fmt)
        for size in range(1, 10):
            x = torch.randn(3, 5, size, size).contiguous(memory_format=fmt).requires_grad_()
            y = conv(x)
            ref = torch.nn.functional.conv2d(x, conv.weight, conv.bias, stride, kernel // 2)
            assert y.shape == ref.shape
            torch.testing.assert_close(y, ref, atol=1e-5, rtol=1e-5)
            g = torch.randn_like(ref)
            got = torch.autograd.grad(y, (x, conv.weight, conv.bias), g)
            want = torch.autograd.grad(ref, (x, conv.weight, conv.bias), g)
            for a, b in zip(got, want):
                torch.testing.assert_close(a, b, atol=1e-5, rtol=1e-5)
            assert got[1].stride() == conv.weight.stride()     # the gradient keeps the weight's layout
    # where nothing is trimmed the weight's outer taps do meet data: their gradient is not zero
    x = torch.randn(2, 5, 9, 9)
    grad_w, = torch.autograd.grad(conv(x).sum(), conv.weight)
    assert grad_w[:, :, 0, 0].abs().sum() > 0
    x1 = torch.randn(2, 5, 1, 1)
    grad_w, = torch.autograd.grad(conv(x1).sum(), conv.weight)
    c = kernel // 2
    assert grad_w[:, :, c, c].abs().sum() > 0
    grad_w[:, :, c, c] = 0                                      # on a 1x1 map only the centre tap meets data
    assert grad_w.abs().max() == 0


def test_variants_read_only_their_channels():
    torch.manual_seed(0)
    x = torch.rand(2, 4, 32, 32)
    changed_ref, changed_right = x.clone(), x.clone()
    changed_ref[:, [1, 3]] = torch.rand(2, 2, 32, 32)
    changed_right[:, [2, 3]] = torch.rand(2, 2, 32, 32)
    out = {}
    with torch.no_grad():
        for variant in VARIANTS:
            torch.manual_seed(1)
            m = build_model(variant, 18, 32, "sigmoid", PAPER_WIDTH).eval()
            torch.nn.init.normal_(m.head[-1].weight)     # the untrained output layer is zero (a constant)
            out[variant] = [m(t) for t in (x, changed_ref, changed_right)]

    def same(a, b):
        return torch.equal(a, b)

    assert same(out["no_ref"][0], out["no_ref"][1])            # references are never read
    assert not same(out["no_ref"][0], out["no_ref"][2])        # the right finger is
    assert same(out["single"][0], out["single"][2])            # the right finger is never read
    assert not same(out["single"][0], out["single"][1])        # the left reference is
    for variant in ("full", "no_gam"):
        assert not same(out[variant][0], out[variant][1])
        assert not same(out[variant][0], out[variant][2])


def test_no_gam_has_no_gam_parameters():
    full, no_gam = build_model("full", 18, 32, "sigmoid", PAPER_WIDTH), build_model("no_gam", 18, 32, "sigmoid", PAPER_WIDTH)
    assert sum("gam" in n for n, _ in full.named_parameters()) > 0
    assert sum("gam" in n for n, _ in no_gam.named_parameters()) == 0


# ----------------------------------------------------------------------------- synthetic data
# make_dataset, make_split_dict, quick_cfg: tests/support/tool_data.py

@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    root = make_dataset(tmp_path_factory.mktemp("tool_model") / "dataset")
    data = ToolFrames(root, "normal")
    return data, make_split_dict(data)


def test_frames_are_downscaled_for_the_model_never_upsampled(tiny):
    data, _ = tiny
    assert data.resized(S // 2).frames.shape[-1] == S // 2 and data.resized(S) is data
    with pytest.raises(ConfigError, match=f"a {2 * S}-px model input from a data set of {S}-px frames"):
        data.resized(2 * S)


def weights(path: Path) -> dict:
    return torch.load(path, map_location="cpu", weights_only=True)["model"]


def assert_same_weights(a: dict, b: dict) -> None:
    assert a.keys() == b.keys()
    for k in a:
        assert torch.equal(a[k], b[k]), k


class CrashingData:
    """Wraps a dataset; the training iterator of epoch ``crash_epoch`` dies after one batch.
    Each epoch makes two shuffled passes: training, then the BatchNorm re-estimation."""

    def __init__(self, data, crash_epoch: int):
        self.data, self.crash_epoch, self.train_epochs = data, crash_epoch, 0

    def __len__(self):
        return len(self.data)

    def __getattr__(self, name):          # labels, frames, ...: the wrapped dataset's
        return getattr(self.data, name)

    def batches(self, idx, batch_size, shuffle, seed=0):
        if shuffle:
            self.train_epochs += 1
        it = self.data.batches(idx, batch_size, shuffle, seed)
        if shuffle and self.train_epochs == 2 * self.crash_epoch - 1:
            yield next(it)
            raise KeyboardInterrupt("simulated crash")
        yield from it


# ----------------------------------------------------------------------------- training

@pytest.mark.slow
def test_training_lowers_validation_loss(tiny, tmp_path):
    data, split = tiny
    cfg = quick_cfg(max_epochs=6, lr=1e-3, batch_size=16, width=PAPER_WIDTH)     # the paper's model
    summary = train(data, split, cfg, tmp_path, progress=False)
    with open(tmp_path / "history.csv") as f:
        hist = list(csv.DictReader(f))
    assert [int(h["epoch"]) for h in hist] == list(range(1, 7))
    assert list(hist[0]) == ["epoch", "train_loss", "val_loss", "val_mae_n", "lr", "epoch_s", "wall_s"]
    val = np.array([float(h["val_loss"]) for h in hist])
    train_loss = np.array([float(h["train_loss"]) for h in hist])
    wall = np.array([float(h["wall_s"]) for h in hist])
    assert np.all(np.diff(wall) > 0)

    # the same initial model, before any training step
    st = split["label_stats"]
    torch.manual_seed(cfg.seed)
    untrained = build_model("full", 18, S, "sigmoid", PAPER_WIDTH).eval()
    x_val, y_val = data.arrays(split["validation"])
    with torch.no_grad():
        z = untrained(torch.from_numpy(x_val).float() / 255).numpy()
    t_val = (y_val - st["min"]) / (st["max"] - st["min"])
    untrained_loss = np.abs(z - t_val).mean()
    mean_loss = np.abs(t_val - (data.labels[split["train"]].mean() - st["min"]) / (st["max"] - st["min"])).mean()
    print(f"\nval loss: untrained {untrained_loss:.3f}, predicting the training mean {mean_loss:.3f}, "
          f"per epoch {np.round(val, 3).tolist()}; train loss {np.round(train_loss, 3).tolist()}")
    assert summary["epochs_run"] == 6 and summary["device"] == "cpu" and not summary["early_stopped"]
    assert summary["parameters"] == EXPECTED_PARAMS["full", 18]
    assert summary["best_val_loss"] == pytest.approx(val.min())
    assert summary["best_epoch"] == int(np.argmin(val)) + 1
    assert summary["train_wall_s"] == pytest.approx(wall[-1])
    # Six epochs of 8 steps take the full model (faithful GAM, BatchNorm on 1x1 maps at 32 px) from
    # its initial outputs to about the label scale, not yet below the training-mean predictor: its
    # validation loss is noisy from epoch to epoch, so only robust margins are asserted here (the
    # training loss of the last three epochs was 0.47-0.50 of the first's with the per-tensor and the
    # fused Adam kernels alike: rounding differences alone move it by a few per cent).
    assert val.min() < 0.8 * untrained_loss
    assert train_loss[-3:].mean() < 0.6 * train_loss[0]
    assert (tmp_path / "best.pt").exists() and (tmp_path / "last.pt").exists()

    # predict: denormalised N-scale forces, equal to model output mapped back by the label stats
    model, meta = load_model(tmp_path / "best.pt")
    assert meta["epoch"] == summary["best_epoch"] and meta["normalise"] == "minmax"
    idx = np.asarray(split["validation"])[::-1]            # any order, returned in that order
    pred = predict(model, data, idx, meta["label_stats"], meta["normalise"], batch_size=7)
    assert pred.shape == (len(idx),)
    with torch.no_grad():
        x, _ = data.arrays(idx)
        raw = model(torch.from_numpy(x).float().div(255).contiguous(memory_format=torch.channels_last)).numpy()
    np.testing.assert_allclose(pred, raw * (st["max"] - st["min"]) + st["min"], rtol=1e-4, atol=1e-3)
    assert np.abs(pred - data.labels[idx]).mean() == pytest.approx(summary["best_val_mae_n"], rel=1e-3)
    assert 1.5 < pred.mean() < 30.0                          # N, not the [0, 1] training scale

    ms = latency_ms(model, S, n=5)
    assert isinstance(ms, float) and ms > 0.0


class FlagRecordingData(CrashingData):
    """Wraps a dataset and records PyTorch's deterministic-algorithms flags at every batch."""

    def __init__(self, data):
        super().__init__(data, crash_epoch=0)
        self.flags = set()

    def batches(self, idx, batch_size, shuffle, seed=0):
        for batch in self.data.batches(idx, batch_size, shuffle, seed):
            self.flags.add((torch.are_deterministic_algorithms_enabled(),
                            torch.is_deterministic_algorithms_warn_only_enabled()))
            yield batch


def test_training_runs_deterministic_kernels_and_restores_the_callers_setting(tiny, tmp_path):
    data, split = tiny
    saved = (torch.are_deterministic_algorithms_enabled(), torch.is_deterministic_algorithms_warn_only_enabled())
    recording = FlagRecordingData(data)
    try:
        torch.use_deterministic_algorithms(False)
        train(recording, split, quick_cfg(max_epochs=1, max_train_batches_per_epoch=1, batch_size=16, device="cpu"),
              tmp_path, progress=False)
        assert recording.flags == {(True, False)}                 # on CPU: an error, not a warning
        assert not torch.are_deterministic_algorithms_enabled()
    finally:
        torch.use_deterministic_algorithms(saved[0], warn_only=saved[1])
    # without importing torch.compile's back end (seconds per training job)
    code = ("import sys, torch; from tactilepipe.tool.model.train import _use_deterministic_algorithms; "
            "_use_deterministic_algorithms(True, warn_only=False); "
            "assert torch.are_deterministic_algorithms_enabled(); assert 'torch._inductor' not in sys.modules")
    subprocess.run([sys.executable, "-c", code], check=True)


def test_same_seed_same_weights_and_resume_equals_uninterrupted(tiny, tmp_path):
    data, split = tiny
    cfg = quick_cfg(max_epochs=2, max_train_batches_per_epoch=2, batch_size=16)
    a = train(data, split, cfg, tmp_path / "a", progress=False)
    b = train(data, split, cfg, tmp_path / "b", progress=False)
    assert_same_weights(weights(tmp_path / "a" / "last.pt"), weights(tmp_path / "b" / "last.pt"))
    assert a["best_val_loss"] == b["best_val_loss"]

    other = train(data, split, quick_cfg(max_epochs=1, max_train_batches_per_epoch=2, batch_size=16, seed=8),
                  tmp_path / "other", progress=False)
    assert other["epochs_run"] == 1
    first_a = torch.load(tmp_path / "a" / "last.pt", weights_only=True)["history"][0]
    assert first_a["val_loss"] != other["best_val_loss"]            # another seed, another run

    crashing = CrashingData(data, crash_epoch=2)
    with pytest.raises(KeyboardInterrupt):
        train(crashing, split, cfg, tmp_path / "c", progress=False)
    assert torch.load(tmp_path / "c" / "last.pt", weights_only=True)["epoch"] == 1
    assert len((tmp_path / "c" / "history.csv").read_text().splitlines()) == 2     # header + epoch 1
    c = train(data, split, cfg, tmp_path / "c", progress=False)
    assert c["resumed_from_epoch"] == 1 and c["epochs_run"] == 2
    assert_same_weights(weights(tmp_path / "a" / "last.pt"), weights(tmp_path / "c" / "last.pt"))
    assert_same_weights(weights(tmp_path / "a" / "best.pt"), weights(tmp_path / "c" / "best.pt"))
    hist_a = (tmp_path / "a" / "history.csv").read_text().splitlines()
    hist_c = (tmp_path / "c" / "history.csv").read_text().splitlines()
    assert [r.split(",")[:5] for r in hist_a] == [r.split(",")[:5] for r in hist_c]   # timings aside

    # a finished run re-run is a no-op; a run with other settings refuses the checkpoint
    again = train(data, split, cfg, tmp_path / "a", progress=False)
    assert again["epochs_run"] == 2 and again["resumed_from_epoch"] == 2
    with pytest.raises(TactilepipeError, match="different settings"):
        train(data, split, quick_cfg(max_epochs=2, max_train_batches_per_epoch=2, batch_size=16, lr=1e-3),
              tmp_path / "a", progress=False)


def test_cosine_schedule_decays_to_zero_and_fixes_max_epochs(tiny, tmp_path):
    cfg = quick_cfg(lr=2e-4, lr_schedule="cosine")
    assert scheduled_lr(cfg, 0, 100) == pytest.approx(2e-4)
    assert scheduled_lr(cfg, 50, 100) == pytest.approx(1e-4)
    assert scheduled_lr(cfg, 100, 100) == pytest.approx(0.0, abs=1e-12)
    lrs = [scheduled_lr(cfg, i, 100) for i in range(101)]
    assert all(a > b for a, b in zip(lrs, lrs[1:]))
    assert scheduled_lr(quick_cfg(lr=3e-4), 77, 100) == 3e-4       # constant: the paper's
    data, split = tiny
    run = dict(max_epochs=3, max_train_batches_per_epoch=2, batch_size=16, lr_schedule="cosine")
    train(data, split, quick_cfg(**run), tmp_path / "c", progress=False)
    lr = pd.read_csv(tmp_path / "c" / "history.csv")["lr"].to_numpy()
    # logged: the rate of each epoch's last step (step 2, 4, 6 of 6)
    np.testing.assert_allclose(lr, [2e-4 * 0.5 * (1 + np.cos(np.pi * k / 6)) for k in (1, 3, 5)], rtol=1e-9)
    # with a cosine schedule max_epochs sets the decay: a longer run cannot resume this one
    with pytest.raises(TactilepipeError, match="max_epochs"):
        train(data, split, quick_cfg(**{**run, "max_epochs": 4}), tmp_path / "c", progress=False)
    with pytest.raises(ValidationError, match="lr_schedule"):     # the typed settings refuse it first
        quick_cfg(lr_schedule="step")


def test_early_stopping(tiny, tmp_path):
    data, split = tiny
    # a far too large learning rate: the validation loss soon stops improving
    s = train(data, split, quick_cfg(max_epochs=12, patience=2, lr=0.05, max_train_batches_per_epoch=1,
                                           batch_size=16, variant="no_gam"),
              tmp_path, progress=False)
    hist = pd.read_csv(tmp_path / "history.csv")
    assert s["early_stopped"] and s["epochs_run"] == s["best_epoch"] + 2 < 12
    assert len(hist) == s["epochs_run"] and hist["val_loss"].idxmin() + 1 == s["best_epoch"]


def test_nan_label_names_epoch_and_batch(tmp_path):
    root = make_dataset(tmp_path / "nan", nan_at=5)
    data = ToolFrames(root, "normal")
    split = make_split_dict(data)
    with pytest.raises(TactilepipeError, match=r"epoch 1, batch \d+.*sample indices \[5\]"):
        train(data, split, quick_cfg(max_epochs=1), tmp_path / "run", progress=False)


def test_nan_loss_from_inputs_names_epoch_and_batch(tiny, tmp_path):
    data, split = tiny

    class NanInputs:
        def __len__(self):
            return len(data)

        def batches(self, idx, batch_size, shuffle, seed=0):
            for b, (x, y, part) in enumerate(data.batches(idx, batch_size, shuffle, seed)):
                if shuffle and b == 1:
                    x = x.clone()
                    x[0, 0, 0, 0] = float("nan")
                yield x, y, part

    with pytest.raises(TactilepipeError, match=r"epoch 1, batch 2: labels are finite"):
        train(NanInputs(), split, quick_cfg(max_epochs=1), tmp_path, progress=False)


def test_zscore_normalisation_and_bad_settings(tiny, tmp_path):
    data, split = tiny
    s = train(data, split, quick_cfg(max_epochs=1, normalise="zscore", max_train_batches_per_epoch=2),
              tmp_path / "z", progress=False)
    model, meta = load_model(tmp_path / "z" / "best.pt")
    assert meta["normalise"] == "zscore"
    pred = predict(model, data, split["validation"], meta["label_stats"], "zscore")
    assert np.abs(pred - data.labels[split["validation"]]).mean() == pytest.approx(s["best_val_mae_n"], rel=1e-3)
    with pytest.raises(TactilepipeError, match="normalisation"):
        train(data, split, quick_cfg(normalise="log"), tmp_path / "bad", progress=False)
    with pytest.raises(TactilepipeError, match="image_size"):
        train(data, split, quick_cfg(image_size=64), tmp_path / "bad", progress=False)


def test_over_time_figure_shows_the_strongest_trial_of_each_tool(tmp_path):
    from tactilepipe.tool.report.figures_models import over_time, strongest_trial_per_tool
    rows = []
    for tool, trial, peak in [("spatula", "s/a", 5.0), ("spatula", "s/b", 9.0), ("knife", "k/a", 3.0),
                              ("knife", "k/b", 2.0)]:
        t = np.linspace(0, 3, 30)
        true = peak * np.sin(np.pi * t / 3)
        rows.append(pd.DataFrame({"tool": tool, "trial": trial, "t_s": t + 100, "true": true, "pred": true + 0.1}))
    pred = pd.concat(rows, ignore_index=True)
    assert strongest_trial_per_tool(pred) == ["k/a", "s/b"]
    from tactilepipe.tool.model.variants import defined_variants
    looks = defined_variants(load_params(REPO / "params.yaml")["tool_variants"])
    over_time({"full": pred, "single": pred}, "normal", tmp_path / "fig.png", looks=looks, split="trial")
    assert (tmp_path / "fig.png").stat().st_size > 10_000


def test_every_figure_drawn_from_one_split_names_that_split_in_its_title_and_caption(tmp_path, monkeypatch):
    """Figs. 5-10 show one split's test set, a single draw of the scores over the repeated splits:
    each title names the split it was drawn from, and so does each figure's report caption."""
    from tactilepipe.tool.report import figures_models as fm
    from tactilepipe.tool.model.evaluate import evaluate
    from tactilepipe.tool.model.variants import defined_variants
    titles = {}
    monkeypatch.setattr(fm, "save_figure", lambda out, fig: titles.__setitem__(out.stem, " ".join(
        [t.get_text() for t in fig.texts] + [ax.get_title() for ax in fig.axes])))
    looks = defined_variants(load_params(REPO / "params.yaml")["tool_variants"])
    t = np.linspace(0, 3, 40)
    pred = pd.concat([pd.DataFrame({"tool": tool, "trial": f"{tool}/0", "t_s": t, "true": 6 * np.sin(np.pi * t / 3),
                                    "pred": 6 * np.sin(np.pi * t / 3) + 0.2}) for tool in ("knife", "spatula")],
                     ignore_index=True)
    e = evaluate(pred)
    preds, evals = {"full": pred, "single": pred}, {"full": e, "single": e}
    fm.sorted_predictions(pred, "normal", tmp_path / "sorted_predictions.png", split="trial_r3")
    fm.over_time(preds, "normal", tmp_path / "over_time.png", looks=looks, split="trial_r3")
    fm.per_tool_bars({v: pd.DataFrame(x["per_tool"]) for v, x in evals.items()}, tmp_path / "per_tool.png",
                     looks=looks, split="trial_r3")
    fm.window_heatmap({v: pd.DataFrame(x["per_window"]) for v, x in evals.items()}, tmp_path / "window_heatmap.png",
                      looks=looks, split="trial_r3")
    fm.regression_grid(preds, evals, "normal", tmp_path / "regression.png", looks=looks, split="trial_r3")
    one_split = ["sorted_predictions", "over_time", "per_tool", "window_heatmap", "regression"]
    assert sorted(titles) == sorted(one_split)
    for name, title in titles.items():
        assert "split 'trial_r3'" in title, (name, title)
    for name in one_split + ["per_tool_table", "per_window"]:
        caption = (REPO / "workflow/report/tool" / f"{name}.rst").read_text()
        assert "snakemake.config['tool_train']['split']" in caption and "first" in caption, name


def test_a_verdict_needs_both_improvements_separated_from_zero_over_the_draws():
    from tactilepipe.tool.report.verdicts import versus
    base = {"mae": [1.5, 1.6, 1.7], "r2": [0.80, 0.85, 0.83]}
    good = {"mae": [1.0, 1.2, 1.1], "r2": [0.90, 0.92, 0.91]}
    v = versus(good, base, test_train_ratio=0.0)
    # MAE improvements 0.5, 0.4, 0.6: mean 0.5, std 0.1, t(0.975, 2) = 4.302653, half = 4.302653 * 0.1 / sqrt(3)
    assert v["mae_improvement"]["mean"] == pytest.approx(0.5)
    assert v["mae_improvement"]["low"] == pytest.approx(0.5 - 0.248414, abs=1e-5)
    # R² improvements 0.10, 0.07, 0.08: mean 0.08333, std 0.015275, half 0.037946
    assert v["r2_improvement"]["low"] == pytest.approx(0.083333 - 0.037946, abs=1e-5)
    assert v["beats"] is True
    # Nadeau-Bengio widening with n_test/n_train = 0.25: half = 4.302653 * 0.1 * sqrt(1/3 + 0.25)
    assert versus(good, base, 0.25)["mae_improvement"]["high"] == pytest.approx(0.5 + 0.328621, abs=1e-5)
    # a better mean the draws cannot separate from zero is no verdict
    noisy = {"mae": [1.0, 1.9, 1.3], "r2": good["r2"]}
    assert versus(noisy, base, 0.0)["mae_improvement"]["mean"] > 0 and versus(noisy, base, 0.0)["beats"] is False
    # separated on MAE but worse on R²: not "beats"
    assert versus({"mae": good["mae"], "r2": [0.70, 0.75, 0.74]}, base, 0.0)["beats"] is False
    # one draw says nothing about the spread
    assert versus({"mae": [1.0], "r2": [0.9]}, {"mae": [2.0], "r2": [0.5]}, 0.0)["beats"] is False


def test_the_studys_orderings_are_judged_holds_reversed_or_undecided():
    from tactilepipe.tool.report.verdicts import paper_orderings
    scores = {"full": {"mae": [0.5, 0.6, 0.7]}, "no_gam": {"mae": [0.6, 1.6, 0.8]},
              "no_ref": {"mae": [1.5, 1.6, 1.7]}, "single": {"mae": [1.0, 1.1, 1.2]}}
    got = {(r["better"], r["worse"]): r for r in paper_orderings("tool_normal", scores, 0.0)}
    assert set(got) == {("full", "no_gam"), ("full", "no_ref"), ("full", "single"), ("no_gam", "no_ref"),
                        ("no_ref", "single")}
    assert got[("full", "no_ref")]["verdict"] == "holds"          # differences 1.0, 1.0, 1.0
    assert got[("full", "no_ref")]["mae_difference"] == pytest.approx(1.0)
    assert got[("no_ref", "single")]["verdict"] == "reversed"     # single is better by 0.5 on every draw
    assert got[("full", "no_gam")]["verdict"] == "undecided"      # 0.1, 1.0, 0.1: interval spans zero
    assert [r["claim"] for r in paper_orderings("tool_shear", scores, 0.0)] == \
        ["full < no_gam (MAE)", "full < no_ref (MAE)", "full < single (MAE)"]


def test_the_like_for_like_baselines_see_what_their_variant_sees():
    from tactilepipe.tool.model.evaluate import baselines, rest_frame_rmse_features, tactile_rmse_features
    from tactilepipe.tool.model.variants import defined_variants
    rng = np.random.default_rng(0)
    references = rng.integers(0, 255, (4, 2, 3, 3)).astype(np.uint8)         # 4 trials, 2 fingers
    trial_index = np.repeat(np.arange(4), 5)
    frames = rng.integers(0, 255, (20, 2, 3, 3)).astype(np.uint8)
    split = {"train": list(range(10)), "test": list(range(10, 20))}          # trials 0-1 train, 2-3 test
    rest = rest_frame_rmse_features(frames, references, trial_index, split["train"])
    mean_rest = references[:2].astype(float).mean(axis=0)
    assert rest[13, 1] == pytest.approx(np.sqrt(((frames[13, 1] - mean_rest[1]) ** 2).mean()), rel=1e-5)
    # the rest-frame baseline never sees a test trial's own reference
    other = references.copy()
    other[2:] = 0
    assert np.array_equal(rest, rest_frame_rmse_features(frames, other, trial_index, split["train"]))
    labels = rng.normal(size=20).astype(np.float32)
    rmse = tactile_rmse_features(frames, references, trial_index)
    pred = baselines(labels, rmse, rest, split)
    assert set(pred) == {"mean_predictor", "tactile_rmse_linear", "rest_frame_rmse_linear", "one_finger_rmse_linear"}
    assert {v.baseline for v in defined_variants(load_params(REPO / "params.yaml")["tool_variants"]).values()} <= set(pred)
    assert pred["mean_predictor"] == pytest.approx(np.full(10, labels[:10].mean()))
    # the one-finger baseline is a fit on the left finger only: the right finger's frames do not move it
    right_changed = rmse.copy()
    right_changed[:, 1] = rng.normal(size=20)
    assert baselines(labels, right_changed, rest, split)["one_finger_rmse_linear"] == \
        pytest.approx(pred["one_finger_rmse_linear"])
    assert not np.allclose(baselines(labels, right_changed, rest, split)["tactile_rmse_linear"],
                           pred["tactile_rmse_linear"])

def test_the_optimizer_is_torchs_fused_adam_without_importing_dynamo():
    """make_optimizer's Adam steps exactly as torch.optim.Adam(fused=True), state included, and
    neither building nor stepping it imports torch._dynamo (seconds of CPU per training process)."""
    code = """
import sys, torch
from tactilepipe.tool.model.train import make_optimizer
torch.manual_seed(0)
m = torch.nn.Linear(16, 3)
opt = make_optimizer(m, 1e-3)
for i in range(5):
    opt.zero_grad(set_to_none=True); m(torch.randn(8, 16)).pow(2).sum().backward(); opt.step()
    opt.param_groups[0]["lr"] *= 0.5
opt.load_state_dict(opt.state_dict())
print("torch._dynamo" in sys.modules)
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split()
    assert out == ["False"]

    from tactilepipe.tool.model.train import make_optimizer
    weights, states = [], []
    for build in (lambda m: make_optimizer(m, 1e-3), lambda m: torch.optim.Adam(m.parameters(), lr=1e-3, fused=True)):
        torch.manual_seed(0)
        m = torch.nn.Linear(16, 3)
        opt = build(m)
        for i in range(5):
            opt.zero_grad(set_to_none=True)
            m(torch.randn(8, 16)).pow(2).sum().backward()
            opt.step()
            opt.param_groups[0]["lr"] *= 0.5
        weights.append(m.weight.detach().clone())
        states.append(opt.state_dict())
    assert torch.equal(weights[0], weights[1])
    assert all(torch.equal(a["exp_avg_sq"], b["exp_avg_sq"]) for a, b in zip(states[0]["state"].values(),
                                                                            states[1]["state"].values()))
