"""The ``bilimovich`` console script (and ``python -m explorer_core``): the stop signals handled first, then the
command handed to the warm worker, or run here (:func:`explorer_core.worker.entry`)."""

from __future__ import annotations

from collections.abc import Callable, Sequence

from explorer_core.launch import early


def _main() -> Callable[[Sequence[str]], int]:
    # The command line (numpy, argparse's tree: ~0.15 s) only when this process runs the command.
    from explorer_core.cli import main

    return main


def entry() -> None:
    """Hold Ctrl-C and SIGTERM from the first lines, then run the command line."""
    early()
    from explorer_core.worker import entry as run

    run(_main)


if __name__ == "__main__":
    entry()
