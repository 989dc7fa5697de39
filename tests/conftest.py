"""Shared fixtures of the volume-scene tests: smoke parameters, a few simulated lifts (bags and
shards, written once per session), and a plain rosbags writer for hand-made bad recordings.
Shared plain helpers (not fixtures) are in tests/support/."""

from __future__ import annotations

# A test process computes as a stage process does: NumPy and OpenCV capped at AVX2 before either
# loads (core/vector_dispatch.py; the command line run in-process by a test would refuse otherwise)
from tactilepipe.core import vector_dispatch
vector_dispatch.pin()

import os  # noqa: E402
from pathlib import Path

import pytest

from tactilepipe.core.config import load_params
from tactilepipe.papillarray.shards import ingest_bag
from tactilepipe.volume import simulate as vsim

from support import bags
from support.project import REPO
from support.tool_data import TORCH_THREADS

PARAMS_PATH = REPO / "params.yaml"


# The modules whose tests read the shared smoke build (tests/integration/conftest.py).
SMOKE_BUILD_MODULES = {"tests/integration/test_cluster.py", "tests/integration/test_workflow.py",
                       "tests/integration/test_portability.py", "tests/integration/test_read_audit.py",
                       "tests/integration/test_report.py", "tests/integration/test_content_change.py"}
SMOKE_BUILD_UNIT = "the smoke build"
# The two longest units, handed out first so that neither waits behind the short ones: the DVC
# workflow (its own smoke-scale project, then a chain of `dvc repro` runs), and the smoke build
# with its readers (with the SLURM test on, the cluster run too).
FIRST_UNITS = ["tests/integration/test_dvc_workflow.py", SMOKE_BUILD_UNIT]


def work_unit(nodeid: str) -> str:
    """What `make test` hands a worker whole: a module, or every module that reads the smoke build.
    Each worker builds the session and module fixtures of the tests it gets, so the build and each
    module's fixtures are made once."""
    module = nodeid.split("::")[0]
    return SMOKE_BUILD_UNIT if module in SMOKE_BUILD_MODULES else module


def pytest_xdist_make_scheduler(config, log):
    """`make test` runs the suite on two pytest-xdist workers, which get whole work units, in
    collection order (pytest_collection_modifyitems puts FIRST_UNITS first; xdist's default would
    hand out the units with the most tests first)."""
    from xdist.scheduler import LoadScopeScheduling

    config.option.loadscopereorder = False

    class ByWorkUnit(LoadScopeScheduling):
        def _split_scope(self, nodeid: str) -> str:
            return work_unit(nodeid)

    return ByWorkUnit(config, log)


def pytest_configure(config):
    if os.environ.get("PYTEST_XDIST_WORKER"):          # in-process torch work: one thread per worker
        import torch
        torch.set_num_threads(TORCH_THREADS)


def pytest_collection_modifyitems(items):
    # the scheduler sees only test ids: a module that reads the smoke build must be listed
    readers = {item.nodeid.split("::")[0] for item in items if "smoke_build" in getattr(item, "fixturenames", ())}
    if readers - SMOKE_BUILD_MODULES:
        raise pytest.UsageError(f"{', '.join(sorted(readers - SMOKE_BUILD_MODULES))} read the smoke build: "
                                "add them to SMOKE_BUILD_MODULES in tests/conftest.py")
    rank = {unit: i for i, unit in enumerate(FIRST_UNITS)}
    items.sort(key=lambda item: rank.get(work_unit(item.nodeid), len(FIRST_UNITS)))      # stable


# Lifts simulated once for the whole test session (smoke scale: 100 Hz, pose at 50 Hz).
SESSION_LIFTS = [(0.0, 0), (150.0, 1), (300.0, 2)]


@pytest.fixture(scope="session")
def params_path() -> Path:
    return PARAMS_PATH


@pytest.fixture(scope="session")
def smoke_params() -> dict:
    return load_params(PARAMS_PATH, {"scale": "smoke"})


@pytest.fixture
def vsim_params(smoke_params) -> dict:
    """A fresh copy of the smoke simulate_volume group (tests may modify it)."""
    return dict(smoke_params["simulate_volume"])


@pytest.fixture
def quiet_sim(vsim_params) -> dict:
    """The smoke rig with every measurement error and the grip repeatability switched off, so the
    physics can be checked exactly."""
    return {**vsim_params, "noise_std_n": 0.0, "bias_residual_std_n": 0.0, "drift_inf_n": 0.0,
            "drift_per_kg_n": 0.0, "grip_force_rel_std": 0.0}


@pytest.fixture(scope="session")
def sim_lifts(tmp_path_factory, smoke_params) -> list[dict]:
    """A few smoke-scale lifts: simulator output, bag and ingested shard of each."""
    root = tmp_path_factory.mktemp("volume_lifts")
    out = []
    for volume, index in SESSION_LIFTS:
        lift = vsim.Lift(f"v{int(volume):03d}_main_l{index:02d}", volume, "main", 0, index)
        bag, shard = root / "raw" / f"{lift.name}.bag", root / "shards" / f"{lift.name}.parquet"
        rec = vsim.write_lift_bag(bag, lift, smoke_params["simulate_volume"], smoke_params["seed"])
        ingest_bag(bag, shard)
        out.append({"lift": lift, "rec": rec, "bag": bag, "shard": shard})
    return out


@pytest.fixture(scope="session")
def good_bag(sim_lifts) -> Path:
    return sim_lifts[1]["bag"]


@pytest.fixture(scope="session")
def write_ros1_bag():
    return bags.write_ros1_bag


@pytest.fixture(scope="session")
def sensor_stream():
    return bags.sensor_stream
