"""The chart's early chaos test (issue 34, item 3): the SALI (the default) and the Lyapunov bound give the same regimes
off the boundaries between regimes, and the SALI spends fewer periods on chaotic members."""

from __future__ import annotations

import json

import numpy as np
import pytest

from explorer_core.analyses import regimes
from explorer_core.analyses.regimes import CHAOTIC, TileResult, chart_spec, compute_tile, plan_tiles
from explorer_core.scenes import get_scene
from explorer_core.system.params import ParameterError

FIG11 = get_scene("fig11").params
ICS = [(-0.09, -2.0), (-0.5, -1.0)]


def _chart(chaos_test: str, grid: tuple[int, int]) -> dict[str, np.ndarray]:
    """Fig. 11's window (as `benchmarks/whole_process_targets.sh`) with both ICs, tile by tile: ``regime``, ``period``,
    ``status``, ``lyap``, ``periods_run`` ``[j, i, ic]``."""
    spec = chart_spec(FIG11, "alpha", (-0.6, -0.4), "I11", (1.0, 2.0), grid, ics=ICS, chaos_test=chaos_test)
    ny, nx = spec.shape
    out = {k: np.zeros((ny, nx, len(ICS))) for k in ("regime", "period", "status", "lyap", "periods_run")}
    for tile in plan_tiles(spec.shape, 4, 64):
        res: TileResult = compute_tile(spec, tile)
        for k, arr in out.items():
            arr[res.jj, res.ii] = getattr(res, k)
    out["threshold"] = np.array(spec.lyap_threshold)
    return out


def off_boundaries(code: np.ndarray) -> np.ndarray:
    """``[j, i, ic]``: True where the pixel has 8 neighbours (not on the chart's edge) and all 8 have its code
    (regime, and period for a cycle) for that initial condition."""
    ny, nx, n = code.shape
    out = np.zeros(code.shape, dtype=bool)
    inner = code[1:-1, 1:-1]
    same = np.ones(inner.shape, dtype=bool)
    for dj in (-1, 0, 1):
        for di in (-1, 0, 1):
            same &= code[1 + dj : ny - 1 + dj, 1 + di : nx - 1 + di] == inner
    out[1:-1, 1:-1] = same
    return out


def _code(c: dict[str, np.ndarray]) -> np.ndarray:
    return np.where(c["regime"] == regimes.PERIODIC, c["period"], -c["regime"])


def test_off_boundaries_the_sali_chart_is_the_lyapunov_chart_in_fewer_periods() -> None:
    """Metamorphic: every pixel-IC whose 8 neighbours share its regime (and period) in the chart of the Lyapunov test
    (the reference, as ``benchmarks/chart_speed.py`` judges early stops) has the same regime, period and status with
    the SALI; the members that differ are chaotic by the SALI (a chaotic transient the whole run saw settle or escape).
    Chaotic members cost fewer periods with the SALI."""
    lyap, sali = _chart("lyapunov", (24, 24)), _chart("sali", (24, 24))
    a, b = _code(lyap), _code(sali)
    inside = off_boundaries(a)
    assert inside.sum() >= 400 and (inside & (lyap["regime"] == CHAOTIC)).sum() >= 30
    for k in ("regime", "period", "status"):
        assert np.array_equal(lyap[k][inside], sali[k][inside]), k
    differ = a != b
    assert differ.sum() <= 0.02 * a.size
    assert np.all(sali["regime"][differ] == CHAOTIC)
    # A chaotic member's exponent, shown, is chaos by the threshold with either test.
    for c in (lyap, sali):
        assert np.all(c["lyap"][c["regime"] == CHAOTIC] > c["threshold"])
    both = (lyap["regime"] == CHAOTIC) & (sali["regime"] == CHAOTIC)
    ran_l, ran_s = lyap["periods_run"][both].sum(), sali["periods_run"][both].sum()
    assert ran_s < 0.85 * ran_l, (ran_s, ran_l)
    # Every other member ran exactly as before (the SALI is tried only on members that chaos may stop).
    regular = (lyap["regime"] != CHAOTIC) & (sali["regime"] != CHAOTIC)
    assert np.array_equal(lyap["lyap"][regular], sali["lyap"][regular])


def test_off_boundaries_marks_pixels_inside_regions() -> None:
    code = np.zeros((5, 6, 1), dtype=np.int64)
    code[2, 3, 0] = 1
    inside = off_boundaries(code)[..., 0]
    # The edges never; the odd pixel and its 8 neighbours not; the rest of the inner 3 x 4 block: (1, 1), (2, 1), (3, 1)
    assert inside.sum() == 3 and inside[1, 1] and inside[3, 1] and not inside[2, 3] and not inside[1, 4]


def test_the_chaos_test_is_an_option_of_the_spec_and_the_command(tmp_path) -> None:
    from tests.clirun import run_cli

    spec = chart_spec(FIG11, "alpha", (-0.6, -0.4), "I11", (1.0, 2.0), (2, 2))
    assert spec.chaos_test == "sali" and spec.as_dict()["chaos_test"] == "sali"
    with pytest.raises(ParameterError, match="chaos_test"):
        chart_spec(FIG11, "alpha", (-0.6, -0.4), "I11", (1.0, 2.0), (2, 2), chaos_test="birkhoff")
    out = tmp_path / "c.json"
    code, _, err = run_cli("chart", "--scene", "fig11", "--x-param", "alpha", "--x-range", "-0.6,-0.4", "--y-param",
                           "I11", "--y-range", "1,2", "--grid", "2,2", "--transient", "10", "--periods", "20",
                           "--p-max", "4", "--chaos-test", "lyapunov", "--out", str(out))  # fmt: skip
    assert code == 0, err
    assert json.loads(out.read_text())["chaos_test"] == "lyapunov"
