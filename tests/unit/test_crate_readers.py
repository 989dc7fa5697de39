"""The crate's readers of what a build left: Snakemake's record of its jobs (read as Snakemake
writes it) and a build recorded before provenance.json named sessions by DVC's hash (a real
Snakemake build through the command line: tests/integration/test_crate.py)."""

from __future__ import annotations

import json
import os

from tactilepipe.cli.main import main
from tactilepipe.pipeline.crate import snakemake_times, span


def _snakemake_record_path(metadata_dir, output: str) -> str:
    """Where Snakemake's own file persistence keeps the record of ``output``."""
    from snakemake.persistence.file import FilePersistence
    keeper = object.__new__(FilePersistence)          # its path scheme only: no DAG, no locks
    keeper._max_len = None
    return keeper._record_path(str(metadata_dir), output)


def test_snakemakes_records_are_read_by_output_path_long_paths_too(tmp_path):
    metadata = tmp_path / ".snakemake" / "metadata"
    metadata.mkdir(parents=True)
    short = "results/b/drift/metrics.json"
    long = "results/b/tool_normal/" + "/".join(["a_folder_named_at_length" * 3] * 5) + "/eval.json"
    assert len(long) > 300                          # Snakemake splits its name over folders
    for output, (start, end) in ((short, (100.0, 160.5)), (long, (50.0, 70.0))):
        path = _snakemake_record_path(metadata, output)
        os.makedirs(os.path.dirname(path), exist_ok=True)
        with open(path, "w") as fh:
            json.dump({"rule": "r", "starttime": start, "endtime": end, "incomplete": False}, fh)
    assert any(p.name.startswith("@") for p in metadata.rglob("*")), "the long path's record is not split"
    (metadata / "not-a-record").write_text("{")      # a record being written: skipped
    times = snakemake_times(tmp_path)
    assert times == {short: (100.0, 160.5), long: (50.0, 70.0)}
    # a folder's span covers the files under it; a path with no record has none
    assert span(times, ["results/b/"]) == ("1970-01-01T00:00:50+00:00", "1970-01-01T00:02:40.500000+00:00")
    assert span(times, ["results/b/drift/"]) == ("1970-01-01T00:01:40+00:00", "1970-01-01T00:02:40.500000+00:00")
    assert span(times, ["results/other/"]) is None


def test_a_build_recorded_with_the_old_session_hash_gets_a_crate_without_dvc_md5_or_times(tmp_path, capsys):
    """provenance.json of older revisions: a sha256 of the project's own per session, which names no
    DVC object; no Snakemake record (the results were pulled): the crate says what it has."""
    from rocrate.rocrate import ROCrate
    (tmp_path / "Snakefile").write_text("rule all:\n    input: []\n")
    scene = tmp_path / "results" / "old" / "volume"
    scene.mkdir(parents=True)
    (scene / "metrics.json").write_text('{"r2": {"fz": {"mean": 0.9}}}\n')
    sha = "46ff453c25b546eac85e1814446402efcf414fc604879df81ebd283ee07dd5ce"
    (scene / "provenance.json").write_text(json.dumps({
        "sessions": {"raw/volume/sim-default": sha}, "git": {"commit": "e892075", "uncommitted_changes": False},
        "stages": {"volume-split": {"code_sha256": "1", "params": {"seed": 3, "folds": {"k": 5}}}},
        "environment": {"packages": {"numpy": "2.4.6"}, "python": "3.11.7", "machine": "x86_64", "cpu": {}}}))
    out = tmp_path / "crate"
    assert main(["provenance", "--crate", str(out), "--build", "old", "--repo", str(tmp_path)]) == 0
    assert "2 runs (0 with Snakemake's start and end times)" in capsys.readouterr().out
    crate = ROCrate(out)
    session = crate.get("#raw/volume/sim-default/")
    assert session.type == "Dataset"
    assert session["identifier"]["propertyID"] == "tactilepipe session sha256" and session["identifier"]["value"] == sha
    run = crate.get("#scene-volume")
    assert "startTime" not in run.properties() and "endTime" not in run.properties()
    assert crate.mainEntity["version"] == "e892075"
    given = {o["name"]: o["value"] for o in run["object"] if o.type == "PropertyValue"}
    assert given == {"volume-split: seed": 3, "volume-split: folds.k": 5}
    # an older build's one metrics file is among the scene's records, copied in
    assert "results/old/volume/metrics.json" in {f.id for f in run["result"]}
    assert (out / "results/old/volume/metrics.json").read_text() == '{"r2": {"fz": {"mean": 0.9}}}\n'
