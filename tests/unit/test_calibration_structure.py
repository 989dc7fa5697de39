"""nano17.cal against the Nano17's structure (tool/formats/calibration_structure.py, through
read_calibration): the simulator's matrices at every scale and ATI-layout matrices pass; a row's
largest cell x10 or /10 and a transposed matrix are refused, each with its cause named."""

from __future__ import annotations

import numpy as np
import pytest

from support.project import REPO
from tactilepipe.core.config import load_params
from tactilepipe.core.errors import InputError
from tactilepipe.tool.formats.calibration_structure import block_ratio, check_structure
from tactilepipe.tool.formats.native_layout import AXES, read_calibration, write_calibration
from tactilepipe.tool.sim.plan import calibration_matrix

SCALES = ("smoke", "default", "paper")
PARAMS = {scale: load_params(REPO / "params.yaml", {"scale": scale}) for scale in SCALES}
SEEDS = range(400)


def sim_matrices(seeds=SEEDS):
    for scale in SCALES:
        for seed in seeds:
            yield f"{scale}/seed {seed}", calibration_matrix({**PARAMS[scale], "seed": seed})


def ati_layout(rng: np.random.Generator, tool_dz_mm: float) -> np.ndarray:
    """A matrix in ATI's three-beam layout as its Nano17 files have it (N and N·mm per volt): Fx on
    gauges 4 and 6, Fy on 2 (twice) and 4, 6, Fz on 1, 3, 5, Tx on 3, 5, Ty on 1 (twice) and 3, 5,
    Tz on 2, 4, 6; cross-talk about 1.5% of each row's largest; a tool offset along z folds the
    force rows into the torque rows (ATI's UserAxis rows; its files' own offset is 6.1 mm)."""
    f, fz, t, tz = rng.uniform(3.0, 4.2), rng.uniform(3.5, 4.1), rng.uniform(18.0, 25.0), rng.uniform(13.0, 16.0)
    pattern = np.array([[0, 0, 0, f, 0, -f], [0, -f, 0, f / 2, 0, f / 2], [fz, 0, fz, 0, fz, 0],
                        [0, 0, t, 0, -t, 0], [-t, 0, t / 2, 0, t / 2, 0], [0, -tz, 0, -tz, 0, -tz]])
    pattern = pattern * (1 + 0.03 * rng.standard_normal((6, 6)))
    crosstalk = 0.015 * rng.standard_normal((6, 6)) * np.abs(pattern).max(axis=1)[:, None]
    matrix = np.where(pattern != 0, pattern, crosstalk)
    matrix[3] += tool_dz_mm * matrix[1]
    matrix[4] -= tool_dz_mm * matrix[0]
    return matrix


def ati_matrices(n=300):
    rng = np.random.default_rng(17)
    for k in range(n):
        dz = float(rng.choice([0.0, 2.0, 6.096]))
        yield f"ATI layout {k} (tool dz {dz:g} mm)", ati_layout(rng, dz)


def refusal(matrix: np.ndarray) -> str:
    with pytest.raises(InputError) as err:
        check_structure("nano17.cal", matrix)
    assert err.value.path == "nano17.cal"
    return str(err.value)


def test_the_simulators_matrices_at_every_scale_and_atis_layout_pass():
    for name, matrix in [*sim_matrices(), *ati_matrices()]:
        try:
            check_structure("nano17.cal", matrix)
        except InputError as exc:
            pytest.fail(f"{name}: {exc}")


@pytest.mark.parametrize("factor", [10.0, 0.1], ids=["x10", "div10"])
def test_a_rows_largest_cell_off_by_10x_is_named(factor):
    """Every row, in simulated and ATI-layout matrices: the cell that sets the row's scale (/10 only
    where it is the row's one large cell: in an ATI row another cell as large takes its place)."""
    cases = [*sim_matrices(range(30))] + ([*ati_matrices(30)] if factor > 1 else [])
    for name, clean in cases:
        for i, axis in enumerate(AXES):
            j = int(np.argmax(np.abs(clean[i])))
            matrix = clean.copy()
            matrix[i, j] *= factor
            message = refusal(matrix)
            assert f"cell {axis},g{j + 1} " in message, (name, message)
            assert ("~10x" if factor > 1 else "~1/10") in message, (name, message)
            assert "transposed" not in message, (name, message)


def test_a_transposed_matrix_is_named():
    for name, matrix in [*sim_matrices(range(100)), *ati_matrices(100)]:
        message = refusal(matrix.T.copy())
        assert message.startswith("nano17.cal: the matrix looks transposed: per unit of rated range its force rows"), \
            (name, message)


def test_the_block_ratio_is_apart_from_the_threshold_both_ways():
    """Valid matrices stay under half the threshold, transposed ones over twice it (the margin the
    threshold of 9 leaves: 2,000 simulated seeds reached 4.1 and 18.9)."""
    valid = [block_ratio(m) for _, m in [*sim_matrices(), *ati_matrices()]]
    transposed = [block_ratio(m.T) for _, m in [*sim_matrices(), *ati_matrices()]]
    assert max(valid) < 9 / 2 and min(transposed) > 9 * 2, (max(valid), min(transposed))


def test_read_calibration_refuses_a_cell_x10_naming_the_file_and_the_cell(tmp_path):
    matrix = calibration_matrix(PARAMS["default"])
    write_calibration(tmp_path / "nano17.cal", matrix)
    np.testing.assert_allclose(read_calibration(tmp_path / "nano17.cal"), matrix, rtol=1e-7)
    bad = matrix.copy()
    bad[2, 2] *= 10                                    # Fz's gauge: the labels of a press x10
    write_calibration(tmp_path / "nano17.cal", bad)
    with pytest.raises(InputError) as err:
        read_calibration(tmp_path / "nano17.cal")
    assert str(err.value).startswith(f"{tmp_path / 'nano17.cal'} [UserAxis Fz]: cell Fz,g3 ("), str(err.value)
    write_calibration(tmp_path / "nano17.cal", matrix.T)
    with pytest.raises(InputError, match="the matrix looks transposed"):
        read_calibration(tmp_path / "nano17.cal")


def test_a_cross_talk_cell_x10_is_not_seen():
    """The known limit: a cell that neither sets its row's scale nor crosses the blocks passes."""
    matrix = calibration_matrix(PARAMS["default"])
    matrix[0, 1] *= 10
    check_structure("nano17.cal", matrix)
