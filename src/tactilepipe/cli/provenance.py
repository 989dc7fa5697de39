"""provenance.json of a scene, written by its report stage (imported there only, so the other
stages' code does not include the provenance writer)."""

from __future__ import annotations

from pathlib import Path

from tactilepipe.cli.common import param_overrides


def write_scene_provenance(args, out_dir: Path) -> None:
    """provenance.json beside a scene's metrics: the stages that made it (their code and the
    parameter values each declares), its input sessions, packages, machine and commit."""
    from tactilepipe.core.config import load_params
    from tactilepipe.pipeline.provenance import write_provenance
    write_provenance(out_dir / "provenance.json", args.provenance_stages, load_params(args.params, param_overrides(args)),
                     args.sessions)
