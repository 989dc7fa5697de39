"""The figures' data as DVC data plots: `dvc plots diff` of two commits holds both commits' rows
of every data plot dvc.yaml declares, with the real DVC command line, in a small git + DVC
project whose data files the real figure writers made (two commits, different numbers).

The HTML page DVC writes for data plots loads vega, vega-lite and vega-embed from a CDN
(dvc-render's VegaRenderer): offline it draws the image plots but not the data plots. The
checkout's DVC is pointed at a page template with the libraries inline
(workflow/scripts/offline_plots.py, run by `make`), which a browser with no network draws."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from support.browser import OFFLINE, chromium_run
from support.project import REPO, dvc, git
from tactilepipe.drift.analyse import fit_models
from tactilepipe.drift.figures import write_drift_figure
from tactilepipe.tool.report import figures_models
from tactilepipe.volume import figures

pytestmark = pytest.mark.integration
SCALE = "smoke"


def data_plots() -> dict[str, dict]:
    """{path: definition} of dvc.yaml's data plots, paths for the smoke scale."""
    plots = yaml.safe_load((REPO / "dvc.yaml").read_text())["plots"]
    return {path.replace("${scale}", SCALE): spec for entry in plots if isinstance(entry, dict)
            for path, spec in entry.items()}


def write_revision(wd: Path, shift: float) -> None:
    """Every data plot's file, by the figure writer that makes it in the pipeline; ``shift`` moves
    the numbers so that two revisions differ."""
    for path in data_plots():
        png = (wd / path).with_suffix(".png")
        name = png.stem
        if name == "mu_r2_curve":
            mus = np.linspace(0.2, 1.2, 6)
            curve = pd.concat([pd.DataFrame({"fold": k, "mu": mus, "r2_train": 0.9 - shift - (mus - 0.6) ** 2 * (k + 1)})
                               for k in (0, 1)])
            optima = pd.DataFrame([{"fold": k, "mu_opt": 0.6, "r2_train": 0.9 - shift} for k in (0, 1)])
            figures.mu_curves(curve, optima, 0.6, png)
        elif name == "drift_curves":
            t = np.arange(0.0, 35.0, 5.0)
            series = pd.concat([pd.DataFrame({"run": run, "t_min": t, "drift_n": gain * (1 - np.exp(-t / 10)) + shift,
                                              "deviation_std_n": 0.01, "baseline_drift_n": 0.5 * gain * t / 30})
                                for run, gain in (("unloaded", 0.05), ("loaded", 0.2))])
            write_drift_figure(png, series, fit_models(series, [1, 2], 0.1), 0.1)
        elif name == "error_vs_runtime":
            runs = pd.DataFrame({"run": ["full", "full_r1", "no_ref"], "variant": ["full", "full", "no_ref"],
                                 "split": ["trial", "trial_r1", "trial"], "mae": [0.3 + shift, 0.32, 0.4],
                                 "train_s": [10.0, 11.0, 8.0], "latency_ms": [2.0, 2.1, 1.5]})
            figures_models.pareto(runs, png, looks={})
        elif name == "intervals":
            scores = {m: {"mae": [0.3 + shift + d, 0.35 + d], "r2": [0.9 - d, 0.88 - d]}
                      for m, d in (("full", 0.0), ("mean_predictor", 1.0))}
            summary = {m: {k: {"mean": float(np.mean(v)), "low": min(v), "high": max(v), "n": 2} for k, v in s.items()}
                       for m, s in scores.items()}
            figures_models.interval_bars(scores, summary, "normal", png, looks={})
        else:
            raise AssertionError(f"{path}: a data plot this test cannot write: add its writer here")
        assert (wd / path).is_file(), path


@pytest.fixture(scope="module")
def project(tmp_path_factory) -> Path:
    """Two commits of the data plots' files, with the project's dvc.yaml plots (nothing else)."""
    wd = tmp_path_factory.mktemp("dvcplots")
    git(wd, "init", "-q")
    git(wd, "config", "user.email", "test@example.org")
    git(wd, "config", "user.name", "test")
    dvc(wd, "init", "-q")
    dvc(wd, "config", "core.analytics", "false")
    (wd / "params.yaml").write_text(f"scale: {SCALE}\n")
    plots = yaml.safe_load((REPO / "dvc.yaml").read_text())["plots"]
    (wd / "dvc.yaml").write_text(yaml.safe_dump({"plots": [p for p in plots if isinstance(p, dict)]}, sort_keys=False))
    for message, shift in (("first", 0.0), ("second", 0.05)):
        write_revision(wd, shift)
        git(wd, "add", "-A")
        git(wd, "commit", "-q", "-m", message)
    return wd


def test_the_declared_data_plots_are_the_figures_data():
    plots = data_plots()
    names = sorted(Path(p).name for p in plots)
    assert names == sorted(["mu_r2_curve.csv", "drift_curves.csv"] + ["error_vs_runtime.csv", "intervals.csv"] * 2), names
    for path, spec in plots.items():
        assert {"x", "y", "template", "title"} <= set(spec), path


def test_plots_diff_holds_both_revisions_rows_of_every_data_plot(project):
    out = dvc(project, "plots", "diff", "HEAD~1", "HEAD", "--json").stdout
    found = json.loads(out)
    assert not found.get("errors"), found["errors"]
    assert len(data_plots()) == 6
    for path, spec in data_plots().items():
        (rendered,) = [r for r in found["data"][path] if r["type"] == "vega"]
        values = rendered["content"]["data"]["values"]
        revs = {v["rev"] for v in values}
        assert revs == {"HEAD~1", "HEAD"}, (path, revs)
        ys = spec["y"] if isinstance(spec["y"], list) else [spec["y"]]
        frame = pd.read_csv(project / path)
        assert {spec["x"], *ys} <= set(frame.columns), path
        for rev in ("HEAD~1", "HEAD"):
            rows = [v for v in values if v["rev"] == rev]
            # every row of the file, for each y field drawn
            assert len(rows) == len(frame) * len(ys), (path, rev, len(rows))
            assert all(spec["x"] in v for v in rows), path
        # the two commits' numbers differ, so the overlay shows a change
        first = sorted(str(v) for v in values if v["rev"] == "HEAD~1")
        second = sorted(str(v).replace("'HEAD'", "'HEAD~1'") for v in values if v["rev"] == "HEAD")
        assert first != second, path


def test_plots_diff_html_needs_the_cdn_only_for_vega(project):
    """The limit, checked so a DVC update that changes it is noticed: the page's only network
    references are the three vega scripts; the data itself is inline in the page."""
    dvc(project, "plots", "diff", "HEAD~1", "HEAD", "-o", "diff_html")
    page = (project / "diff_html" / "index.html").read_text()
    remote = sorted(set(re.findall(r"(?:src|href)=\"(https?://[^\"]+)\"", page)))
    assert sorted(re.sub(r"@[\d.]+$", "", u.rsplit("/", 1)[-1]) for u in remote) == ["vega", "vega-embed", "vega-lite"], remote
    assert page.count("vegaEmbed(") == len(data_plots())
    assert "HEAD~1" in page and "\"rev\": \"HEAD\"" in page.replace("'", "\"")


def test_with_the_offline_template_a_browser_with_no_network_draws_every_data_plot(project):
    # as make runs it when it installs .venv
    subprocess.run([sys.executable, str(REPO / "workflow/scripts/offline_plots.py"), "--project", str(project)],
                   check=True, capture_output=True, text=True)
    try:
        dvc(project, "plots", "diff", "HEAD~1", "HEAD", "-o", "offline_html")
    finally:
        dvc(project, "config", "--local", "--unset", "plots.html_template")   # the CDN test above needs DVC's page
    page = project / "offline_html" / "index.html"
    text = page.read_text()
    assert not re.findall(r"(?:src|href)=\"https?://", text)
    assert text.count("vegaEmbed(") == len(data_plots())
    dom = chromium_run(page, *OFFLINE, "--dump-dom")
    drawn = re.sub(r"<(script|style)\b.*?</\1>", "", dom, flags=re.S)     # the page as drawn, not its code
    # vega-embed marks each container it drew into and puts the chart's SVG in it; a page whose
    # libraries did not load keeps bare divs
    assert len(re.findall(r'<div id="[^"]+" class="vega-embed', drawn)) == len(data_plots()), drawn[:2000]
    assert drawn.count('class="marks"') == len(data_plots())
    assert ">HEAD~1<" in drawn and ">HEAD<" in drawn          # both revisions in the legends
