"""The bilimovich command line: outputs in the documented shapes, one-line errors."""

from __future__ import annotations

import csv
import json
import subprocess
import sys

import numpy as np
import pytest
from clirun import run_cli


def test_section_csv_and_json(tmp_path) -> None:
    out = tmp_path / "s.csv"
    rc, stdout, err = run_cli(
        "section",
        "--scene",
        "fig1C",
        "--ic",
        "0.1,0.2",
        "--ic",
        "0.5,-0.3",
        "--periods",
        "7",
        "--transient",
        "2",
        "--out",
        str(out),
        "--json",
    )
    assert rc == 0, err
    summary = json.loads(stdout)
    assert [t["ic"] for t in summary["trajectories"]] == [[0.1, 0.2], [0.5, -0.3]]
    assert {t["status"] for t in summary["trajectories"]} == {"ok"}
    assert [t["points"] for t in summary["trajectories"]] == [7, 7]
    assert summary["elapsed_s"] >= 0
    rows = list(csv.reader(out.open()))
    assert rows[0] == ["traj", "k", "q", "r"]
    assert len(rows) == 15 and rows[1][:2] == ["0", "3"] and rows[-1][:2] == ["1", "9"]


def test_explicit_flags_override_scene() -> None:
    rc, stdout, _ = run_cli(
        "section",
        "--scene",
        "fig8B",
        "--alpha",
        "-0.4",
        "--I11",
        "1.2",
        "--omega",
        "2",
        "--random",
        "3",
        "--seed",
        "4",
        "--periods",
        "2",
        "--method",
        "rk4",
        "--json",
    )
    assert rc == 0
    s = json.loads(stdout)
    assert s["params"]["alpha"] == -0.4 and s["params"]["inertia"][0] == 1.2 and s["params"]["omega"] == 2.0
    assert s["params"]["inertia"][4] == 0.5  # from the scene
    assert s["numerics"]["method"] == "rk4"
    assert len(s["trajectories"]) == 3


def test_escaped_trajectory_reported() -> None:
    rc, stdout, _ = run_cli(
        "section",
        "--inertia",
        "1,2,4,0,0,0",
        "--alpha",
        "0.1",
        "--ic",
        "0,8",
        "--periods",
        "300",
        "--bound",
        "25",
        "--json",
    )
    assert rc == 0
    t = json.loads(stdout)["trajectories"][0]
    assert t["status"] == "escaped" and 0 < t["points"] < 300


def test_critical_json_shape() -> None:
    rc, stdout, _ = run_cli("critical", "--inertia", "1,2,4,0,0,0", "--alpha", "0.1", "--t", "0.3", "--json")
    assert rc == 0
    d = json.loads(stdout)
    assert d["t"] == 0.3
    pts = sorted((e["q"], e["r"]) for e in d["equilibria"])
    np.testing.assert_allclose(pts, sorted([(0.0, 0.0), (-0.1 / np.cos(0.3), np.sin(0.3) / 2)]), atol=1e-12)
    for e in d["equilibria"]:
        assert len(e["eigenvalues"]) == 2 and len(e["eigenvalues"][0]) == 2 and isinstance(e["type"], str)


def test_critical_track_csv(tmp_path) -> None:
    out = tmp_path / "tracks.csv"
    rc, _, err = run_cli("critical", "--scene", "fig8B", "--track", "--n-t", "101", "--out", str(out))
    assert rc == 0, err
    rows = list(csv.reader(out.open()))
    assert rows[0][:5] == ["branch", "t", "q", "r", "type"]
    assert len(rows) > 100


def test_tprime_npz(tmp_path) -> None:
    out = tmp_path / "t.npz"
    rc, _, err = run_cli(
        "tprime",
        "--scene",
        "fig1A",
        "--t",
        "0.5",
        "--q-range",
        "-1,1",
        "--r-range",
        "-2,2",
        "--grid",
        "12",
        "--out",
        str(out),
    )
    assert rc == 0, err
    with np.load(out) as z:
        assert z["values"].shape == (12, 12) and str(z["kind"]) == "instantaneous"
    rc, _, err = run_cli("tprime", "--scene", "fig1A", "--grid", "6", "--per-period", "--out", str(out))
    assert rc == 0, err
    with np.load(out) as z:
        assert str(z["kind"]) == "per-period"


def test_scenes_listing() -> None:
    rc, stdout, _ = run_cli("scenes")
    assert rc == 0 and "fig8B" in stdout and "fig11" in stdout
    rc, stdout, _ = run_cli("scenes", "--json")
    assert len(json.loads(stdout)) == 22


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["section", "--inertia", "1,2,4,3,0,0", "--ic", "0,0", "--periods", "3"], "not positive definite"),
        (["section", "--inertia", "1,2,4", "--ic", "0,0", "--periods", "3"], "--inertia needs 6"),
        (["section", "--alpha", "nan", "--ic", "0,0", "--periods", "3"], "alpha must be finite"),
        (["section", "--omega", "0", "--ic", "0,0", "--periods", "3"], "omega must be > 0"),
        (["section", "--omega", "-1", "--ic", "0,0", "--periods", "3"], "omega must be > 0"),
        (["section", "--ic", "0,x", "--periods", "3"], "--ic must be comma-separated numbers"),
        (["section", "--ic", "0,0"], "give --periods N (no --scene to take it from)"),
        (["section", "--periods", "3"], "give initial conditions"),
        (["section", "--random", "0", "--periods", "3"], "--random: random must be an integer in [1, "),
        (["section", "--random", "3", "--box", "1,0,0,1", "--periods", "3"], "qmin < qmax"),
        (["section", "--scene", "nope", "--periods", "3"], "unknown scene 'nope'"),
        (["section", "--ic", "0,0", "--periods", "3", "--rtol", "0"], "rtol must be"),
        (["section", "--ic", "0,0", "--periods", "3", "--method", "euler"], "invalid choice"),
        (["section", "--ic", "0,0", "--periods", "3", "--out", "/no/such/dir/x.csv"], "does not exist"),
        (["tprime", "--grid", "1"], "grid must be between 2"),
        (["tprime", "--q-range", "3,1"], "--q-range: q-range must be finite with lo < hi"),
        (["critical", "--t", "inf", "--json"], "--t: t must be a finite number, got inf"),
        (["critical", "--track"], "give --out FILE (.csv) and/or --json: nothing would be kept"),
        (
            ["section", "--ic", "0,0", "--periods", "3", "--bogus", "1"],
            "bilimovich section: error: unrecognized arguments: --bogus 1",
        ),
        (["scenes", "--x"], "bilimovich scenes: error: unrecognized arguments: --x"),
        (["critical", "--alpha", "1e300", "--json"], "coefficients overflow in double precision (alpha = 1e+300"),
        (["serve", "--address", "999.1.1.1", "--port", "5999"], "--address '999.1.1.1' is no address or host name"),
        (["serve", "--address", "192.0.2.1", "--port", "5999"], "cannot listen on --address 192.0.2.1 --port 5999"),
    ],
)
def test_bad_input_one_line_no_traceback(args, needle) -> None:
    rc, _, err = run_cli(*args)
    assert rc == 2
    assert needle in err
    assert "Traceback" not in err
    assert len(err.strip().splitlines()) == 1


def test_console_script_installed() -> None:
    exe = subprocess.run([sys.executable, "-m", "explorer_core.cli", "--version"], capture_output=True, text=True)
    assert exe.returncode == 0 and "bilimovich" in exe.stdout


def test_basins_json_and_npz(tmp_path) -> None:
    out = tmp_path / "b.npz"
    rc, stdout, err = run_cli("basins", "--scene", "fig11", "--I11", "1.6", "--box", "-1.7,1.5,-3,1", "--grid",
                              "12,10", "--out", str(out), "--json")  # fmt: skip
    assert rc == 0, err
    s = json.loads(stdout)
    assert sorted((a["kind"], a["period"]) for a in s["attractors"]) == [("periodic", 1), ("periodic", 3)]
    for a in s["attractors"]:
        assert len(a["points"]) == a["period"] and 0 < a["fraction"] < 1
    assert s["grid"] == [12, 10] and s["completed"] is True and s["out"] == [{"path": str(out)}]
    with np.load(out) as z:
        assert z["q"].shape == (12,) and z["r"].shape == (10,) and z["label"].shape == (10, 12)
        assert set(np.unique(z["label"])) == {a["id"] for a in s["attractors"]}


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["--box", "1,0,0,1"], "qmin < qmax"),
        (["--box", "0,1,0"], "--box needs 4"),
        (["--box", "0,inf,0,1"], "--box must be finite"),
        (["--grid", "0,5"], "grid NX must be an integer in [1, 2048], got 0"),
        (["--grid", "5,9999"], "grid NY must be an integer in [1, 2048], got 9999"),
        (["--grid", "5.5,5"], "--grid must be two whole numbers"),
        (["--grid", "1100,1100"], "1210000 pixels"),
        (["--out", "/no/such/dir/b.npz"], "does not exist"),
        (["--out", "b.csv"], "--out must end in .npz"),
        (["--cells", "0,4"], "cells NQ"),
        (["--max-periods", "0"], "max-periods must be an integer in [1, "),
    ],
)
def test_basins_bad_input_one_line(args, needle) -> None:
    rc, _, err = run_cli("basins", "--scene", "fig11", *args)
    assert rc == 2
    assert needle in err
    assert "Traceback" not in err
    assert len(err.strip().splitlines()) == 1


def test_basins_needs_a_box_without_a_scene() -> None:
    rc, _, err = run_cli("basins", "--grid", "4,4")
    assert rc == 2 and "give --box" in err


# --- the one writer, the one error path, losses ------------------------------------------------------------


def test_export_csv_numbers_read_back(tmp_path) -> None:
    from explorer_core import export

    path = tmp_path / "x.csv"
    rows = [(np.int64(1), np.float64(-0.0959), np.float32(0.5), np.bool_(True), None, np.nan, -np.inf, "a b")]
    assert export.write_csv(str(path), ["i", "x", "y", "ok", "none", "nan", "inf", "text"], rows) == 1
    text = path.read_text()
    assert "np." not in text
    assert text.splitlines()[1] == "1,-0.0959,0.5,1,,nan,-inf,a b"
    t = np.genfromtxt(path, delimiter=",", names=True, usecols=range(7))  # an empty field reads as NaN
    assert float(t["x"]) == -0.0959 and np.isnan(t["none"]) and np.isnan(t["nan"]) and t["inf"] == -np.inf
    with pytest.raises(TypeError, match="complex"):
        export.write_csv(str(path), ["z"], [(np.complex128(1j),)])


def test_export_json_is_strict_and_plain() -> None:
    from dataclasses import dataclass

    from explorer_core import export
    from explorer_core.losses import Loss

    @dataclass
    class Point:
        q: float
        r: np.ndarray

    doc = {"a": np.float64(1.5), "b": np.arange(3), "c": np.nan, "d": [np.inf, np.int32(2)],
           "e": Point(0.5, np.ones(2)), "f": Loss("pixels", np.int64(3), "escaped"), "g": np.complex128(1 - 2j),
           "h": (np.bool_(False),)}  # fmt: skip
    back = json.loads(export.dumps(doc))
    assert back == {"a": 1.5, "b": [0, 1, 2], "c": None, "d": [None, 2], "e": {"q": 0.5, "r": [1.0, 1.0]},
                    "f": {"what": "pixels", "count": 3, "why": "escaped"}, "g": [1.0, -2.0], "h": [False]}  # fmt: skip


def test_export_npz_at_exactly_the_path(tmp_path) -> None:
    from explorer_core import export

    export.write_npz(str(tmp_path / "image"), counts=np.ones((2, 3)))
    export.write_npy(str(tmp_path / "a.bin"), np.arange(4))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.bin", "image"]
    with np.load(tmp_path / "image") as z:
        assert z["counts"].shape == (2, 3)
    assert np.load(tmp_path / "a.bin").tolist() == [0, 1, 2, 3]


@pytest.mark.parametrize(
    ("name", "suffixes", "needle"),
    [
        ("x.png", (".csv",), "must end in .csv, got"),
        ("x", (".npz",), "must end in .npz"),
        ("no/such/dir/x.csv", (".csv",), "does not exist"),
        ("", (".csv",), "must be a file name"),
        (".", (), "is a directory"),
    ],
)
def test_check_output_refuses_with_the_path(tmp_path, monkeypatch, name, suffixes, needle) -> None:
    from explorer_core import export

    monkeypatch.chdir(tmp_path)
    with pytest.raises(export.OutputError, match=needle) as info:
        export.check_output(name, suffixes)
    assert name in str(info.value) and "\n" not in str(info.value)


def test_check_output_tries_writing_and_leaves_nothing(tmp_path) -> None:
    from explorer_core import export

    with pytest.raises(export.OutputError, match=r"cannot be written: /proc/x\.csv"):
        export.check_output("/proc/x.csv", (".csv",))  # not writable even for root
    kept = tmp_path / "kept.csv"
    kept.write_text("old")
    export.check_output(str(kept), (".CSV",))
    export.check_output(str(tmp_path / "new.csv"), (".csv",))
    assert kept.read_text() == "old" and sorted(p.name for p in tmp_path.iterdir()) == ["kept.csv"]


class _FakeContinuation:
    """What continue_orbit returns, with numpy values in its branches and the losses contract."""

    def __init__(self) -> None:
        from types import SimpleNamespace

        from explorer_core.losses import Loss

        self.branches = [SimpleNamespace(period=1, stop="range end", values=np.array([-0.35, -0.36]),
                                         states=np.array([[-0.0959, -1.962], [-0.1, -1.9]]),
                                         mults=np.array([[0.5 + 0.1j, 0.5 - 0.1j], [-0.9, -0.2]], dtype=complex),
                                         stable=np.array([True, True]))]  # fmt: skip
        self.bifurcations: list = []
        self.messages: list = []
        self.param = "alpha"
        self.completed = True
        self.complete = False
        self.lost = [Loss("branch 1 (period 2)", 1, "the corrector did not converge at the smallest step")]

    def summary(self) -> dict:
        return {"branches": len(self.branches), "completed": self.completed}

    def report(self) -> list:
        from explorer_core.analyses.continuation import Continuation

        return Continuation.report(self)  # type: ignore[arg-type]

    # The result writes its own files: the real writer on these fields (a fake with numpy values).
    def csv_rows(self) -> list:
        from explorer_core.analyses.continuation import Continuation

        return Continuation.csv_rows(self)  # type: ignore[arg-type]

    def write(self, path: str) -> dict:
        from explorer_core.analyses.continuation import Continuation

        self.CSV_HEADER = Continuation.CSV_HEADER
        return Continuation.write(self, path)  # type: ignore[arg-type]


def test_continue_steps_csv_and_losses(tmp_path, monkeypatch) -> None:
    """--ds/--ds-min/--ds-max reach continue_orbit; its CSV holds numbers; its losses are printed and in --json."""
    from explorer_core.analyses import continuation

    seen = {}

    def fake(spec, **kwargs):  # the CLI builds the spec (continuation_spec) and runs it
        seen.update(ds=spec.options.ds, ds_min=spec.options.ds_min, ds_max=spec.options.ds_max)
        return _FakeContinuation()

    monkeypatch.setattr(continuation, "continue_orbit", fake)
    out = tmp_path / "c.csv"
    rc, stdout, err = run_cli("continue", "--scene", "fig10", "--param", "alpha", "--range", "-0.35,-0.36", "--from",
                              "-0.0959,-1.962", "--ds", "0.01", "--ds-min", "1e-6", "--ds-max", "0.05", "--out",
                              str(out), "--json")  # fmt: skip
    assert rc == 0, err
    assert (seen["ds"], seen["ds_min"], seen["ds_max"]) == (0.01, 1e-6, 0.05)
    why = "the corrector did not converge at the smallest step"
    assert err == f"bilimovich continue: lost: branch 1 (period 2): {why}\n"
    d = json.loads(stdout)
    assert d["complete"] is False and d["lost"] == [{"what": "branch 1 (period 2)", "count": 1, "why": why}]
    assert "np." not in out.read_text()
    t = np.genfromtxt(out, delimiter=",", names=True)
    assert t["value"].tolist() == [-0.35, -0.36] and t["mu1_im"].tolist() == [0.1, 0.0]
    assert t["stable"].tolist() == [1, 1]
    rc, _, err = run_cli("continue", "--scene", "fig10", "--param", "alpha", "--range", "-0.35,-0.36", "--from",
                         "-0.0959,-1.962", "--ds", "0.5")  # fmt: skip
    assert rc == 2 and "ds-min <= ds <= ds-max" in err and err.count("\n") == 1


def test_critical_says_when_the_equilibria_form_a_curve() -> None:
    rc, stdout, err = run_cli("critical", "--inertia", "1,1,1,0,0,0", "--alpha", "0")
    assert rc == 0, err
    d = json.loads(stdout)
    assert d["equilibria"] == [] and d["degenerate"] is True and "every point" in d["message"]
    rc, stdout, _ = run_cli("critical", "--scene", "fig8B")
    assert "degenerate" not in json.loads(stdout)


def test_one_error_path(monkeypatch, tmp_path) -> None:
    """Ctrl-C outside the work's own handler: 130 and one line; an output that fails after all: 2 and one line."""
    from explorer_core import cli

    def interrupted(args):
        raise KeyboardInterrupt

    monkeypatch.setitem(cli.COMMANDS, "scenes", cli.COMMANDS["scenes"].__class__("", None, interrupted))
    rc, _, err = run_cli("scenes")
    assert rc == 130 and err == "bilimovich scenes: interrupted\n"

    def unwritable(args):
        raise PermissionError(13, "Permission denied", "/x.csv")

    monkeypatch.setitem(cli.COMMANDS, "scenes", cli.COMMANDS["scenes"].__class__("", None, unwritable))
    rc, _, err = run_cli("scenes")
    assert rc == 2 and err == "bilimovich scenes: error: Permission denied: /x.csv\n"


def test_method_vern9_is_selectable_and_agrees_with_solve_ivp(tmp_path) -> None:
    """Verner's 9(8) pair (issue 22) from the command line; its points against solve_ivp at 1e-13."""
    from naive import ivp_map

    from explorer_core.scenes import get_scene

    out = tmp_path / "v.csv"
    rc, _, err = run_cli("section", "--scene", "fig1C", "--ic", "0.1,0.2", "--periods", "20", "--transient", "0",
                         "--method", "vern9", "--rtol", "1e-11", "--atol", "1e-13", "--out", str(out))  # fmt: skip
    assert rc == 0, err
    pts = np.genfromtxt(out, delimiter=",", skip_header=1)[:, 2:]
    params = get_scene("fig1C").params
    ref = np.array([ivp_map(params, (0.1, 0.2), k) for k in range(1, 21)])
    assert np.max(np.abs(pts - ref)) < 1e-8


def test_the_words_on_stderr_match_the_exit_status() -> None:
    """A run that went on (exit 0) prints no line that says "error": an unreliable method is "unreliable [code]"
    (its JSON level stays "error"); every member failing is exit 3 with "failed:"."""
    rc, out, err = run_cli("section", "--scene", "fig8B", "--periods", "5", "--method", "rk4", "--steps-per-period",
                           "3", "--json")  # fmt: skip
    assert rc == 0
    assert "unreliable [rk4_unstable]" in err and "error" not in err.lower()
    assert [w["level"] for w in json.loads(out)["reliability"] if w["code"] == "rk4_unstable"] == ["error"]


def test_continue_help_names_both_files_out_writes() -> None:
    """Fails on the old code (the .csv's first ten columns only): the help names the columns of the .csv and of the
    .codim2.csv as the writers write them."""
    from explorer_core.analyses.continuation import Continuation
    from explorer_core.cli import COMMANDS

    words = COMMANDS["continue"].out_help
    assert ",".join(Continuation.CSV_HEADER) in words and ",".join(Continuation.CODIM2_CSV_HEADER) in words
    assert "FILE.codim2.csv" in words
