"""provenance.json of a scene, written by its report stage (imported there only, so the other
stages' code does not include the provenance writer)."""

from __future__ import annotations

from pathlib import Path

from tactilepipe.cli.common import param_overrides


def write_scene_provenance(args, out_dir: Path) -> None:
    """provenance.json beside a scene's metrics: the stages that made it (their code and the
    parameter values each declares), its input sessions, packages, machine and commit. Under the
    workflow the values are those of each stage's stamp, beside the report's own (the report
    rule's inputs); by hand, params.yaml's."""
    from tactilepipe.core.config import declared, load_params
    from tactilepipe.pipeline import codedeps
    from tactilepipe.pipeline.provenance import write_provenance
    from tactilepipe.pipeline.stamps import stamp_values
    if args.stamp:
        stamps = Path(args.stamp).parent
        values = {s: stamp_values(str(stamps / f"{s}.json"), s) for s in args.provenance_stages}
    else:
        resolved = load_params(args.params, param_overrides(args))
        values = {s: resolved for s in args.provenance_stages}
    given = {s: declared(values[s], codedeps.stage_param_keys(s), s) for s in args.provenance_stages}
    write_provenance(out_dir / "provenance.json", given, args.sessions)
