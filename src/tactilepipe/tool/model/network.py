"""Tool-force model of study 000 (paper section III-B), written out by hand.

Input: the loader's (b, 4, S, S) tensor in [0, 1], channels [left, left_ref, right, right_ref].
The model picks its own channels, so every variant is fed by the same loader::

    per sensor   [current, reference] (2 ch) -> encoder: 3 x [conv3x3 pad 1, BN, ReLU, maxpool 2]
                 with 64/128/256 channels, Dropout 0.2 -> GAM(256)               (S/8 x S/8)
    fusion       concat both sensors -> 512 ch -> GAM(512)
    regressor    ResNet (no pretrained weights) whose stem conv takes the fused channels:
                 Conv(C->64, 7, stride 2, pad 3), BN, ReLU, maxpool 3/2 pad 1; stages of BasicBlock
                 (depth 18, 34) or Bottleneck (50, 101); global average pool; fc removed
    head         Linear(512 | 2048 -> 1024), ReLU, Linear(1024 -> 512), ReLU, Linear(512 -> 1)

Output: (b,) normalised force. GAM: channel branch Linear(C->C/4)-ReLU-Linear(C/4->C) applied per
pixel, then sigmoid, multiplied in; spatial branch Conv7x7(C->C/4)-BN-ReLU-Conv7x7(C/4->C)-BN-sigmoid
multiplied in. The public code has no sigmoid on the channel branch; with it absent the two gates
in a row made the features a 4th-degree polynomial of the input and, in eval mode, they collapsed
to ~1e-7 (measured), so we gate as the GAM paper does. ``gam_channel_gate="none"`` (params.yaml
tool_train.gam_channel_gate) builds the public flavour, which its published weights need; it
creates the same parameters in the same order, so the default ("sigmoid") is unchanged. Kaiming initialisation, then zero-init of
each residual block's last BN and of the output layer (see _kaiming_init).

The channel counts above are the paper's, at ``width`` 64 (params.yaml tool_train.width; the
published weights have it). Every channel count and the head's hidden sizes scale with ``width``
(encoder w/2w/4w, ResNet stem and stages w..8w, head 16w and 8w): the smoke scale runs width 8,
so its checkpoints take about 1 MB instead of 100 MB. At 64 the layers, and the order in which
they are created and initialised, are exactly the paper's.

Parameter counts do not depend on the image size (the network is fully convolutional up to the
global pool). ``full`` at depth 101: 57,297,665 parameters (the paper: about 57 M).

Input sizes: the encoder halves the image three times (S/8); the ResNet stem divides by 4 and
its stages by 8 more, every stride-2 step rounding up, and the global pool is adaptive. So any
S >= MIN_IMAGE_SIZE (8: the encoder's third pool needs a 2x2 map) runs; below it build_model and
forward raise ArgumentError (a TactilepipeError, and a ValueError), which the CLI prints as one
line. Even at 224 px the published design reaches 1x1 in the last ResNet stage (28 / 32); at
64 px the maps are 1x1 from the second stage on, at 32 px from the first.
With 1x1 maps, BatchNorm in training mode needs at least 2 samples per batch (the trainer skips
a trailing batch of one sample).
"""

from __future__ import annotations

import numbers

import torch
from torch import nn

from tactilepipe.core.errors import ArgumentError
from tactilepipe.tool.model import fixed_order
from tactilepipe.core.tool_vocabulary import RESNET_DEPTHS as DEPTHS
from tactilepipe.tool.model.variants import NAMED_ARCHITECTURES, Architecture

MIN_IMAGE_SIZE = 8
GAM_CHANNEL_GATES = ("sigmoid", "none")
PAPER_WIDTH = 64                     # the published model's width (its weights need it)


def _unused_taps(kernel: int, padding: int, stride: int, size: int) -> int:
    """How many kernel taps at each end of one axis only ever meet zero padding on an input of
    ``size`` pixels (the same number at both ends, so the padding stays symmetric)."""
    last_out = (size + 2 * padding - kernel) // stride      # index of the last output pixel
    low = max(0, padding - last_out * stride)                # leading taps left of every output's window
    high = max(0, kernel - padding - size)                   # trailing taps right of the first output's
    return min(low, high)


class _CentreTaps(torch.autograd.Function):
    """weight[:, :, th:-th, tw:-tw] whose gradient keeps the weight's memory format. A plain slice
    returns a row-major gradient, and laying it out as the channels_last weight cost more than
    the trimmed taps saved (measured: a 10 ms copy per step for a 7x7 GAM conv)."""

    @staticmethod
    def forward(ctx, weight: torch.Tensor, th: int, tw: int) -> torch.Tensor:
        ctx.save_for_backward(weight)
        ctx.taps = th, tw
        kh, kw = weight.shape[-2:]
        return weight[:, :, th:kh - th, tw:kw - tw]

    @staticmethod
    def backward(ctx, grad: torch.Tensor):
        (weight,), (th, tw) = ctx.saved_tensors, ctx.taps
        kh, kw = weight.shape[-2:]
        full = torch.zeros_like(weight)            # same strides as the weight
        full[:, :, th:kh - th, tw:kw - tw] = grad
        return full, None, None


class TrimmedConv2d(nn.Conv2d):
    """nn.Conv2d (zero padding, dilation 1) that skips the kernel taps which only meet padding.

    The maps here are tiny (at 32 px the ResNet runs on 1x1 maps, at 16 px the GAMs' 7x7 convs
    on 2x2 ones), and CPU kernels multiply the padding zeros like any other pixel: a 3x3 conv on
    a 1x1 map does 9x the useful work. Trimming those taps gives the same output and the same
    gradients (the skipped taps get a zero gradient either way, so Adam never moves them); the
    parameters and state_dict are those of nn.Conv2d."""

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        (kh, kw), (ph, pw), (sh, sw) = self.kernel_size, self.padding, self.stride
        th = _unused_taps(kh, ph, sh, x.shape[-2])
        tw = _unused_taps(kw, pw, sw, x.shape[-1])
        if th == 0 and tw == 0:
            return fixed_order.conv2d(x, self.weight, self.bias, self.stride, self.padding, self.groups)
        weight = _CentreTaps.apply(self.weight, th, tw)
        return fixed_order.conv2d(x, weight, self.bias, self.stride, (ph - th, pw - tw), self.groups)


class Linear(nn.Linear):
    """nn.Linear that takes the fixed-order kernels while they are enabled (tool/model/fixed_order.py),
    as every convolution here does through TrimmedConv2d."""

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return fixed_order.linear(x, self.weight, self.bias)


class GAM(nn.Module):
    """Global Attention Mechanism (spatial branch sigmoid-gated; the channel branch too unless
    ``channel_gate`` is "none", the public code's flavour; see the module docstring)."""

    def __init__(self, channels: int, rate: int = 4, channel_gate: str = "sigmoid"):
        super().__init__()
        self.channel_gate = channel_gate
        hidden = channels // rate
        self.channel = nn.Sequential(Linear(channels, hidden), nn.ReLU(inplace=True), Linear(hidden, channels))
        self.spatial = nn.Sequential(
            TrimmedConv2d(channels, hidden, 7, padding=3), nn.BatchNorm2d(hidden), nn.ReLU(inplace=True),
            TrimmedConv2d(hidden, channels, 7, padding=3), nn.BatchNorm2d(channels))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        att = self.channel(x.permute(0, 2, 3, 1)).permute(0, 3, 1, 2)   # per pixel over channels
        x = x * (torch.sigmoid(att) if self.channel_gate == "sigmoid" else att)
        return x * torch.sigmoid(self.spatial(x))


class Encoder(nn.Module):
    def __init__(self, in_channels: int, width: int, dropout: float = 0.2):
        super().__init__()
        layers, c = [], in_channels
        for w in (width, 2 * width, 4 * width):
            layers += [TrimmedConv2d(c, w, 3, padding=1), nn.BatchNorm2d(w), nn.ReLU(inplace=True), nn.MaxPool2d(2)]
            c = w
        layers.append(nn.Dropout(dropout))
        self.body = nn.Sequential(*layers)
        self.out_channels = c

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.body(x)


class BasicBlock(nn.Module):
    expansion = 1

    def __init__(self, inplanes: int, planes: int, stride: int = 1):
        super().__init__()
        self.conv1 = TrimmedConv2d(inplanes, planes, 3, stride, 1, bias=False)
        self.bn1 = nn.BatchNorm2d(planes)
        self.conv2 = TrimmedConv2d(planes, planes, 3, 1, 1, bias=False)
        self.bn2 = nn.BatchNorm2d(planes)
        self.relu = nn.ReLU(inplace=True)
        self.downsample = _downsample(inplanes, planes * self.expansion, stride)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        identity = x if self.downsample is None else self.downsample(x)
        out = self.relu(self.bn1(self.conv1(x)))
        out = self.bn2(self.conv2(out))
        return self.relu(out + identity)


class Bottleneck(nn.Module):
    expansion = 4

    def __init__(self, inplanes: int, planes: int, stride: int = 1):
        super().__init__()
        self.conv1 = TrimmedConv2d(inplanes, planes, 1, bias=False)
        self.bn1 = nn.BatchNorm2d(planes)
        self.conv2 = TrimmedConv2d(planes, planes, 3, stride, 1, bias=False)   # stride on the 3x3 (v1.5)
        self.bn2 = nn.BatchNorm2d(planes)
        self.conv3 = TrimmedConv2d(planes, planes * self.expansion, 1, bias=False)
        self.bn3 = nn.BatchNorm2d(planes * self.expansion)
        self.relu = nn.ReLU(inplace=True)
        self.downsample = _downsample(inplanes, planes * self.expansion, stride)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        identity = x if self.downsample is None else self.downsample(x)
        out = self.relu(self.bn1(self.conv1(x)))
        out = self.relu(self.bn2(self.conv2(out)))
        out = self.bn3(self.conv3(out))
        return self.relu(out + identity)


def _downsample(inplanes: int, outplanes: int, stride: int) -> nn.Module | None:
    if stride == 1 and inplanes == outplanes:
        return None
    return nn.Sequential(TrimmedConv2d(inplanes, outplanes, 1, stride, bias=False), nn.BatchNorm2d(outplanes))


class ResNetRegressor(nn.Module):
    """ResNet trunk whose stem takes ``in_channels`` fused feature channels; fc removed."""

    def __init__(self, in_channels: int, depth: int, width: int):
        super().__init__()
        kind, blocks = DEPTHS[depth]
        block = BasicBlock if kind == "basic" else Bottleneck
        self.stem = nn.Sequential(TrimmedConv2d(in_channels, width, 7, 2, 3, bias=False), nn.BatchNorm2d(width),
                                  nn.ReLU(inplace=True), nn.MaxPool2d(3, 2, 1))
        stages, inplanes = [], width
        for i, (planes, n) in enumerate(zip((width, 2 * width, 4 * width, 8 * width), blocks)):
            layers = []
            for j in range(n):
                layers.append(block(inplanes, planes, 2 if (i > 0 and j == 0) else 1))
                inplanes = planes * block.expansion
            stages.append(nn.Sequential(*layers))
        self.stages = nn.Sequential(*stages)
        self.pool = nn.AdaptiveAvgPool2d(1)
        self.out_features = inplanes

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return torch.flatten(self.pool(self.stages(self.stem(x))), 1)


class ToolForceNet(nn.Module):
    def __init__(self, variant: str, depth: int, image_size: int, gam_channel_gate: str, width: int,
                 spec: Architecture):
        super().__init__()
        self.variant, self.depth, self.image_size, self.width = variant, depth, image_size, width
        self.gam_channel_gate, self.architecture = gam_channel_gate, spec
        self.slices = spec.sensors
        self.encoders = nn.ModuleList(Encoder(b - a, width) for a, b in spec.sensors)
        self.sensor_gams = nn.ModuleList(GAM(e.out_channels, channel_gate=gam_channel_gate) if spec.gam
                                         else nn.Identity() for e in self.encoders)
        fused = sum(e.out_channels for e in self.encoders)
        self.fusion_gam = (GAM(fused, channel_gate=gam_channel_gate) if (spec.gam and len(self.encoders) > 1)
                           else nn.Identity())
        self.regressor = ResNetRegressor(fused, depth, width)
        f = self.regressor.out_features
        self.head = nn.Sequential(Linear(f, 16 * width), nn.ReLU(inplace=True), Linear(16 * width, 8 * width),
                                  nn.ReLU(inplace=True), Linear(8 * width, 1))
        _kaiming_init(self)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        if x.ndim != 4 or x.shape[1] != 4:
            raise ArgumentError(f"forward: expected input x (batch, 4, S, S) [left, left_ref, right, right_ref], "
                                f"got {tuple(x.shape)}")
        if tuple(x.shape[2:]) != (self.image_size, self.image_size):
            raise ArgumentError(f"forward: model built for {self.image_size} px inputs, got input x of "
                                f"{tuple(x.shape[2:])}")
        feats = [gam(enc(x[:, a:b])) for (a, b), enc, gam in zip(self.slices, self.encoders, self.sensor_gams)]
        z = self.fusion_gam(torch.cat(feats, 1) if len(feats) > 1 else feats[0])
        return self.head(self.regressor(z)).squeeze(1)


def _kaiming_init(model: nn.Module) -> None:
    for m in model.modules():
        if isinstance(m, nn.Conv2d):
            nn.init.kaiming_normal_(m.weight, mode="fan_out", nonlinearity="relu")
            if m.bias is not None:
                nn.init.zeros_(m.bias)
        elif isinstance(m, nn.Linear):
            nn.init.kaiming_normal_(m.weight, mode="fan_in", nonlinearity="relu")
            nn.init.zeros_(m.bias)
        elif isinstance(m, nn.BatchNorm2d):
            nn.init.ones_(m.weight)
            nn.init.zeros_(m.bias)
    # Start as a calm function: each residual block as the identity (its last BN scaled to 0, as
    # torchvision's zero_init_residual) and the force output at 0. With Kaiming on every layer the
    # untrained model's outputs spread ~1 (in units of the whole label range) from frame to frame,
    # and Adam at 2e-4 spends hundreds of steps unlearning that noise before it learns the force.
    for m in model.modules():
        if isinstance(m, (BasicBlock, Bottleneck)):
            nn.init.zeros_((m.bn2 if isinstance(m, BasicBlock) else m.bn3).weight)
    nn.init.zeros_(model.head[-1].weight)


def check_image_size(image_size: int) -> None:
    if isinstance(image_size, bool) or not isinstance(image_size, numbers.Integral):
        raise ArgumentError(f"image_size {image_size!r} must be a whole number of pixels, at least {MIN_IMAGE_SIZE} "
                            f"(the encoder divides by 8)")
    if image_size < MIN_IMAGE_SIZE:
        raise ArgumentError(f"image_size {image_size!r} is too small: the model needs at least {MIN_IMAGE_SIZE} px "
                            f"(the encoder divides by 8)")


def build_model(variant: str, depth: int, image_size: int, gam_channel_gate: str, width: int,
                architecture: Architecture | None = None) -> ToolForceNet:
    """A freshly initialised model (no pretrained weights). ``variant`` is the variant's name and
    ``architecture`` what it builds (its params.yaml ``tool_variants`` entry, or a checkpoint's
    record of it; None: the name's entry of variants.NAMED_ARCHITECTURES), ``depth`` one of 18,
    34, 50, 101, ``image_size`` the side S of the square inputs, ``gam_channel_gate`` one of
    GAM_CHANNEL_GATES, ``width`` the channels of the first encoder stage (PAPER_WIDTH: the paper's)."""
    if gam_channel_gate not in GAM_CHANNEL_GATES:
        raise ArgumentError(f"unknown gam_channel_gate '{gam_channel_gate}' (one of {', '.join(GAM_CHANNEL_GATES)})")
    if architecture is None:
        if variant not in NAMED_ARCHITECTURES:
            raise ArgumentError(f"unknown model variant '{variant}' without its definition (sensors, gam): the "
                                f"names known without one are {', '.join(NAMED_ARCHITECTURES)}")
        architecture = NAMED_ARCHITECTURES[variant]
    if not architecture.sensors or any(not 0 <= a < b <= 4 for a, b in architecture.sensors):
        raise ArgumentError(f"model variant '{variant}': sensors {[list(s) for s in architecture.sensors]} must be "
                            f"[start, stop) slices of the 4 input channels")
    if depth not in DEPTHS:
        raise ArgumentError(f"unsupported ResNet depth {depth} (one of {', '.join(map(str, DEPTHS))})")
    check_image_size(image_size)
    if isinstance(width, bool) or not isinstance(width, numbers.Integral) or width < 1:
        raise ArgumentError(f"model width {width!r} must be a whole number of channels, at least 1")
    return ToolForceNet(variant, depth, int(image_size), gam_channel_gate, int(width), architecture)


def count_parameters(model: nn.Module, trainable_only: bool = False) -> int:
    return sum(p.numel() for p in model.parameters() if p.requires_grad or not trainable_only)
