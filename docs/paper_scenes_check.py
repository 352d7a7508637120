"""The paper's scenes checked by brute force (docs/continuation.md, "The paper's scenes by brute force").

The continuation gives every period doubling of Fig. 10's cascade and the Neimark-Sacker (NS) point of Fig. 10's
and Fig. 11's period-1 orbit in ``g1`` with their normal-form coefficients and criticality. Here each is checked
with the project's own brute-force commands, independently of the normal forms:

* a doubling of the period-``n`` orbit at ``alpha_k``: ``bilimovich bifurcation`` across it (continuation seeding,
  forward and backward sweeps); the doubled orbit's amplitude ``A = max_j |x_j - x_{j+n}|`` on the side where the
  period-``n`` orbit is unstable is fitted by ``A = c d^e`` (``d = alpha_k - alpha``); supercritical means ``e``
  near 1/2 and the two sweeps equal (no hysteresis);
* a NS point at ``g1*``: ``bilimovich section`` at ``g1 = g1* + delta`` on both sides from a point near the orbit
  and from a point farther out; the attractor's size (half its diameter) is ``0`` on the stable side, a small
  closed curve on the other whose size grows like ``delta^e`` with ``e`` near 1/2, reached from inside and
  outside (a stable invariant curve born: supercritical).

    python docs/paper_scenes_check.py [DIR]  # writes docs/figures/paper_scenes_bruteforce.png, prints the numbers
                                             # (DIR: keep the commands' outputs there and reuse them)

About 5 minutes on an idle core.
"""

from __future__ import annotations

import csv
import json
import subprocess
import sys
import tempfile
from collections import defaultdict
from pathlib import Path

import numpy as np

OUT = Path(__file__).parent / "figures" / "paper_scenes_bruteforce.png"
#: Fig. 10's period-1 orbit at alpha = -0.35 (README) and Fig. 11's period-1 focus at alpha = -0.5, I11 = 1.6.
FIG10_ORBIT = (-0.0959, -1.962)
FIG11 = ["--scene", "fig11", "--inertia", "1.6,2,4,0,0.5,0.3"]
FIG11_ORBIT = (-0.1744491259, -2.185453719)
#: The doublings' windows, as fractions of the distance to the next doubling: this much on the unstable side ...
UNSTABLE_SIDE = 0.2
#: ... and this much on the stable side.
STABLE_SIDE = 0.05
#: Values of a doubling's orbit diagram (offset so that no value falls on the doubling).
N_VALUES = 26
#: A value enters the fit if its forward and backward amplitudes agree to this (relative): converged.
AGREE = 0.02
#: The NS points' distances delta (both sides), the sections' transient and kept points.
DELTAS = (1e-3, 2e-3, 4e-3, 8e-3, 1.6e-2)
NS_TRANSIENT, NS_POINTS = 30000, 600
#: Fig. 11's NS curve in (g1, I11) has a Chenciner point at I11 = 1.9968: its NS points on either side.
CH_SIDES = (1.9, 2.1)


def bilimovich(*args: str) -> None:
    """Run ``bilimovich ARGS`` (this checkout's, as ``python -m explorer_core.cli``), quietly; not again if its
    ``--out`` file is there (a kept directory, ``python docs/paper_scenes_check.py DIR``)."""
    if Path(args[args.index("--out") + 1]).exists():
        return
    subprocess.run([sys.executable, "-m", "explorer_core.cli", *args, "--quiet"], check=True)


def pair(x: tuple[float, float]) -> str:
    return f"{float(x[0])!r},{float(x[1])!r}"


def fit_power(d: np.ndarray, a: np.ndarray) -> tuple[float, float, float]:
    """``a = c d^e`` by least squares in logs: ``(c, e, standard error of e)``."""
    X = np.column_stack([np.ones(d.size), np.log(d)])
    coef, res, _, _ = np.linalg.lstsq(X, np.log(a), rcond=None)
    dof = max(d.size - 2, 1)
    s2 = float(res[0]) / dof if res.size else 0.0
    cov = s2 * np.linalg.inv(X.T @ X)
    return float(np.exp(coef[0])), float(coef[1]), float(np.sqrt(cov[1, 1]))


def bilimovich_json(out: Path, *args: str) -> dict:
    """``bilimovich ARGS --json`` into ``out`` (not again if it is there), read."""
    if not out.exists():
        part = out.with_suffix(".part")
        with part.open("w") as f:
            subprocess.run([sys.executable, "-m", "explorer_core.cli", *args, "--json", "--quiet"], check=True,
                           stdout=f)  # fmt: skip
        part.rename(out)
    return json.loads(out.read_text())


def cascade(tmp: Path) -> list[dict]:
    """Fig. 10's doublings as ``bilimovich continue --switch`` locates them (JSON ``bifurcations``)."""
    res = bilimovich_json(tmp / "cascade.json", "continue", "--scene", "fig10", "--param", "alpha",
                          "--range=-0.35,-0.42", f"--from={pair(FIG10_ORBIT)}", "--switch")  # fmt: skip
    return sorted((b for b in res["bifurcations"] if b["type"] == "period_doubling"), key=lambda b: -b["value"])


def doubling_check(tmp: Path, k: int, b: dict, spacing: float) -> dict:
    """The orbit diagram across the doubling ``b`` (spacing: the distance to the next doubling): amplitudes by
    sweep and value, the fit on the unstable side, the hysteresis (largest forward-backward difference)."""
    n, ac = int(b["period"]), float(b["value"])
    lo, hi = ac - UNSTABLE_SIDE * spacing, ac + STABLE_SIDE * spacing
    lo -= 0.37 * (hi - lo) / (N_VALUES - 1)  # no value on the doubling itself
    f = tmp / f"doubling{k}.csv"
    bilimovich("bifurcation", "--scene", "fig10", "--param", "alpha", f"--range={lo!r},{hi!r}", "--n-values",
               str(N_VALUES), "--points", str(8 * n), "--transient", str(4000 * n), f"--ic={pair(FIG10_ORBIT)}",
               "--out", str(f))  # fmt: skip
    pts = defaultdict(list)
    for r in csv.DictReader(f.open()):
        if r["status"] == "ok":
            pts[r["sweep"], float(r["value"])].append((float(r["q"]), float(r["r"])))
    values = np.array(sorted({v for _, v in pts}))
    amp = {s: np.array([split(np.array(pts[s, v]), n) for v in values]) for s in ("forward", "backward")}
    d = ac - values
    fw, bw = amp["forward"], amp["backward"]
    ok = (d > 0) & (np.abs(fw - bw) <= AGREE * np.maximum(fw, bw)) & (fw > 0)
    c, e, se = fit_power(d[ok], 0.5 * (fw[ok] + bw[ok]))
    return {"period": n, "alpha": ac, "b": b["coefficient"], "b_error": b["coefficient_error"],
            "criticality": b["criticality"], "d": d, "forward": fw, "backward": bw, "fit": (c, e, se),
            "n_fit": int(ok.sum()), "ok": ok, "hysteresis": float(np.abs(fw - bw).max() / max(fw.max(), 1e-300)),
            "stable_side": float(np.maximum(fw, bw)[d < 0].max()), "pts": pts, "values": values}  # fmt: skip


def split(p: np.ndarray, n: int) -> float:
    """The doubled orbit's amplitude: the largest ``|x_j - x_{j+n}|`` (0 on a period-``n`` orbit)."""
    return float(np.linalg.norm(p[n:] - p[:-n], axis=1).max())


def size(tmp: Path, name: str, args: list[str], g1: float, ic: tuple[float, float]) -> float:
    """Half the diameter of the section's attractor at ``g1`` from ``ic`` (0 on a fixed point)."""
    return sized(tmp, name, args, g1, ic)[0]


def sized(tmp: Path, name: str, args: list[str], g1: float, ic: tuple[float, float],
          transient: int = NS_TRANSIENT) -> tuple[float, np.ndarray]:  # fmt: skip
    """:func:`size` and the section's last point."""
    f = tmp / f"{name}.csv"
    bilimovich("section", *args, "--g1", repr(g1), f"--ic={pair(ic)}", "--transient", str(transient),
               "--periods", str(NS_POINTS), "--out", str(f))  # fmt: skip
    p = np.array([(float(r["q"]), float(r["r"])) for r in csv.DictReader(f.open())])
    return 0.5 * float(np.max(np.linalg.norm(p[:, None, :] - p[None, :, :], axis=2))), p[-1]


def ns_point(tmp: Path, name: str, args: list[str], orbit: tuple[float, float]) -> dict:
    """The NS point of ``args``'s period-1 orbit in ``g1`` from 1 to 4 (``bilimovich continue``, JSON)."""
    res = bilimovich_json(tmp / f"{name}.json", "continue", *args, "--param", "g1", "--range=1,4",
                          f"--from={pair(orbit)}")  # fmt: skip
    return next(b for b in res["bifurcations"] if b["type"] == "neimark_sacker")


def ch_check(tmp: Path, i11: float) -> dict:
    """Fig. 11's NS point at ``I11`` (on either side of the Chenciner point of its NS curve in ``(g1, I11)``):
    the attractor's size just above it (``+1e-3``, ``+4e-3``, from near the orbit) and just below it (``-1e-3``)
    from near the orbit and, over ten times the transient, from the last point of the ``+1e-3`` run (a jump that
    stays: hysteresis)."""
    args = ["--scene", "fig11", "--inertia", f"{i11!r},2,4,0,0.5,0.3", "--alpha", "-0.5"]
    ns = ns_point(tmp, f"ch{i11}", args, FIG11_ORBIT)
    g, near = float(ns["value"]), tuple(np.array(ns["point"]) + 0.01)
    up1, last = sized(tmp, f"ch{i11}_up1", args, g + 1e-3, near)
    up4 = size(tmp, f"ch{i11}_up4", args, g + 4e-3, near)
    down = size(tmp, f"ch{i11}_down", args, g - 1e-3, near)
    back = sized(tmp, f"ch{i11}_back_long", args, g - 1e-3, tuple(last), 10 * NS_TRANSIENT)[0]
    return {"I11": i11, "g1": g, "re_d": ns["coefficient"], "re_d_error": ns["coefficient_error"],
            "criticality": ns["criticality"], "up1": up1, "up4": up4, "down": down, "back": back}  # fmt: skip


def ns_check(tmp: Path, name: str, args: list[str], orbit: tuple[float, float], far: float) -> dict:
    """The NS point of ``args``'s period-1 orbit in ``g1`` (:func:`ns_point`) and the sections across it, from
    ``0.01`` and ``far`` off the orbit (inside its basin: Fig. 11's period-3 cycle coexists)."""
    ns = ns_point(tmp, name, args, orbit)
    g, x = float(ns["value"]), np.array(ns["point"])
    near, out = tuple(x + 0.01), tuple(x + far)
    rows = []
    for delta in (*(-d for d in DELTAS[::2]), *DELTAS):
        rows.append((delta, size(tmp, f"{name}_{delta}_in", args, g + delta, near),
                     size(tmp, f"{name}_{delta}_out{far}", args, g + delta, out)))  # fmt: skip
    rows = np.array(rows)
    up = rows[:, 0] > 0
    c, e, se = fit_power(rows[up, 0], rows[up, 1])
    return {"g1": g, "re_d": ns["coefficient"], "re_d_error": ns["coefficient_error"],
            "criticality": ns["criticality"], "theta": float(np.angle(complex(*ns["multipliers"][0]))),
            "rows": rows, "fit": (c, e, se), "point": x}  # fmt: skip


def figure(doublings: list[dict], nss: dict[str, dict], tmp: Path) -> None:
    import matplotlib  # lazily: the checks themselves need no plotting

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(2, 2, figsize=(12, 9))
    first = doublings[0]
    for s, m, col in (("forward", "o", "k"), ("backward", "x", "tab:orange")):
        for v in first["values"]:
            q = np.array(first["pts"][s, v])[:, 0]
            ax[0, 0].plot(np.full(q.size, v), q, m, ms=3, color=col, mfc="none",
                          label=f"{s} sweep" if v == first["values"][0] else None)  # fmt: skip
    ax[0, 0].axvline(first["alpha"], color="tab:red", lw=0.8, label="doubling (continuation)")
    ax[0, 0].set(xlabel="alpha", ylabel="q_k", title="Fig. 10: orbit diagram across the first doubling")
    ax[0, 0].legend(fontsize=8)
    for r in doublings:
        d, a = r["d"], 0.5 * (r["forward"] + r["backward"])
        keep, ok = d > 0, r["ok"]
        c, e, _ = r["fit"]
        line = ax[0, 1].loglog(d[ok], a[ok], "o", ms=3, label=f"period {r['period']} -> {2 * r['period']}: "
                               f"e = {e:.3f}")  # fmt: skip
        col = line[0].get_color()
        ax[0, 1].loglog(d[keep & ~ok], a[keep & ~ok], "o", ms=3, mfc="none", color=col)  # not converged: not fitted
        ax[0, 1].loglog(d[keep], c * d[keep] ** e, "-", lw=0.8, color=col)
    ax[0, 1].set(xlabel="alpha_k - alpha", ylabel="amplitude max |x_j - x_(j+n)|",
                 title="Fig. 10's five doublings: amplitude ~ c d^e (hollow: not fitted)")  # fmt: skip
    ax[0, 1].legend(fontsize=8)
    r = nss["fig10"]
    for delta, col in ((-DELTAS[-1], "tab:blue"), (DELTAS[0], "tab:green"), (DELTAS[-1], "tab:red")):
        for end in ("in", "out"):
            f = tmp / f"fig10_{delta}_{'in' if end == 'in' else 'out0.3'}.csv"
            p = np.array([(float(x["q"]), float(x["r"])) for x in csv.DictReader(f.open())])
            ax[1, 0].plot(p[:, 0], p[:, 1], ".", ms=2, color=col,
                          label=f"g1 = g1* {delta:+.3g}" if end == "in" else None)  # fmt: skip
    ax[1, 0].set(xlabel="q", ylabel="r", title=f"Fig. 10 (alpha = -0.35): sections across the NS point g1* = "
                 f"{r['g1']:.6f}")  # fmt: skip
    ax[1, 0].legend(fontsize=8)
    for name, r in nss.items():
        up = r["rows"][:, 0] > 0
        c, e, _ = r["fit"]
        line = ax[1, 1].loglog(r["rows"][up, 0], r["rows"][up, 1], "o", ms=4, label=f"{name}: e = {e:.3f}")
        ax[1, 1].loglog(r["rows"][up, 0], r["rows"][up, 2], "x", ms=6, color=line[0].get_color())
        ax[1, 1].loglog(r["rows"][up, 0], c * r["rows"][up, 0] ** e, "-", lw=0.8, color=line[0].get_color())
    ax[1, 1].set(xlabel="g1 - g1*", ylabel="invariant curve's half diameter",
                 title="NS points: curve size ~ c delta^e (o from inside, x from outside)")  # fmt: skip
    ax[1, 1].legend(fontsize=8)
    fig.suptitle("The paper's scenes by brute force (docs/paper_scenes_check.py)")
    fig.tight_layout()
    fig.savefig(OUT, dpi=110)


def main() -> None:
    with tempfile.TemporaryDirectory() as t:
        tmp = Path(sys.argv[1] if len(sys.argv) > 1 else t)
        tmp.mkdir(parents=True, exist_ok=True)
        bifs = cascade(tmp)
        spacings = [bifs[k]["value"] - bifs[k + 1]["value"] for k in range(len(bifs) - 1)]
        spacings.append(spacings[-1] / 4.669)  # Feigenbaum's ratio for the last one's next
        doublings = [doubling_check(tmp, k, b, s) for k, (b, s) in enumerate(zip(bifs, spacings, strict=True))]
        for r in doublings:
            c, e, se = r["fit"]
            print(f"doubling of the period-{r['period']} orbit at alpha = {r['alpha']:.12f}: b = {r['b']:.6g} "
                  f"+- {r['b_error']:.1g} ({r['criticality']}); brute force: A = {c:.4g} d^{e:.4f} (+- {se:.1g}, "
                  f"{r['n_fit']} values), forward-backward {r['hysteresis']:.1g} of the largest amplitude, "
                  f"stable side amplitude <= {r['stable_side']:.1g}")  # fmt: skip
        nss = {"fig10": ns_check(tmp, "fig10", ["--scene", "fig10", "--alpha", "-0.35"], FIG10_ORBIT, 0.3),
               "fig11": ns_check(tmp, "fig11", [*FIG11, "--alpha", "-0.5"], FIG11_ORBIT, 0.15)}  # fmt: skip
        for name, r in nss.items():
            c, e, se = r["fit"]
            print(f"{name}: NS at g1 = {r['g1']:.12f}, theta = {r['theta']:.4f}, Re d = {r['re_d']:.6g} +- "
                  f"{r['re_d_error']:.1g} ({r['criticality']}); brute force: size = {c:.4g} delta^{e:.4f} "
                  f"(+- {se:.1g})")  # fmt: skip
            for delta, a_in, a_out in r["rows"]:
                print(f"    delta = {delta:+.4g}: half diameter {a_in:.4g} (from inside), {a_out:.4g} (outside)")
        for i11 in CH_SIDES:
            r = ch_check(tmp, i11)
            print(f"fig11 at I11 = {i11}: NS at g1 = {r['g1']:.12f}, Re d = {r['re_d']:.6g} +- {r['re_d_error']:.1g} "
                  f"({r['criticality']}); brute force: size {r['up1']:.4g} at +1e-3, {r['up4']:.4g} at +4e-3, "
                  f"{r['down']:.3g} at -1e-3 from near the orbit, {r['back']:.4g} at -1e-3 from the +1e-3 "
                  "attractor")  # fmt: skip
        figure(doublings, nss, tmp)


if __name__ == "__main__":
    main()
