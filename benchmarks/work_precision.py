"""Work-precision benchmark as a plain script: exactly ``bilimovich bench`` (same options, same files).

    .venv/bin/python benchmarks/work_precision.py --out out/bench [--quick] [--cases regular,drift]
        [--repeat 3] [--no-peers] [--cache-dir DIR] [--json]

Writes bench.json, bench.csv, bench.md, throughput.json and work_precision.png in --out; see
docs/bench.md for the cases, the reference, the horizon and the measured numbers.
"""

from __future__ import annotations

import sys

from explorer_core.cli import main

if __name__ == "__main__":
    sys.exit(main(["bench", *sys.argv[1:]]))
