"""`snakemake --report` on the shared smoke build, read as a reader reads it: one self-contained
HTML file whose front page shows each scene's headline tables as tables (each number once) and the
parameters as one collapsed table, checked in headless Chromium (Debian's `chromium`; `.ci/run`
installs it, elsewhere the rendering test skips without it)."""

from __future__ import annotations

import json
import re
from html import unescape
from pathlib import Path

import numpy as np
import pytest

from support.browser import chromium_run
from support.project import snakemake

pytestmark = pytest.mark.integration

# Measured in the browser: where the landing page's title and Table 1 sit in the window once the
# report has drawn itself, written on <body> for --dump-dom to carry out.
LAYOUT_PROBE = """<script>
window.addEventListener("load", () => setTimeout(() => {
  const box = (el) => { if (!el) return null; const r = el.getBoundingClientRect(); return [r.top, r.bottom]; };
  const title = [...document.querySelectorAll("h1")].find(h => h.textContent.startsWith("tactilepipe: raw tactile"));
  const table = [...document.querySelectorAll("table.tactilepipe")].find(t => t.textContent.includes("Table 1"));
  document.body.dataset.layout = JSON.stringify({title: box(title), table: box(table), view: window.innerHeight});
}, 3000));
</script>"""


@pytest.fixture(scope="module")
def report(smoke_build, tmp_path_factory) -> dict:
    out = tmp_path_factory.mktemp("report") / "report.html"
    snakemake(smoke_build, "--report", str(out))
    text = out.read_text()
    # the front page: reStructuredText rendered by docutils, held as one JavaScript string
    line = next(l for l in text.splitlines() if "workflow_desc = " in l)
    front = json.loads(line[line.index("workflow_desc = ") + len("workflow_desc = "):].rstrip().rstrip(";"))
    return {"path": out, "html": text, "front": front}


def test_the_report_is_one_self_contained_file_with_every_result(report):
    html = report["html"]
    assert len(html) > 100_000
    for name in ("r2_by_modality", "drift_curves", "pressing_strip", "window_heatmap", "table1_r2.html",
                 "fits.html", "variants.html", "mu_max", "learning_rate"):
        assert name in html, name


def test_the_front_page_shows_tables_as_tables_and_parameters_in_one_collapsed_table(report):
    front = report["front"]
    assert "System Message" not in front, "the front page's reStructuredText has an error"
    heads = [front.index(h) for h in ("Volume from force", "Sensor drift", "Tool force from touch (study 000): normal",
                                      "Tool force from touch (study 000): shear", "Parameters of this run")]
    assert heads == sorted(heads)
    # headline tables: HTML tables with their captions, not Markdown source, each number once
    sections = [front[a:b] for a, b in zip(heads, heads[1:])]
    table = re.compile(r"<table class=\"tactilepipe\">.*?</table>", re.S)
    volume, drift, normal, shear = ([t for t in table.findall(part)] for part in sections)
    assert len(volume) == 1 and len(drift) >= 2 and len(normal) == len(shear) == 2
    assert "<caption>Table 1: R²" in volume[0] and "est_vol (baseline)" in volume[0]
    assert "<th>run</th>" in drift[0] and "rest_frame_rmse_linear" in normal[0] + shear[0]
    assert "**Table 1" not in front and "| method |" not in front and "|---|" not in front
    for machine_column in ("r2_mean", "r2_std", "ci95_low", "ci95_high"):
        assert machine_column not in volume[0], machine_column
    # the parameters: one collapsed table of key/value rows, no Python dict dumps
    params = front[heads[-1]:]
    assert re.search(r"<details class=\"parameters\"><summary>", params) and "<details open" not in params
    assert "<code>tool_train.lr</code>" in params and "<code>simulate_volume.friction_static</code>" in params
    assert "<code>scales.smoke.tool_train.max_epochs</code>" in params
    assert "<code>scales.default." not in params and "<code>scales.paper." not in params
    assert "{&#x27;" not in params and "{'" not in params


def test_a_browser_renders_the_tables_and_keeps_the_parameters_closed(report, tmp_path):
    dom = chromium_run(report["path"], "--dump-dom")
    tables = re.findall(r"<table class=\"tactilepipe\">.*?</table>", dom, re.S)
    assert tables and "Table 1: R²" in tables[0], dom[:2000]
    cells = re.findall(r"<td class=\"num\">([^<]*)</td>", tables[0])
    assert cells and all(re.match(r"^[-+−]?\d", c) for c in cells)
    assert "**Table 1" not in dom and "| method |" not in dom
    details = re.search(r"<details class=\"parameters\"[^>]*>", dom)
    assert details and " open" not in details.group(0)
    png = tmp_path / "front.png"
    chromium_run(report["path"], f"--screenshot={png}", "--window-size=1400,2400")
    import cv2
    image = cv2.imread(str(png))
    assert image is not None and image.shape[:2] == (2400, 1400)
    # a page with content: many distinct grey levels, not one blank colour
    assert len(np.unique(cv2.cvtColor(image, cv2.COLOR_BGR2GRAY))) > 20


def test_the_landing_page_opens_at_its_title_with_table_1_in_view(report, tmp_path):
    """A landing page taller than the window once opened about 1,000 px below its title, which could
    not be scrolled to (Snakemake centres the page in a window-high box): at 1400x900 the title and
    the volume Table 1 are in the window as the report opens."""
    html = report["html"]
    end = html.rfind("</body>")
    page = tmp_path / "probed.html"
    page.write_text(html[:end] + LAYOUT_PROBE + html[end:])
    dom = chromium_run(page, "--dump-dom", "--window-size=1400,900")
    found = re.search(r'data-layout="([^"]*)"', dom)
    assert found, "the probe did not run: " + dom[:2000]
    layout = json.loads(unescape(found.group(1)))
    assert layout["title"] and layout["table"], layout
    (title_top, title_bottom), (table_top, table_bottom), view = layout["title"], layout["table"], layout["view"]
    assert 0 <= title_top < title_bottom < table_top < table_bottom <= view, layout


def test_every_item_carries_a_readable_label_and_a_caption_of_its_data_scale_and_split(report):
    """The result tables list items by label, not by file name, and each caption says which data,
    scale and split the item shows, without dumps of parameter groups."""
    line = next(l for l in report["html"].splitlines() if l.strip().startswith("var results = {"))
    items = json.loads(line.strip()[len("var results = "):].rstrip(";"))
    assert len(items) > 40
    for path, item in items.items():
        label = (item["labels"] or {}).get("result", "")
        assert label and not re.search(r"[_/]|\.(png|html|json|md)$", label), (path, item["labels"])
        caption = item["caption"]
        text = re.sub(r"<[^>]+>", "", caption)
        scene = path.split("/")[2]
        study = {"volume": "study 001", "drift": "study 001", "tool_normal": "study 000, normal force",
                 "tool_shear": "study 000, shear force"}[scene]
        assert f"simulated session sim-smoke ({study}), scale smoke." in text, (path, text)
        assert "Split: " in text, (path, text)
        assert "{'" not in text and "{&#x27;" not in caption and "overlay" not in text, (path, text)
