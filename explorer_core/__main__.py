"""The ``bilimovich`` console script (and ``python -m explorer_core``): the stop signals handled first
(:mod:`explorer_core.launch`), then the command line (:func:`explorer_core.cli.entry`)."""

from __future__ import annotations

from explorer_core.launch import early


def entry() -> None:
    """Hold Ctrl-C and SIGTERM from the first lines, then run the command line."""
    early()
    from explorer_core.cli import entry as run

    run()


if __name__ == "__main__":
    entry()
