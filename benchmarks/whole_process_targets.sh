#!/bin/bash
# Issue 22's whole-process targets, as the user types them (the warm worker on): the Fig. 10 orbit diagram,
# a 40x40x2 Fig. 11 chart, 200 ICs x 1000 periods at 1e-10 against solve_ivp. Three runs each; run it on a
# quiet machine:   benchmarks/whole_process_targets.sh
set -u
ROOT=$(cd "$(dirname "$0")/.." && pwd)
B="$ROOT/.venv/bin/bilimovich"
OUT=$(mktemp -d)
cd "$OUT"
uptime
"$B" warmup >/dev/null 2>&1
# A command leaves the warm worker (the user's second command meets it); wait until it listens, or the first runs
# below would run by themselves while it starts.
"$B" section --scene fig1A --ic 0.1,0.2 --periods 1 --quiet >/dev/null 2>&1
for _ in $(seq 120); do "$B" worker status | grep -q listening && break; sleep 1; done
for i in 1 2 3; do
  /usr/bin/time -f "orbit diagram (400 x (500+200), --out csv): %e s" "$B" bifurcation --scene fig10 --param alpha \
    --range -0.42,-0.35 --n-values 400 --transient 500 --points 200 --out od.csv --quiet
done
for i in 1 2 3; do
  /usr/bin/time -f "chart fig11 40x40x2 every pixel: %e s" "$B" chart --scene fig11 --x-param alpha --x-range -0.6,-0.4 \
    --y-param I11 --y-range 1,2 --grid 40,40 --ic -0.09,-2 --ic -0.5,-1 --out ch.npz --quiet
done
for i in 1 2 3; do
  /usr/bin/time -f "section 200 x 1000 at 1e-10: %e s" "$B" section --scene fig1C --random 200 --periods 1000 \
    --rtol 1e-10 >/dev/null
done
# solve_ivp's time per trajectory (3 of them), for the ratio with the section's whole-process time above.
cd "$ROOT" && .venv/bin/python benchmarks/section_vs_solve_ivp.py --scene fig1C --random 200 --periods 1000 \
  --ivp-trajectories 3 --repeat 1 2>&1 | tail -2
uptime
rm -rf "$OUT"
