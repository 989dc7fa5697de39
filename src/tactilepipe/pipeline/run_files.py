"""A run's files as `tactilepipe diff` reads them (pipeline/diff.py): which file holds a scene's
scores at a revision, and the layouts earlier revisions wrote read in today's, so that a diff
across a change of layout compares the same numbers under the same names (the committed results
of every earlier commit stay readable).

A scene's numbers are in its ``scores.json``; its ``metrics/`` holds their headline only (DVC's
metrics, a row per model: core/metric_rows.py). Revisions from before scores.json kept everything
in ``metrics.json``, a tool scene's with each model's top-level ``mae``, ``rmse`` and ``r2`` the
first split's values (``current_layout``).
"""

from __future__ import annotations

import json

from tactilepipe.core.errors import InputError
from tactilepipe.pipeline.layout import results_root
from tactilepipe.pipeline.scenes import SCENES as SCENE_TABLE
from tactilepipe.pipeline.scenes import contract


def read_run(rev: str | None, repo: str = ".", scenes=tuple(SCENE_TABLE), build: str = "default") -> dict[str, dict | None]:
    """Each scene's numbers (its ``scores.json``, else, in earlier revisions, its ``metrics.json``) and
    ``provenance.json`` of ``build`` (results/<build>/) at ``rev`` (None: the workspace), as
    {"metrics", "provenance"}; a scene the run does not have is None. Revisions from before
    builds had folders kept the default scale's results in results/<scene>/: the default build
    is read there when its folder is absent, so a diff across that move still compares."""
    import dvc.api
    from dvc.exceptions import DvcException, PathMissingError
    roots = [results_root(build)] + (["results"] if build == "default" else [])
    out = {}
    for scene in scenes:
        for root in roots:
            files = {}
            for name in ("scores", "metrics", "provenance"):
                path = f"{root}/{scene}/{name}.json"
                try:
                    files[name] = json.loads(dvc.api.read(path, repo=repo, rev=rev))
                except (FileNotFoundError, PathMissingError):
                    files[name] = None
                except (DvcException, json.JSONDecodeError) as exc:
                    raise InputError(f"{path} at {rev or 'the workspace'}", str(exc).splitlines()[0]) from None
            if files["scores"] is not None:                # every number; metrics/ their headline
                files["metrics"] = files["scores"]
            del files["scores"]
            if files["metrics"] is not None:
                break
        out[scene] = files if files["metrics"] is not None else None
    return out


def current_layout(scene: str, metrics: dict) -> dict:
    """A scene's scores in today's layout: its study reads earlier revisions' layouts (a tool
    scene's first-split scores before scores.json: tool/scores_layout.py); today's as it is."""
    return contract(scene).scores.current_layout(metrics)
