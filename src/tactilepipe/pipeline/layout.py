"""Where a build keeps its results: ``results/<build>/`` (params.yaml ``build``, by default the
scale's name), so that each scale, or two named builds of one scale, never share a file.

Under a build's folder: each scene's results (``<scene>/``), the tool scenes' shared shards and
clock figures (``tool/``), the parameter stamps (``params/<stage>.json``) and the logs (``logs/``).
Raw recordings are not per build: they live in raw/, a simulated session named by its scale.
"""

from __future__ import annotations

RESULTS = "results"


def results_root(build: str) -> str:
    """The folder of a build's results, relative to the project (``results/<build>``)."""
    if not build or "/" in build or build in (".", ".."):
        raise ValueError(f"a build is one folder name under {RESULTS}/, not {build!r}")
    return f"{RESULTS}/{build}"
