"""The GAM channel-gate option and the public checkpoint's key mapping (tool/model/public_weights.py).

The public network's key names and shapes are written out here from its description (two
3-conv encoders, three GAM blocks, a torchvision-named ResNet-101 whose stem takes 512 channels,
a 3-layer head), independently of the mapping under test, and a functional forward pass reads
that state dict by its public names."""

from __future__ import annotations

import hashlib

import pytest
import torch
import torch.nn.functional as F

from support.public_formats import to_public
from tactilepipe.core.errors import InputError
from tactilepipe.tool.model import public_weights as pw
from tactilepipe.tool.model.network import build_model, PAPER_WIDTH
from tactilepipe.tool.model.inference import load_model

# Computed with the model code before the gate option existed (seed 2026, 16 px; the zero-initialised
# output layer set to a ramp so the output depends on every layer).
BEFORE = {("full", 18): ("2c65912f952e0d18cfc0699f95612a9c98e744cb92f8aa127963f2d44104f822",
                         [-0.0180854, -0.0100817, -0.0153192]),
          ("no_gam", 18): ("d0b1547354b65e6e100180a9551687dc89eabca35c1137a8aa2a7f82c4d9d7e4",
                           [-0.106013, -0.116724, -0.0837791])}


def _fingerprint(model) -> tuple[str, list[float]]:
    h = hashlib.sha256()
    for k, v in model.state_dict().items():
        h.update(k.encode())
        h.update(v.detach().contiguous().numpy().tobytes())
    x = torch.rand(3, 4, 16, 16, generator=torch.Generator().manual_seed(7))
    model.eval()
    with torch.no_grad():
        w = model.head[-1].weight
        w.copy_(torch.linspace(-1, 1, w.numel()).reshape(w.shape))
        return h.hexdigest(), model(x).tolist()


@pytest.mark.parametrize("variant,depth", sorted(BEFORE))
def test_default_gate_builds_and_computes_as_before(variant, depth):
    torch.manual_seed(2026)
    digest, out = _fingerprint(build_model(variant, depth, 16, "sigmoid", PAPER_WIDTH))
    assert digest == BEFORE[variant, depth][0]
    assert out == pytest.approx(BEFORE[variant, depth][1], rel=1e-5, abs=1e-8)


def test_ungated_model_has_the_same_parameters_and_other_outputs():
    torch.manual_seed(2026)
    digest, out = _fingerprint(build_model("full", 18, 16, gam_channel_gate="none", width=PAPER_WIDTH))
    assert digest == BEFORE["full", 18][0]            # same parameters, same initial draws
    assert out != pytest.approx(BEFORE["full", 18][1], rel=1e-3)
    with pytest.raises(ValueError, match="gam_channel_gate"):
        build_model("full", 18, 16, gam_channel_gate="tanh", width=PAPER_WIDTH)


# --- the public network, by its key names ----------------------------------------------------

def _conv(spec, name, cin, cout, k, bias):
    spec[f"{name}.weight"] = (cout, cin, k, k)
    if bias:
        spec[f"{name}.bias"] = (cout,)


def _bn(spec, name, c):
    spec.update({f"{name}.weight": (c,), f"{name}.bias": (c,), f"{name}.running_mean": (c,),
                 f"{name}.running_var": (c,), f"{name}.num_batches_tracked": ()})


def public_spec(blocks=(3, 4, 23, 3), head="normal") -> dict[str, tuple]:
    spec: dict[str, tuple] = {}
    for enc in ("initial_cnn1", "initial_cnn2"):
        for n, (cin, cout) in enumerate([(2, 64), (64, 128), (128, 256)], start=1):
            _conv(spec, f"{enc}.conv{n}", cin, cout, 3, True)
            _bn(spec, f"{enc}.bn{n}", cout)
    _conv(spec, "resnet.conv1", 512, 64, 7, False)
    _bn(spec, "resnet.bn1", 64)
    inplanes = 64
    for layer, (planes, n) in enumerate(zip((64, 128, 256, 512), blocks), start=1):
        for j in range(n):
            p = f"resnet.layer{layer}.{j}"
            _conv(spec, f"{p}.conv1", inplanes, planes, 1, False)
            _bn(spec, f"{p}.bn1", planes)
            _conv(spec, f"{p}.conv2", planes, planes, 3, False)
            _bn(spec, f"{p}.bn2", planes)
            _conv(spec, f"{p}.conv3", planes, planes * 4, 1, False)
            _bn(spec, f"{p}.bn3", planes * 4)
            if j == 0:
                _conv(spec, f"{p}.downsample.0", inplanes, planes * 4, 1, False)
                _bn(spec, f"{p}.downsample.1", planes * 4)
            inplanes = planes * 4
    for name, c in (("attention1", 256), ("attention2", 256), ("attention3", 512)):
        spec[f"{name}.channel_attention.0.weight"] = (c // 4, c)
        spec[f"{name}.channel_attention.0.bias"] = (c // 4,)
        spec[f"{name}.channel_attention.2.weight"] = (c, c // 4)
        spec[f"{name}.channel_attention.2.bias"] = (c,)
        _conv(spec, f"{name}.spatial_attention.0", c, c // 4, 7, True)
        _bn(spec, f"{name}.spatial_attention.1", c // 4)
        _conv(spec, f"{name}.spatial_attention.3", c // 4, c, 7, True)
        _bn(spec, f"{name}.spatial_attention.4", c)
    for i, (cin, cout) in zip((0, 2, 4) if head == "normal" else (0, 3, 5), [(2048, 1024), (1024, 512), (512, 1)]):
        spec[f"fc.{i}.weight"] = (cout, cin)
        spec[f"fc.{i}.bias"] = (cout,)
    return spec


def random_state(spec, seed=0) -> dict[str, torch.Tensor]:
    g = torch.Generator().manual_seed(seed)
    out = {}
    for k, shape in spec.items():
        if k.endswith("num_batches_tracked"):
            out[k] = torch.tensor(int(torch.randint(0, 1000, (), generator=g)))
        elif k.endswith("running_var"):
            out[k] = 0.5 + torch.rand(shape, generator=g)
        elif f"{k.rsplit('.', 1)[0]}.running_var" in spec:              # a BatchNorm's weight, bias, mean
            out[k] = (0.8 + 0.4 * torch.rand(shape, generator=g)) if k.endswith(".weight") \
                else 0.1 * torch.randn(shape, generator=g)
        else:
            fan_in = max(1, int(torch.tensor(shape[1:]).prod())) if len(shape) > 1 else 16
            out[k] = torch.randn(shape, generator=g) / fan_in ** 0.5
    return out


def reference_forward(sd, x, blocks=(3, 4, 23, 3), head="normal"):
    """The public network in eval mode, straight from its state dict (inputs in [0, 1])."""
    x = x * 2 - 1

    def conv(t, n, stride=1, pad=0):
        return F.conv2d(t, sd[f"{n}.weight"], sd.get(f"{n}.bias"), stride, pad)

    def bn(t, n):
        return F.batch_norm(t, sd[f"{n}.running_mean"], sd[f"{n}.running_var"], sd[f"{n}.weight"], sd[f"{n}.bias"],
                            False, 0.0, 1e-5)

    def encoder(t, p):
        for n in (1, 2, 3):
            t = F.max_pool2d(F.relu(bn(conv(t, f"{p}.conv{n}", pad=1), f"{p}.bn{n}")), 2)
        return t

    def gam(t, p):
        a = t.permute(0, 2, 3, 1)
        a = F.linear(F.relu(F.linear(a, sd[f"{p}.channel_attention.0.weight"], sd[f"{p}.channel_attention.0.bias"])),
                     sd[f"{p}.channel_attention.2.weight"], sd[f"{p}.channel_attention.2.bias"])
        t = t * a.permute(0, 3, 1, 2)                                 # no gate on the channel branch
        s = F.relu(bn(conv(t, f"{p}.spatial_attention.0", pad=3), f"{p}.spatial_attention.1"))
        return t * torch.sigmoid(bn(conv(s, f"{p}.spatial_attention.3", pad=3), f"{p}.spatial_attention.4"))

    z = torch.cat([gam(encoder(x[:, 0:2], "initial_cnn1"), "attention1"),
                   gam(encoder(x[:, 2:4], "initial_cnn2"), "attention2")], 1)
    z = gam(z, "attention3")
    z = F.max_pool2d(F.relu(bn(conv(z, "resnet.conv1", 2, 3), "resnet.bn1")), 3, 2, 1)
    for layer, n in enumerate(blocks, start=1):
        for j in range(n):
            p, stride = f"resnet.layer{layer}.{j}", 2 if layer > 1 and j == 0 else 1
            out = F.relu(bn(conv(z, f"{p}.conv1"), f"{p}.bn1"))
            out = F.relu(bn(conv(out, f"{p}.conv2", stride, 1), f"{p}.bn2"))
            out = bn(conv(out, f"{p}.conv3"), f"{p}.bn3")
            ident = bn(conv(z, f"{p}.downsample.0", stride), f"{p}.downsample.1") if j == 0 else z
            z = F.relu(out + ident)
    z = z.mean((2, 3))
    i0, i1, i2 = (0, 2, 4) if head == "normal" else (0, 3, 5)
    z = F.relu(F.linear(z, sd[f"fc.{i0}.weight"], sd[f"fc.{i0}.bias"]))
    z = F.relu(F.linear(z, sd[f"fc.{i1}.weight"], sd[f"fc.{i1}.bias"]))
    return F.linear(z, sd[f"fc.{i2}.weight"], sd[f"fc.{i2}.bias"]).squeeze(1)


@pytest.mark.slow
def test_public_state_dict_round_trips_losslessly_at_paper_depth_and_computes_the_same(tmp_path):
    public = random_state(public_spec())
    path = tmp_path / "best_model_normal.pth"
    torch.save(public, path)
    model, meta = load_model(path, channels_last=False, image_size=32)
    assert (meta["depth"], meta["gam_channel_gate"], meta["source"], meta["head"]) == (101, "none", "public", "normal")
    assert sum(p.numel() for p in model.parameters()) == 57_297_665          # the full model at depth 101
    # saved back under the public names: every key, shape and value as it came
    back = to_public(model.net.state_dict())
    assert list(back) == list(to_public(pw.from_public(public)[0])) and set(back) == set(public)
    assert all(torch.equal(back[k], public[k]) for k in public)
    # and the outputs are those of the same weights read by their public names
    x = torch.rand(2, 4, 32, 32, generator=torch.Generator().manual_seed(3))
    with torch.no_grad():
        ours = model.double()(x.double())
        ref = reference_forward({k: v.double() if v.is_floating_point() else v for k, v in public.items()}, x.double())
    assert torch.isfinite(ref).all() and ref.abs().max() > 0
    torch.testing.assert_close(ours, ref, rtol=1e-9, atol=1e-12)


def test_shear_head_and_wrapped_or_prefixed_dicts_map_too():
    spec = public_spec(blocks=(3, 4, 6, 3), head="shear")                   # a ResNet-50 trunk, shear head
    public = random_state(spec, seed=1)
    ours, depth, head = pw.from_public({"state_dict": {f"module.{k}": v for k, v in public.items()}})
    assert (depth, head) == (50, "shear")
    assert set(to_public(ours, head)) == set(public)
    x = torch.rand(2, 4, 16, 16, generator=torch.Generator().manual_seed(4))
    net = build_model("full", 50, 16, gam_channel_gate="none", width=PAPER_WIDTH)
    net.load_state_dict(ours)
    with torch.no_grad():
        torch.testing.assert_close(pw.PublicInput(net).eval().double()(x.double()),
                                   reference_forward({k: v.double() if v.is_floating_point() else v
                                                      for k, v in public.items()}, x.double(), (3, 4, 6, 3), "shear"),
                                   rtol=1e-9, atol=1e-12)


def test_missing_unexpected_and_misshaped_keys_are_named(tmp_path):
    public = random_state(public_spec(blocks=(3, 4, 6, 3)))
    del public["attention3.channel_attention.2.bias"]
    public["resnet.layer2.0.conv2.weight"] = torch.zeros(128, 128, 5, 5)
    public["extra.weight"] = torch.zeros(1)
    with pytest.raises(InputError) as err:
        pw.from_public(public, tmp_path / "x.pth")
    msg = str(err.value)
    assert "x.pth" in msg and "missing keys: attention3.channel_attention.2.bias" in msg
    assert "unexpected keys: extra.weight" in msg
    assert "resnet.layer2.0.conv2.weight (128, 128, 5, 5) (expected (128, 128, 3, 3))" in msg
    torch.save({"weights": 1}, tmp_path / "other.pth")
    with pytest.raises(InputError, match="other.pth.*not a tool-model checkpoint"):
        load_model(tmp_path / "other.pth")


def test_predict_streams_a_public_checkpoint_and_asks_for_its_force_range(tmp_path):
    import io

    import numpy as np

    from tactilepipe.core.config import load_params
    from tactilepipe.tool.model.stream import stream_predictions
    from support.public_formats import write_public_trial
    from support.project import REPO
    rng = np.random.default_rng(0)
    frames = [rng.integers(60, 200, (48, 64, 3), dtype=np.uint8) for _ in range(3)]
    trial = write_public_trial(tmp_path, "t0", frames, frames[::-1], [0.5, 3.0, 1.0], "normal")
    (tmp_path / "trials.csv").write_text("trial,tool,orientation_deg,insertion_mm\nt0,knife,5,10\n")
    torch.manual_seed(0)
    ckpt = tmp_path / "best_model_normal.pth"
    torch.save(to_public(build_model("full", 18, 8, gam_channel_gate="none", width=PAPER_WIDTH).state_dict()), ckpt)
    p = load_params(REPO / "params.yaml", {"scale": "smoke"})
    with pytest.raises(InputError, match="best_model_normal.pth.*--label-range"):
        stream_predictions(ckpt, trial, "public", p)
    out = io.StringIO()
    summary = stream_predictions(ckpt, trial, "public", p, out=out, label_range=(0.0, 30.0))
    lines = out.getvalue().splitlines()
    assert summary["pairs"] == 3 and lines[0] == "pair,left_frame,right_frame,t_s,prediction_n,latency_ms" and len(lines) == 5
    assert all(np.isfinite(float(line.split(",")[4])) for line in lines[1:4])
