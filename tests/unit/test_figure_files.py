"""Every figure is written as a PNG and its SVG twin, the same bytes on every write, and both are
declared wherever a scene's outputs are; the figures that are DVC data plots write their numbers
beside them (the plots themselves: tests/integration/test_dvc_plots.py)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from tactilepipe.core.atomic import vector_twin
from tactilepipe.pipeline.scenes import SCENES, scene_targets
from tactilepipe.pipeline.sessions import SessionSheet
from tactilepipe.volume import figures

REPO = Path(__file__).resolve().parents[2]


def write_mu_curve(folder: Path) -> Path:
    """The volume baseline's mu-R² figure of two folds, through its real writer."""
    mus = np.linspace(0.2, 1.2, 11)
    curve = pd.concat([pd.DataFrame({"fold": k, "mu": mus, "r2_train": 0.9 - (mus - 0.6 - 0.1 * k) ** 2})
                       for k in (0, 1)])
    optima = pd.DataFrame([{"fold": k, "mu_opt": 0.6 + 0.1 * k, "r2_train": 0.9, "on_edge": False} for k in (0, 1)])
    out = folder / "figures" / "mu_r2_curve.png"
    figures.mu_curves(curve, optima, 0.65, out)
    return out


def test_a_figure_gets_its_svg_twin_and_two_writes_are_the_same_bytes(tmp_path):
    first, second = write_mu_curve(tmp_path / "a"), write_mu_curve(tmp_path / "b")
    assert first.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    svg = vector_twin(first)
    assert svg == first.with_suffix(".svg")
    text = svg.read_text()
    assert text.startswith("<?xml") and "<svg" in text and "<path" in text
    assert "<dc:date>" not in text                   # matplotlib stamps the date unless told not to
    for a, b in ((first, second), (svg, vector_twin(second)), (first.with_suffix(".csv"), second.with_suffix(".csv"))):
        assert a.read_bytes() == b.read_bytes(), a.name


def test_the_mu_curve_writes_its_numbers_beside_it(tmp_path):
    data = pd.read_csv(write_mu_curve(tmp_path).with_suffix(".csv"))
    assert list(data.columns) == ["mu", "r2_train_mean", "r2_train_min", "r2_train_max"]
    assert len(data) == 11 and (data["r2_train_min"] <= data["r2_train_mean"]).all()
    assert (data["r2_train_mean"] <= data["r2_train_max"]).all()


def test_every_declared_png_has_its_svg_declared_too(smoke_params):
    sheet = SessionSheet(smoke_params)
    targets = scene_targets(list(SCENES), "results/smoke", smoke_params, sheet)
    pngs = [t for t in targets if t.endswith(".png")]
    assert len(pngs) > 20 and any("clock_sync" in t for t in pngs)
    assert [t for t in pngs if t[:-4] + ".svg" not in targets] == []
    # the rules that list figures by hand (not through pipeline/scenes.py) name the twin as well
    for smk in sorted((REPO / "workflow/rules").glob("*.smk")):
        text = smk.read_text()
        assert text.count('.png"') == text.count('.svg"'), smk.name
