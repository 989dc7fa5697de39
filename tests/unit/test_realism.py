"""The simulated DIGIT frames against the shipped real DIGIT frame (tactilepipe realism), the realism
statistics themselves, and a sensor's own background frame (simulate_tool.render.background)."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from support import tool_sim
from support.project import REPO
from tactilepipe.cli import main as cli
from tactilepipe.core.config import deep_merge, load_params
from tactilepipe.core.errors import InputError
from tactilepipe.tool.sim import realism
from tactilepipe.tool import sim as ts
from tactilepipe.tool.sim.background import SHIPPED, load_background
from tactilepipe.tool.formats.native_layout import FRAME_H, FRAME_W, SENSORS


@pytest.fixture(scope="module")
def default_params() -> dict:
    return load_params(REPO / "params.yaml")


def _with_background(params: dict, path) -> dict:
    return {**params, "simulate_tool": deep_merge(params["simulate_tool"], {"render": {"background": str(path)}})}


def _rest_frames(params: dict, step: int = 4) -> dict:
    """Frame 0 (tip at rest: the zero-force reference) of every ``step``-th pressing trial, both
    fingers, exactly as the session writes it (noise, LED flicker, drift and warm-up included)."""
    plan = [s for s in ts.session_plan(params) if s.kind == "normal"][::step]
    out = {}
    for spec in plan:
        trial = ts.Trial(spec, params)
        for s, name in enumerate(SENSORS):
            out[f"{spec.name}_{name}"] = trial.frame(s, 0)
    return out


@pytest.fixture(scope="module")
def rest_dir(tmp_path_factory, default_params):
    d = tmp_path_factory.mktemp("sim_rest")
    for name, img in _rest_frames(default_params).items():
        cv2.imwrite(str(d / f"{name}.png"), img)
    return d


def test_default_rest_frames_match_the_real_digit(rest_dir, tmp_path, capsys):
    real_dir = SHIPPED.parent
    result = realism.compare(real_dir, rest_dir)
    real, sim = result["real"], result["sim"]
    assert real.n_frames == 1 and sim.n_frames == 48
    assert np.abs(sim.channel_mean - real.channel_mean).max() <= 10.0            # DN
    assert (np.abs(sim.spatial_std / real.spatial_std - 1) <= 0.25).all()
    assert (np.abs(sim.noise_std / real.noise_std - 1) <= 0.5).all()
    assert result["layout_correlation"] >= 0.8
    # the same through the command line, which prints the table and writes the figure
    fig = tmp_path / "realism.png"
    assert cli.main(["realism", str(real_dir), str(rest_dir), "--figure", str(fig)]) == 0
    printed = capsys.readouterr().out
    assert f"{result['layout_correlation']:.3f}" in printed and "channel mean" in printed
    assert fig.stat().st_size > 10_000 and cv2.imread(str(fig)) is not None


def test_landscape_frames_are_turned_to_portrait_and_sizes_matched(rest_dir, tmp_path):
    land, big, port = tmp_path / "landscape", tmp_path / "vga", tmp_path / "portrait"
    land.mkdir(), big.mkdir(), port.mkdir()
    for p in sorted(rest_dir.glob("*.png"))[:6]:
        img = cv2.imread(str(p))
        cv2.imwrite(str(port / p.name), img)
        cv2.imwrite(str(land / p.name), img.transpose(1, 0, 2))                   # 320 wide x 240 high
        cv2.imwrite(str(big / p.name), cv2.resize(img, (2 * FRAME_W, 2 * FRAME_H), interpolation=cv2.INTER_NEAREST))
    portrait = realism.folder_stats(port)
    turned = realism.folder_stats(land)
    assert turned.size == (FRAME_W, FRAME_H) and turned.n_frames == 6
    for key in ("channel_mean", "spatial_std", "noise_std", "layout"):
        np.testing.assert_allclose(getattr(turned, key), getattr(portrait, key), rtol=1e-5, atol=1e-4)
    # a VGA real folder: the simulated frames are compared at its size, the layouts still agree
    result = realism.compare(big, land)
    assert result["real"].size == (2 * FRAME_W, 2 * FRAME_H) == result["sim"].size
    assert result["layout_correlation"] > 0.99


def test_change_statistic_against_each_subfolders_reference(tmp_path):
    bg = cv2.imread(str(SHIPPED))
    for trial, bump in (("a", 20), ("b", 40)):
        d = tmp_path / "frames" / trial
        d.mkdir(parents=True)
        cv2.imwrite(str(d / "000_ref.png"), bg)
        pressed = bg.astype(np.int16)
        pressed[100:150, 80:130] += bump                     # a 50 x 50 px patch, all channels
        cv2.imwrite(str(d / "001.png"), np.clip(pressed, 0, 255).astype(np.uint8))
    stats = realism.folder_stats(tmp_path / "frames")
    assert stats.n_frames == 4 and stats.change_mean_dn.size == 2                # references are not counted
    area = 2500 / (FRAME_W * FRAME_H)
    assert stats.change_share == pytest.approx([area, area], rel=0.05)
    assert stats.change_mean_dn[1] == pytest.approx(2 * stats.change_mean_dn[0], rel=0.05)
    assert stats.change_mean_dn[0] == pytest.approx(20 * area, rel=0.1)
    # one given reference frame for the whole folder instead
    fixed = realism.folder_stats(tmp_path / "frames", reference=tmp_path / "frames" / "a" / "000_ref.png")
    assert fixed.change_mean_dn.size == 4 and fixed.change_mean_dn.min() == 0.0


def test_contact_changes_frames_more_than_rest_noise(default_params, tmp_path):
    spec = [s for s in ts.session_plan(default_params) if s.kind == "normal"][0]
    out = tool_sim.render_at_forces(spec, default_params, [0.0, 0.0, 5.0, 10.0], noise=True)
    for name in SENSORS:
        d = tmp_path / name
        d.mkdir()
        for k, img in enumerate(out[name]):
            cv2.imwrite(str(d / f"{k:03d}.png"), img)
    stats = realism.folder_stats(tmp_path)
    mean, p99, share = (v.reshape(2, 3) for v in (stats.change_mean_dn, stats.change_p99, stats.change_share))
    # columns: a second frame at 0 N (noise, flicker), 5 N, 10 N; the press changes a small area a lot
    assert (mean[:, 2] > mean[:, 1]).all() and (mean[:, 1] > mean[:, 0]).all()
    assert (p99[:, 1] > p99[:, 0]).all() and (p99[:, 2] > 2 * p99[:, 0]).all()
    assert (share[:, 0] < 0.001).all() and (share[:, 2] > 0.005).all()


def test_realism_refuses_an_empty_folder(tmp_path, capsys):
    (tmp_path / "empty").mkdir()
    assert cli.main(["realism", str(SHIPPED.parent), str(tmp_path / "empty")]) == 2
    err = capsys.readouterr().err
    assert "empty" in err and "no frames" in err and "Traceback" not in err


def test_a_users_background_changes_the_frames(default_params, tmp_path):
    mirrored = tmp_path / "mirrored.png"                     # red along the right side instead of the left
    cv2.imwrite(str(mirrored), cv2.imread(str(SHIPPED))[:, ::-1])
    landscape = tmp_path / "landscape.png"                   # the same frame as the camera streams it
    cv2.imwrite(str(landscape), cv2.imread(str(SHIPPED)).transpose(1, 0, 2))
    default = _rest_frames(default_params, step=48)
    own = _rest_frames(_with_background(default_params, mirrored), step=48)
    same = _rest_frames(_with_background(default_params, landscape), step=48)
    for key in default:
        d, o = default[key].astype(np.float32), own[key].astype(np.float32)
        assert d[:, :60, 2].mean() > d[:, -60:, 2].mean() + 40          # shipped: red on the left
        assert o[:, -60:, 2].mean() > o[:, :60, 2].mean() + 40          # the user's: red on the right
        np.testing.assert_array_equal(same[key], default[key])


@pytest.mark.parametrize("make, message", [
    (lambda: cv2.cvtColor(cv2.imread(str(SHIPPED)), cv2.COLOR_BGR2GRAY), "3-channel"),
    (lambda: cv2.cvtColor(cv2.imread(str(SHIPPED)), cv2.COLOR_BGR2BGRA), "3-channel"),
    (lambda: cv2.imread(str(SHIPPED))[:200], "3:4 shape"),
    (lambda: np.zeros((FRAME_H, FRAME_W, 3), np.uint8), "not a lit"),
    (lambda: np.full((FRAME_H, FRAME_W, 3), 100, np.uint8), "flat"),
])
def test_a_bad_background_is_refused(tmp_path, make, message):
    path = tmp_path / "bg.png"
    cv2.imwrite(str(path), make())
    with pytest.raises(InputError, match=message) as info:
        load_background(str(path))
    assert str(path) in str(info.value) and "simulate_tool.render.background" in str(info.value)


def test_simulate_tool_stops_on_a_bad_background_with_one_line(tmp_path, capsys):
    bad = tmp_path / "bad.jpg"
    bad.write_bytes(b"not an image")
    override = json.dumps({"simulate_tool": {"render": {"background": str(bad)}}})
    rc = cli.main(["tool-simulate", "--params", str(REPO / "params.yaml"), "--scale", "smoke",
                   "--override", override, "--out-dir", str(tmp_path / "session"), "--jobs", "2"])
    err = capsys.readouterr().err
    assert rc == 2 and str(bad) in err and "simulate_tool.render.background" in err
    assert "Traceback" not in err and not list((tmp_path / "session").glob("*/meta.json"))
