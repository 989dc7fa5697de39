"""Study 000 on its own data (studies/000/, docs/reproduce_study_000.md), against stand-ins served
on 127.0.0.1: an archive in the public layout (simulated trials, JPEG frames in the public naming)
and a random-weights checkpoint under the public code's key names. Import (`dvc import-url`),
unpack, ingest, smoke-scale training and the published-weights check all run through `dvc repro`;
plus the archive checks (size, sha256, zip-slip, not a zip) on their own."""

from __future__ import annotations

import csv
import functools
import hashlib
import http.server
import json
import shutil
import threading
import zipfile
from pathlib import Path

import pytest
import torch
import yaml

from tactilepipe.core.config import load_params
from tactilepipe.core.errors import InputError
from tactilepipe.tool.formats import public_archive as pa
from tactilepipe.tool.formats.trials import list_trials

from support.project import BIN, REPO, SMOKE, copy_project, dvc, git, results, run

STUDY = "studies/000"


def _zip_public(src_root: Path, kind_dir: str, archive: Path, wrap: bool = True) -> None:
    with zipfile.ZipFile(archive, "w", zipfile.ZIP_STORED) as zf:
        for f in sorted((src_root / kind_dir).rglob("*")):
            if f.is_file():
                rel = f.relative_to(src_root if wrap else src_root / kind_dir)
                zf.write(f, str(rel))


def _digest(path: Path) -> dict:
    return {"size": path.stat().st_size, "sha256": hashlib.sha256(path.read_bytes()).hexdigest()}


@pytest.fixture(scope="module")
def stand_ins(tmp_path_factory) -> dict:
    """Served files: data_normal.zip (simulated smoke trials) and best_model_normal.pth (random
    weights of the full model, depth 18, under the public key names); the simulator's trials.csv."""
    from support.public_formats import to_public
    from tactilepipe.tool.model.network import build_model, PAPER_WIDTH
    from support.tool_sim import simulate_public_session
    root = tmp_path_factory.mktemp("study000_sim")
    params = load_params(REPO / "params.yaml", {"scale": "smoke"})
    names = simulate_public_session(root / "sim", params)
    served = root / "served"
    served.mkdir()
    _zip_public(root / "sim", "data_normal", served / "data_normal.zip")
    torch.manual_seed(0)
    torch.save(to_public(build_model("full", 18, 32, gam_channel_gate="none", width=PAPER_WIDTH).state_dict()),
               served / "best_model_normal.pth")
    rows = list(csv.DictReader((root / "sim" / "trials.csv").open()))
    normal = sorted(p.name for p in (root / "sim" / "data_normal").iterdir())
    return {"served": served, "rows": rows, "normal": normal, "names": names}


@pytest.fixture(scope="module")
def server(stand_ins):
    handler = functools.partial(http.server.SimpleHTTPRequestHandler, directory=str(stand_ins["served"]))
    handler.log_message = lambda *a, **k: None
    httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    thread = threading.Thread(target=httpd.serve_forever, daemon=True)
    thread.start()
    yield f"http://127.0.0.1:{httpd.server_address[1]}"
    httpd.shutdown()


@pytest.fixture(scope="module")
def project(tmp_path_factory, stand_ins, server) -> Path:
    """A git + DVC copy of the project at the smoke scale whose public_data points at the stand-ins."""
    wd = copy_project(tmp_path_factory.mktemp("study000"), scale="smoke")     # studies/ included
    for name in (".gitignore", ".dvcignore"):
        shutil.copy(REPO / name, wd / name)
    params = yaml.safe_load((wd / "params.yaml").read_text())
    for name in ("data_normal.zip", "best_model_normal.pth"):
        params["public_data"]["files"][name.split(".")[0]] = {"url": f"{server}/{name}",
                                                              **_digest(stand_ins["served"] / name)}
    (wd / "params.yaml").write_text(yaml.safe_dump(params, sort_keys=False))
    git(wd, "init", "-q")
    git(wd, "config", "user.email", "test@example.com")
    git(wd, "config", "user.name", "test")
    dvc(wd, "init", "-q")
    study = wd / STUDY
    (study / "raw/downloads").mkdir(parents=True)
    for name in ("data_normal.zip", "best_model_normal.pth"):
        dvc(study, "import-url", f"{server}/{name}", f"raw/downloads/{name}")
    yield wd
    shutil.rmtree(wd, ignore_errors=True)


@pytest.mark.extended
def test_import_unpack_ingest_train_and_published_check_run_through_dvc_repro(project, stand_ins):
    study = project / STUDY
    assert yaml.safe_load((study / "raw/downloads/data_normal.zip.dvc").read_text())["deps"][0]["path"].startswith(
        "http://127.0.0.1:")
    dvc(study, "repro", "unpack_normal")
    session = study / "raw/tool/public"
    assert sorted(p.name for p in (session / "data_normal").iterdir()) == stand_ins["normal"]
    first = session / "data_normal" / stand_ins["normal"][0]
    assert (first / "tactile1" / "tactile_frame_0000.jpg").read_bytes()[:2] == b"\xff\xd8"
    template = (session / "trials.csv").read_text().splitlines()
    assert template[0] == "trial,tool,orientation_deg,insertion_mm"
    assert template[1:] == [f"data_normal/{n},,," for n in stand_ins["normal"]]

    # until trials.csv is complete, the data stage stops before any job, naming the trials
    proc = dvc(study, "repro", "data", check=False)
    assert proc.returncode != 0
    out = proc.stdout + proc.stderr
    assert f"no tool for {len(stand_ins['normal'])} of {len(stand_ins['normal'])} public trials" in out, out[-2000:]
    assert f"data_normal/{stand_ins['normal'][0]}" in out
    assert not (results(study) / "tool/shards").exists()

    # the user completes it (kept as written on later unpacks)
    by_name = {r["trial"]: r for r in stand_ins["rows"]}
    (session / "trials.csv").write_text("trial,tool,orientation_deg,insertion_mm\n" + "".join(
        f"data_normal/{n},{by_name[n]['tool']},{by_name[n]['orientation_deg']},{by_name[n]['insertion_mm']}\n"
        for n in stand_ins["normal"]))
    dvc(study, "repro", "protocols")
    samples = results(study) / "tool_normal/data/samples.parquet"
    assert len(list((results(study) / "tool/shards/public").glob("*.parquet"))) == len(stand_ins["normal"])
    metrics = json.loads((results(study) / "study000/metrics.json").read_text())
    assert set(metrics) == {"public_frame", "trial", "paper"}
    assert metrics["paper"] == {"mae_n": 0.5964, "r2": 0.9743}
    frame_split = json.loads((results(study) / "tool_normal/splits/public_frame.json").read_text())
    assert frame_split["leaky"] and frame_split["name"] == "public_frame"
    import pandas as pd
    labels = pd.read_parquet(samples)["normal"]
    assert frame_split["label_stats"]["max"] == pytest.approx(labels.max())     # taken before the split
    for split in ("public_frame", "trial"):
        e = json.loads((results(study) / f"tool_normal/models/full_{split}/eval.json").read_text())
        assert e["split"] == split and metrics[split]["n"] == e["n"] == len(json.loads(
            (results(study) / f"tool_normal/splits/{split}.json").read_text())["test"])
    # tool-evaluate on our own checkpoint gives the training run's test metrics again
    ours = results(study) / "tool_normal/models/full_trial"
    run([str(BIN / "tactilepipe"), "tool-evaluate", "--params", "params.yaml", "--checkpoint", str(ours / "best.pt"),
         "--scene", "tool_normal", "--data-dir", f"{SMOKE}/tool_normal/data", "--split",
         f"{SMOKE}/tool_normal/splits/trial.json", "--out-dir", str(project / "again")], study)
    again, trained = (json.loads((d / "eval.json").read_text()) for d in (project / "again", ours))
    assert again["source"] == "tactilepipe" and not again["contaminated"]
    assert (again["n"], again["mae"], again["r2"]) == pytest.approx((trained["n"], trained["mae"], trained["r2"]),
                                                                    rel=1e-6)
    table = (results(study) / "study000/protocols.md").read_text()
    assert "0.5964" in table and "0.9743" in table and "leaky" in table

    dvc(study, "repro", "published")
    e = json.loads((results(study) / "study000/published_normal/eval.json").read_text())
    assert e["contaminated"] is True and e["source"] == "public" and e["frames"] == "all"
    assert e["n"] == len(labels) and e["gam_channel_gate"] == "none" and "contaminated" in e["note"]
    assert "contaminated" in (results(study) / "study000/published.md").read_text()
    # the default pipeline's outputs are untouched: nothing was written outside studies/000
    assert not (results(project) / "tool_normal").exists() and not (project / "raw/tool").exists()
    proc = dvc(study, "status", "protocols", "published")
    assert "changed" not in proc.stdout, proc.stdout
    # studies/000 is a DVC project of its own: the project's stages, status and pushes never see it
    assert "unpack_normal" not in dvc(project, "stage", "list").stdout


def test_a_wrong_checksum_is_refused_naming_the_file(project):
    study = project / STUDY
    params_path = project / "params.yaml"
    original = params_path.read_text()
    params = yaml.safe_load(original)
    params["public_data"]["files"]["data_normal"]["sha256"] = "0" * 64
    params_path.write_text(yaml.safe_dump(params, sort_keys=False))
    try:
        proc = dvc(study, "repro", "unpack_normal", check=False)
    finally:
        params_path.write_text(original)
    out = proc.stdout + proc.stderr
    assert proc.returncode != 0
    assert "raw/downloads/data_normal.zip: sha256" in out and "refused" in out, out[-2000:]


def test_the_study_dvc_yaml_is_generated_with_exact_code_deps():
    """studies/000/dvc.yaml lists the source files its stages run (no folder: byte-code caches
    written by any import would mark the stages changed and re-run a GPU training)."""
    proc = run([str(BIN / "python"), "workflow/scripts/dvc_yaml.py", "--check", "--study000"], REPO, check=False)
    assert proc.returncode == 0, proc.stdout[-3000:]
    stages = yaml.safe_load((REPO / STUDY / "dvc.yaml").read_text())["stages"]
    for stage in stages.values():
        assert "../../src/tactilepipe" not in stage["deps"]
        assert all(Path(REPO / STUDY / d).resolve().is_file() for d in stage["deps"] if d.endswith(".py"))
    assert "../../src/tactilepipe/tool/model/public_weights.py" in stages["published"]["deps"]
    assert "../../src/tactilepipe/tool/model/train.py" not in stages["unpack_normal"]["deps"]


# --- the archive checks on their own -----------------------------------------------------------

def _tiny_archive(path: Path, members: dict[str, bytes]) -> Path:
    with zipfile.ZipFile(path, "w") as zf:
        for name, data in members.items():
            zf.writestr(name, data)
    return path


def test_verify_names_the_file_on_size_or_checksum_mismatch(tmp_path):
    f = tmp_path / "data_normal.zip"
    f.write_bytes(b"abc")
    good = hashlib.sha256(b"abc").hexdigest()
    pa.verify(f, 3, good)
    with pytest.raises(InputError, match=r"data_normal.zip: size 3 bytes, expected 4"):
        pa.verify(f, 4, good)
    with pytest.raises(InputError, match=r"data_normal.zip: sha256 ba78.* differs"):
        pa.verify(f, 3, "1" * 64)
    with pytest.raises(InputError, match="missing"):
        pa.verify(tmp_path / "nope.zip", 3, good)


def test_unpack_finds_trials_at_any_depth_and_keeps_a_completed_trials_csv(tmp_path):
    a = _tiny_archive(tmp_path / "a.zip", {"t1/tactile1/tactile_frame_0000.jpg": b"x",
                                           "t1/force/force_data_0000.txt": b"1,968\n",
                                           "deep/er/t2/tactile2/tactile_frame_0000.jpg": b"y",
                                           "__MACOSX/t1/._x": b"", "README.txt": b"notes"})
    session = tmp_path / "s"
    assert pa.unpack(a, "data_normal", session) == ["t1", "t2"]
    assert (session / "data_normal/t2/tactile2/tactile_frame_0000.jpg").read_bytes() == b"y"
    assert pa.write_trials_template(session) == ["data_normal/t1", "data_normal/t2"]
    (session / "trials.csv").write_text("trial,tool,orientation_deg,insertion_mm\nt1,knife,5,10\n")
    assert pa.write_trials_template(session) == ["data_normal/t2"]            # t1 is listed by its short name
    assert (session / "trials.csv").read_text().splitlines()[1:] == ["t1,knife,5,10", "data_normal/t2,,,"]
    # unpacking again replaces the folder as a whole
    b = _tiny_archive(tmp_path / "b.zip", {"t3/force/force_data_0000.txt": b"1,968\n"})
    assert pa.unpack(b, "data_normal", session) == ["t3"]
    assert sorted(p.name for p in (session / "data_normal").iterdir()) == ["t3"]
    assert not [p for p in session.iterdir() if p.name.startswith(".")]          # no temporary folders left


@pytest.mark.parametrize("member", ["../evil/tactile1/x.jpg", "/abs/t/tactile1/x.jpg", "t/tactile1/../../../x"])
def test_unpack_refuses_members_escaping_the_session(tmp_path, member):
    a = _tiny_archive(tmp_path / "a.zip", {member: b"x"})
    with pytest.raises(InputError, match=r"a.zip: member .* outside the session folder"):
        pa.unpack(a, "data_normal", tmp_path / "s")
    assert not (tmp_path / "s" / "data_normal").exists() and not (tmp_path / "evil").exists()


def test_unpack_refuses_non_zip_and_empty_archives(tmp_path):
    bad = tmp_path / "data_normal.zip"
    bad.write_bytes(b"PK but not really a zip")
    with pytest.raises(InputError, match="data_normal.zip: not a zip archive"):
        pa.unpack(bad, "data_normal", tmp_path / "s")
    empty = _tiny_archive(tmp_path / "e.zip", {"notes.txt": b"x"})
    with pytest.raises(InputError, match="e.zip: no trials found"):
        pa.unpack(empty, "data_normal", tmp_path / "s")


def test_a_template_row_names_the_trial_when_the_session_is_listed(tmp_path):
    a = _tiny_archive(tmp_path / "a.zip", {f"t{i}/tactile1/tactile_frame_0000.jpg": b"x" for i in range(3)})
    session = tmp_path / "public"
    pa.unpack(a, "data_normal", session)
    pa.write_trials_template(session)
    text = (session / "trials.csv").read_text().replace("data_normal/t1,,,", "data_normal/t1,knife,5,10")
    (session / "trials.csv").write_text(text)
    with pytest.raises(InputError, match=r"trials.csv: no tool for 2 of 3 public trials: data_normal/t0, "
                                         r"data_normal/t2; complete their rows"):
        list_trials(session)


def test_a_public_trial_keeps_frame_0_as_its_reference_when_its_label_is_dropped(tmp_path):
    """As the public code: frame 0 is the zero-force reference even when it reads below 0 N and
    is no sample; ingest stores it, the dataset uses it."""
    import numpy as np

    from tactilepipe.tool.data.dataset import build_tool_dataset
    from tactilepipe.tool.formats.trials import open_trial
    from tactilepipe.tool.data.ingest import ingest_trial, preprocess
    from support.public_formats import write_public_trial
    rng = np.random.default_rng(1)
    left = [rng.integers(60, 200, (48, 64, 3), dtype=np.uint8) for _ in range(6)]
    right = [rng.integers(60, 200, (48, 64, 3), dtype=np.uint8) for _ in range(6)]
    trial = write_public_trial(tmp_path, "t0", left, right, [-0.4, 1.0, 2.0, 3.0, 2.0, 1.0], "normal")
    (tmp_path / "trials.csv").write_text("trial,tool,orientation_deg,insertion_mm\nt0,knife,5,10\n")
    p = load_params(REPO / "params.yaml", {"scale": "smoke"})
    raw = open_trial(trial, "public")
    assert len(raw.frames["digit_left"]) == 5 and raw.drops["public: below 0 N"] == 1
    ingest_trial(raw, tmp_path / "t0.parquet", 32, p["tool_ingest"])
    build_tool_dataset([tmp_path / "t0.parquet"], "normal", tmp_path / "data", p["tool_sync"])
    refs = np.load(tmp_path / "data" / "references.npy")
    frame0 = [preprocess(np.asarray(__import__("cv2").imread(str(trial / s / "tactile_frame_0000.jpg"))), 32)
              for s in ("tactile1", "tactile2")]
    assert np.array_equal(refs[0, 0], frame0[0]) and np.array_equal(refs[0, 1], frame0[1])
    frames = np.load(tmp_path / "data" / "frames.npy")
    assert len(frames) == 5 and not np.array_equal(frames[0, 0], refs[0, 0])
