"""Checkpoints of the public code of study 000 (its published ``best_model_normal.pth`` and
``best_model_shear.pth``): their state-dict keys mapped onto our ``full`` model and back.

The public network is ours at paper scale (depth 101) with the GAM channel branch ungated
(``gam_channel_gate="none"``). Its parts and our names for them (only names differ; every shape
matches):

    initial_cnn1 / initial_cnn2 .conv{n}, .bn{n}   encoders.0 / .1 .body.{4(n-1)}, .body.{4(n-1)+1}
    attention1 / attention2 / attention3           sensor_gams.0 / .1, fusion_gam
        .channel_attention.{0,2}, .spatial_attention.{0,1,3,4}   .channel.{0,2}, .spatial.{0,1,3,4}
    resnet.conv1, resnet.bn1                       regressor.stem.0, regressor.stem.1
    resnet.layer{L}.{j}.*                          regressor.stages.{L-1}.{j}.* (same block names)
    fc.{0,2,4} (normal) or fc.{0,3,5} (shear:      head.{0,2,4}
      a dropout at index 2, identity in eval)

Its inputs are grayscale frames scaled to [-1, 1] (ours: [0, 1]): ``PublicInput`` puts our
loader's frames on that scale. It predicts min-max-normalised normal force (statistics of the
whole data set) or shear force in N, unnormalised.
"""

from __future__ import annotations

import pickle
import re
from pathlib import Path

import torch
from torch import nn

from tactilepipe.core.errors import ArgumentError, InputError
from tactilepipe.tool.model.network import PAPER_WIDTH, build_model
from tactilepipe.core.tool_vocabulary import RESNET_DEPTHS as DEPTHS
from tactilepipe.tool.model.variants import NAMED_ARCHITECTURES

PUBLIC_MARKER = "initial_cnn1.conv1.weight"
HEADS = {"normal": (0, 2, 4), "shear": (0, 3, 5)}      # public fc indices of our head.0, head.2, head.4
_GAMS = {"attention1": "sensor_gams.0", "attention2": "sensor_gams.1", "attention3": "fusion_gam"}
_GAM_PARTS = {"channel_attention": "channel", "spatial_attention": "spatial"}


def read_state(path: Path):
    """torch.load of a checkpoint (tensors only), with errors naming the file."""
    try:
        return torch.load(path, map_location="cpu", weights_only=True)
    except FileNotFoundError:
        raise InputError(path, "checkpoint not found") from None
    except pickle.UnpicklingError as exc:         # torch's paragraph suggests loading it unrestricted: never
        found = re.search(r"Unsupported global: GLOBAL (\S+)", str(exc))
        if found:
            raise InputError(path, f"refused: not a checkpoint of tensors and plain values (it calls "
                                   f"{found.group(1)}); a pickle like this can run code, so it is not loaded") from None
        detail = " ".join(str(exc).split("WeightsUnpickler error:")[-1].split("Check the documentation")[0].split())
        raise InputError(path, f"cannot read checkpoint (UnpicklingError: {detail})") from None
    except Exception as exc:                      # truncated or foreign file
        raise InputError(path, f"cannot read checkpoint ({type(exc).__name__}: {' '.join(str(exc).split())})") from None


def _unwrap(state) -> dict:
    """The public state dict: saved bare, or under "state_dict"/"model", maybe with DataParallel's
    "module." prefix."""
    if isinstance(state, dict) and PUBLIC_MARKER not in state:
        for key in ("state_dict", "model"):
            if isinstance(state.get(key), dict):
                state = state[key]
                break
    if isinstance(state, dict) and all(isinstance(k, str) and k.startswith("module.") for k in state):
        state = {k[len("module."):]: v for k, v in state.items()}
    return state


def is_public_state(state) -> bool:
    return isinstance(state, dict) and PUBLIC_MARKER in _unwrap(state)


def to_ours_key(key: str, head: str = "normal") -> str | None:
    """Our name for a public key (None: not a key of the public network)."""
    m = re.fullmatch(r"initial_cnn([12])\.(conv|bn)([123])\.(\w+)", key)
    if m:
        enc, kind, n, leaf = int(m.group(1)) - 1, m.group(2), int(m.group(3)), m.group(4)
        return f"encoders.{enc}.body.{4 * (n - 1) + (kind == 'bn')}.{leaf}"
    m = re.fullmatch(r"(attention[123])\.(channel_attention|spatial_attention)\.(\d+)\.(\w+)", key)
    if m:
        return f"{_GAMS[m.group(1)]}.{_GAM_PARTS[m.group(2)]}.{m.group(3)}.{m.group(4)}"
    m = re.fullmatch(r"resnet\.(conv1|bn1)\.(\w+)", key)
    if m:
        return f"regressor.stem.{0 if m.group(1) == 'conv1' else 1}.{m.group(2)}"
    m = re.fullmatch(r"resnet\.layer([1-4])\.(\d+)\.(.+)", key)
    if m:
        return f"regressor.stages.{int(m.group(1)) - 1}.{m.group(2)}.{m.group(3)}"
    m = re.fullmatch(r"fc\.(\d+)\.(\w+)", key)
    if m and int(m.group(1)) in HEADS[head]:
        return f"head.{2 * HEADS[head].index(int(m.group(1)))}.{m.group(2)}"
    return None


def to_public_key(key: str, head: str = "normal") -> str:
    """The public name of one of our ``full`` model's keys."""
    m = re.fullmatch(r"encoders\.([01])\.body\.(\d+)\.(\w+)", key)
    if m:
        idx = int(m.group(2))
        return f"initial_cnn{int(m.group(1)) + 1}.{'bn' if idx % 4 else 'conv'}{idx // 4 + 1}.{m.group(3)}"
    for public, ours in _GAMS.items():
        if key.startswith(ours + "."):
            part, rest = key[len(ours) + 1:].split(".", 1)
            return f"{public}.{next(p for p, o in _GAM_PARTS.items() if o == part)}.{rest}"
    m = re.fullmatch(r"regressor\.stem\.([01])\.(\w+)", key)
    if m:
        return f"resnet.{'conv1' if m.group(1) == '0' else 'bn1'}.{m.group(2)}"
    m = re.fullmatch(r"regressor\.stages\.(\d)\.(.+)", key)
    if m:
        return f"resnet.layer{int(m.group(1)) + 1}.{m.group(2)}"
    m = re.fullmatch(r"head\.([024])\.(\w+)", key)
    if m:
        return f"fc.{HEADS[head][int(m.group(1)) // 2]}.{m.group(2)}"
    raise KeyError(f"{key} is not a key of the full model")


def public_layout(state: dict) -> tuple[int, str]:
    """(ResNet depth, head: normal | shear) of a public state dict, from its keys."""
    blocks = [len({k.split(".")[2] for k in state if k.startswith(f"resnet.layer{i}.")}) for i in range(1, 5)]
    kind = "bottleneck" if "resnet.layer1.0.conv3.weight" in state else "basic"
    depth = next((d for d, spec in DEPTHS.items() if spec == (kind, blocks)), None)
    head = "shear" if "fc.5.weight" in state else "normal"
    if depth is None:
        raise ArgumentError(f"ResNet of {kind} blocks {blocks} per stage is none of depths {sorted(DEPTHS)}")
    return depth, head


def from_public(state, source: str | Path = "checkpoint") -> tuple[dict, int, str]:
    """(our state dict, depth, head) of a public state dict. InputError naming ``source`` and the
    keys when a key is missing or unexpected or a shape differs from our ``full`` model's."""
    state = _unwrap(state)
    try:
        depth, head = public_layout(state)
    except ValueError as exc:
        raise InputError(source, f"not the public network's layout: {exc}") from None
    ref = build_model("full", depth, 8, gam_channel_gate="none", width=PAPER_WIDTH).state_dict()
    mapped, unexpected = {}, []
    for key, value in state.items():
        ours = to_ours_key(key, head)
        if ours is None or ours not in ref:
            unexpected.append(key)
        else:
            mapped[ours] = value
    missing = [to_public_key(k, head) for k in ref if k not in mapped]
    shapes = [f"{to_public_key(k, head)} {tuple(v.shape)} (expected {tuple(ref[k].shape)})"
              for k, v in mapped.items() if tuple(v.shape) != tuple(ref[k].shape)]
    problems = [f"{label}: {', '.join(items[:8])}" + (f" and {len(items) - 8} more" if len(items) > 8 else "")
                for label, items in (("missing keys", missing), ("unexpected keys", unexpected),
                                     ("shape mismatches", shapes)) if items]
    if problems:
        raise InputError(source, f"public-code state dict does not fit the full model at depth {depth}: "
                                 + "; ".join(problems))
    return {k: mapped[k] for k in ref}, depth, head


class PublicInput(nn.Module):
    """Our model fed as the public code fed its network: frames in [0, 1] scaled to [-1, 1]."""

    def __init__(self, net: nn.Module):
        super().__init__()
        self.net = net

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.net(x * 2.0 - 1.0)


def public_model(state, image_size: int, source: str | Path = "checkpoint") -> tuple[nn.Module, dict]:
    """Our ``full`` model (ungated GAM channel branch) holding a public state dict, behind
    PublicInput, and metadata as ``train.load_model`` gives it (label_stats None: the public
    checkpoint does not record the force range it was normalised with)."""
    ours, depth, head = from_public(state, source)
    net = build_model("full", depth, image_size, gam_channel_gate="none", width=PAPER_WIDTH)
    net.load_state_dict(ours)
    meta = {"variant": "full", "architecture": NAMED_ARCHITECTURES["full"].as_dict(), "depth": depth, "image_size": int(image_size), "gam_channel_gate": "none",
            "width": PAPER_WIDTH, "label": head, "normalise": "minmax", "label_stats": None, "source": "public", "head": head,
            "input_range": [-1.0, 1.0]}
    return PublicInput(net), meta
