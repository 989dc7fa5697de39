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
    from tactilepipe.pipeline.stamps import TRAIN_STAGE, run_values, stamp_values
    if args.stamp:
        # beside the report's own stamp (results/<build>/params/), but where the workflow names one
        # elsewhere: a simulator's is its scale's, shared by every build of that scale
        stamps = Path(args.stamp).parent
        elsewhere = {Path(p).stem: Path(p) for p in getattr(args, "provenance_stamps", None) or []}
        values = {s: _train_values(stamps, getattr(args, "runs", None) or []) if s == TRAIN_STAGE
                  else stamp_values(str(elsewhere.get(s, stamps / f"{s}.json")), s)
                  for s in args.provenance_stages}
    else:
        resolved = load_params(args.params, param_overrides(args))
        values = {s: run_values(resolved, codedeps.stage_param_keys(s), codedeps.stage_graph_keys(s))
                  if s == TRAIN_STAGE else resolved for s in args.provenance_stages}
    given = {s: declared(values[s], codedeps.stage_param_keys(s), s) for s in args.provenance_stages}
    write_provenance(out_dir / "provenance.json", given, args.sessions)


def _train_values(stamps: Path, runs: list[str]) -> dict:
    """The training stage's values: its declared keys, the same in the stamp of every run of the
    scene (results/<build>/params/tool-train/<run>.json); each run's own definition is in its stamp."""
    from tactilepipe.core.errors import InputError
    from tactilepipe.pipeline import codedeps
    from tactilepipe.pipeline.stamps import TRAIN_STAGE, stamp_values
    keys = codedeps.stage_param_keys(TRAIN_STAGE)
    first = None
    for run in runs:
        path = stamps / TRAIN_STAGE / f"{run}.json"
        given = {k: v for k, v in stamp_values(path, TRAIN_STAGE).items() if k != "run"}
        if first is not None and given != first[1]:
            raise InputError(path, f"its {TRAIN_STAGE} settings differ from those of run {first[0]}'s stamp: the runs "
                                   f"of one scene are trained with one set ({', '.join(keys)})")
        first = first or (run, given)
    if first is None:
        raise InputError(stamps / TRAIN_STAGE, "no run given (--runs) whose stamp records the training settings")
    return first[1]
