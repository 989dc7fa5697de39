"""Helpers shared by several test modules (a test module never imports another one).

project      the repository (REPO), the venv's bin (BIN, ENV), project copies and the command
             lines run in them: run, snakemake, dvc, git, copy_project
dvc_graph    dvc.yaml read as {stage: cmd, deps, outs} (dvc_stages) and path coverage (covers)
sessions     synthetic tool-rig recordings (native and public layouts, ROS bags) and the ingest
             settings the reader tests use
bags         hand-made ROS1 bags written with rosbags directly, and a synthetic PapillArray stream
volume_data  samples that follow the volume baseline formula exactly, with their folds
tool_data    a tiny tool-force dataset in the dataset stage's format, its split, a quick TrainConfig

`pythonpath = ["tests"]` in pyproject.toml puts tests/ on sys.path: `from support.project import REPO`.
"""
