"""The reproduction's search for a chaotic IC by the SALI (issue 34, item 3: the chart's ``chaos_test``, same names
and default): the IC the finite-time exponent picks, in a fraction of the periods, checked against 5,000-period
exponents."""

from __future__ import annotations

import json

import pytest

from explorer_core.analyses.lyapunov import lyapunov_spectrum
from explorer_core.scenes import get_scene
from explorer_core.solve.numerics import Numerics
from explorer_core.studies import reproduce as rp
from explorer_core.system.params import ParameterError


@pytest.mark.parametrize("sid", ["fig4A", "fig4B", "fig8B"])
def test_the_sali_finds_the_ic_the_exponent_finds_and_it_is_chaotic_over_5000_periods(sid: str) -> None:
    sc = get_scene(sid)
    by_sali = rp._find_attractor_ic(sc, 8, 300, None, "sali")  # the tiny size's search
    assert by_sali is not None and by_sali == rp._find_attractor_ic(sc, 8, 300, None, "lyapunov")
    long = lyapunov_spectrum(
        sc.params, [by_sali], 5000, transient=sc.transient, numerics=Numerics(rtol=1e-10, atol=1e-10)
    )
    assert long.ok[0] and long.exponents[0, 0] > rp.CHAOS_THRESHOLD, long.exponents


def test_when_the_sali_finds_none_the_exponent_decides(monkeypatch) -> None:
    # 12 periods align no pair of vectors on Fig. 4A's attractor (its exponent is 0.016 per unit time): the exponent
    # over 300 periods then picks, as chaos_test="lyapunov" does
    monkeypatch.setattr(rp, "SALI_SEARCH_PERIODS", 12)
    sc = get_scene("fig4A")
    ics = sc.initial_conditions()[:8]
    short = rp.sali(sc.params, ics, 12, transient=sc.transient, numerics=Numerics(rtol=1e-9, atol=1e-9))
    assert not (short.verdict == rp.ALIGNED_CHAOS).any()  # so the fallback is what picks
    picked = rp._find_attractor_ic(sc, 8, 300, None, "sali")
    assert picked is not None and picked == rp._find_attractor_ic(sc, 8, 300, None, "lyapunov")


def test_the_chaos_test_is_named_when_bad_and_recorded_in_the_json() -> None:
    with pytest.raises(ParameterError, match="chaos_test"):
        rp.reproduce("tiny", stages=("lyapunov",), chaos_test="birkhoff")
    rep = rp.Reproduction(rp.SIZES["tiny"], "lyapunov")
    assert json.loads(json.dumps(rep.summary()))["chaos_test"] == "lyapunov"
    assert rp.Reproduction(rp.SIZES["tiny"]).chaos_test == "sali"


def test_the_command_line_passes_its_chaos_test_and_refuses_a_bad_one(monkeypatch, tmp_path, capsys) -> None:
    from explorer_core import cli

    asked: list[dict] = []

    class Asked(Exception):
        pass

    def fake(size, **kw):
        asked.append(kw)
        raise Asked  # what reproduce received is all this test needs

    monkeypatch.setattr(rp, "reproduce", fake)
    base = ["reproduce", "--out", str(tmp_path / "r"), "--size", "tiny", "--stages", "lyapunov", "--quiet"]
    cli.main([*base, "--chaos-test", "lyapunov"])
    cli.main(base)
    assert asked[0]["chaos_test"] == "lyapunov" and "chaos_test" not in asked[1]  # the default is reproduce's
    monkeypatch.undo()
    assert cli.main([*base, "--chaos-test", "bogus"]) == 2
    assert "chaos_test must be one of sali, lyapunov, got 'bogus'" in capsys.readouterr().err
