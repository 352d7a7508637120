"""The reproduction pipeline at CI size: every stage runs, the table has every number, figures are written."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from explorer_core.studies.reproduce import SIZES, reproduce
from explorer_core.system.params import ParameterError


def test_bad_size_and_stage_named() -> None:
    with pytest.raises(ParameterError, match="size must be one of"):
        reproduce("huge")
    with pytest.raises(ParameterError, match="unknown stages"):
        reproduce("tiny", stages=("sections", "poetry"))


def test_sizes_grow() -> None:
    tiny, quick, full = SIZES["tiny"], SIZES["quick"], SIZES["full"]
    assert tiny.lyap_periods < quick.lyap_periods < full.lyap_periods
    assert np.prod(tiny.chart_grid) < np.prod(quick.chart_grid) < np.prod(full.chart_grid)


def test_lyapunov_stage_alone_gives_consistent_rows() -> None:
    rep = reproduce("tiny", stages=("lyapunov",))
    rows = {(r.figure, r.quantity): r for r in rep.rows}
    for fig in ("Fig. 4A", "Fig. 4B", "Fig. 8B"):
        assert (fig, "Lambda_1") in rows and (fig, "D = 1 + L1/|L2|") in rows
    l1 = float(rows[("Fig. 8B", "Lambda_1")].ours)
    l2 = float(rows[("Fig. 8B", "Lambda_2")].ours)
    assert l1 > 0 > l2  # chaotic, dissipative: whatever the size
    assert float(rows[("Fig. 8B", "D = 1 + L1/|L2|")].ours) == pytest.approx(1 + l1 / abs(l2), rel=1e-3)
    assert set(rep.timings) == {"lyapunov"} and rep.completed


@pytest.mark.slow
def test_cli_reproduce_tiny_writes_every_figure_and_the_table(tmp_path, capsys) -> None:
    from explorer_core.cli import main

    out = tmp_path / "rep"
    assert main(["reproduce", "--out", str(out), "--size", "tiny", "--json", "--quiet"]) == 0
    s = json.loads(capsys.readouterr().out)
    names = {p.rsplit("/", 1)[-1] for p in s["figures"]}
    assert {f"fig{i}.png" for i in range(1, 12)} <= names and "lyapunov_convergence.png" in names
    for p in s["figures"]:
        with open(p, "rb") as fh:
            assert fh.read(8) == b"\x89PNG\r\n\x1a\n"
    rows = list(csv.reader((out / "table.csv").open()))
    assert rows[0] == ["figure", "quantity", "paper", "ours", "uncertainty", "paper_text", "ours_text", "settings",
                       "note"]  # fmt: skip
    # Every stage's rows read back as numbers (issue 35: "+-" text and commas in quoted fields did not).
    t = np.genfromtxt(out / "table.csv", delimiter=",", names=True, dtype=None, encoding="utf-8")
    assert t.shape == (len(rows) - 1,) and all(t[n].dtype.kind == "f" for n in ("paper", "ours", "uncertainty"))
    figs = {r[0] for r in rows[1:]}
    assert {"Fig. 3", "Fig. 4A", "Fig. 4B", "Fig. 6A", "Fig. 6B", "Fig. 8B", "Fig. 9", "Fig. 10", "Fig. 11"} <= figs
    md = (out / "table.md").read_text()
    assert md.startswith("| figure | quantity | paper | ours |") and "L1/\\|L2\\|" in md
    assert set(s["timings_s"]) == {"sections", "lyapunov", "drift", "bifurcation", "chart"}
    assert json.loads((out / "reproduce.json").read_text())["completed"] is True
