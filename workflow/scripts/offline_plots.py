"""Let `dvc plots show` and `dvc plots diff` draw the data plots without a network.

The page DVC writes loads vega, vega-lite and vega-embed from a CDN, so offline (a cluster node,
a train, a lab without internet) its data plots stay blank. This writes .dvc/offline_plots.html,
a page template for DVC with the three libraries inline (the bundle vl-convert ships, the same
libraries DVC's page would fetch) and without DVC's `{scripts}` placeholder, where the CDN tags
would go; then it points this checkout's DVC at it (`dvc config --local plots.html_template`).
`make` runs it when it installs .venv. Usage:

    .venv/bin/python workflow/scripts/offline_plots.py [--project .]
"""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

from tactilepipe.core.atomic import write_text

TEMPLATE = "offline_plots.html"       # in .dvc/, where DVC resolves a relative template path
VEGA_LITE = "5.21"                    # DVC's specs are vega-lite 5


def page(bundle: str) -> str:
    """DVC's page layout, with the libraries inline; DVC fills {refresh_tag} and {plot_divs}."""
    if "</script" in bundle:
        bundle = bundle.replace("</script", "<\\/script")     # would end the inline script early
    return ("<!DOCTYPE html>\n<html>\n<head>\n{refresh_tag}\n<meta charset=\"utf-8\">\n<title>DVC Plot</title>\n"
            f"<script type=\"text/javascript\">\n{bundle}\n</script>\n"
            "<style>\ntable { border-spacing: 15px; }\n</style>\n</head>\n<body>\n{plot_divs}\n</body>\n</html>\n")


def install(project: Path) -> Path | None:
    """The template's path; None (nothing done) outside a DVC project, such as an exported copy."""
    import vl_convert

    dvc_dir = project / ".dvc"
    if not dvc_dir.is_dir():
        return None
    out = dvc_dir / TEMPLATE
    write_text(out, page(vl_convert.javascript_bundle(vl_version=VEGA_LITE)))
    dvc = Path(sys.executable).with_name("dvc")
    done = subprocess.run([str(dvc) if dvc.exists() else "dvc", "config", "--local", "plots.html_template", TEMPLATE],
                          cwd=project, capture_output=True, text=True)
    if done.returncode:
        raise SystemExit(f"dvc config --local plots.html_template {TEMPLATE}: {done.stderr.strip()}")
    return out


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--project", type=Path, default=Path("."), help="the DVC project (default: here)")
    project = ap.parse_args(argv).project
    out = install(project)
    print(f"{out}: dvc plots draws offline (vega, vega-lite {VEGA_LITE} and vega-embed inline)" if out else
          f"{project.resolve()}: no .dvc/ here, so no DVC plots page to set up")


if __name__ == "__main__":
    main()
