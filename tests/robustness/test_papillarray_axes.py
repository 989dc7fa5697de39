"""A PapillArray with a reversed axis: its lifts are refused naming the sensor and the sign (not
"never leaves the table", never a dataset of negative loads); params.yaml papillarray_axes maps
it back (volume/dataset.py, docs/robustness.md)."""

from __future__ import annotations

import copy

import numpy as np
import pandas as pd
import pytest

from tactilepipe.core.errors import ConfigError, InputError
from tactilepipe.studies import load_params      # as the workflow validates: every study's checks
from tactilepipe.volume.dataset import build_dataset

from support.project import REPO


def reversed_shard(src, dst, sensors, axis="gfy"):
    df = pd.read_parquet(src)
    rows = df["sensor"].isin(sensors)
    df.loc[rows, axis] = -df.loc[rows, axis]
    df.to_parquet(dst)
    return dst


def lifts_of(shard, volume):
    return pd.DataFrame([{"lift": "s/x", "session": "s", "volume_ml": volume, "set": "main", "shard": str(shard)}])


@pytest.mark.parametrize("method", ["auto", "force"])
@pytest.mark.parametrize("sensors, named", [([1], r"sensor 1 \(Fy -"), ([0, 1], r"sensor 0 \(Fy -.* and sensor 1 \(Fy -")])
def test_a_reversed_y_axis_is_named(sim_lifts, smoke_params, tmp_path, method, sensors, named):
    item = sim_lifts[1]
    shard = reversed_shard(item["shard"], tmp_path / "rev.parquet", sensors)
    seg = {**smoke_params["segment"], "method": method}
    with pytest.raises(InputError, match=r"^" + str(shard) + r": Fy has the wrong sign while the container is "
                                         r"lifted on .*" + named + r".*papillarray_axes"):
        build_dataset(lifts_of(shard, item["lift"].volume_ml), seg, smoke_params["papillarray_axes"],
                      smoke_params["volume_checks"])


@pytest.mark.parametrize("method", ["auto", "force"])
def test_a_reversed_z_axis_is_named(sim_lifts, smoke_params, tmp_path, method):
    item = sim_lifts[1]
    shard = reversed_shard(item["shard"], tmp_path / "rev.parquet", [0], axis="gfz")
    seg = {**smoke_params["segment"], "method": method}
    with pytest.raises(InputError, match=r"^" + str(shard) + r": the grip force Fz has the wrong sign while the "
                                         r"container is lifted on sensor 0 \(Fz -[56]\.\d+ N\).*z: '-z'"):
        build_dataset(lifts_of(shard, item["lift"].volume_ml), seg, smoke_params["papillarray_axes"],
                      smoke_params["volume_checks"])


def test_the_axis_map_reads_a_reversed_sensor_right(sim_lifts, smoke_params, tmp_path):
    item = sim_lifts[1]
    lifts = lifts_of(item["shard"], item["lift"].volume_ml)
    good, _ = build_dataset(lifts, smoke_params["segment"], smoke_params["papillarray_axes"],
                            smoke_params["volume_checks"])
    shard = reversed_shard(item["shard"], tmp_path / "rev.parquet", [1])
    axes = copy.deepcopy(smoke_params["papillarray_axes"])
    axes["sensor_1"]["y"] = "-y"
    mapped, _ = build_dataset(lifts_of(shard, item["lift"].volume_ml), smoke_params["segment"], axes,
                              smoke_params["volume_checks"])
    np.testing.assert_allclose(mapped["fy1"], good["fy1"], rtol=1e-6)
    assert (mapped["fy1"] > 0).mean() > 0.95


def test_an_axis_map_that_is_not_a_permutation_is_refused(tmp_path):
    path = tmp_path / "params.yaml"
    path.write_text((REPO / "params.yaml").read_text().replace(
        'sensor_1: {x: "+x", y: "+y", z: "+z"}', 'sensor_1: {x: "+x", y: "+x", z: "+z"}'))
    with pytest.raises(ConfigError, match=r"papillarray_axes.sensor_1 must take each recorded axis x, y, z once"):
        load_params(path)
