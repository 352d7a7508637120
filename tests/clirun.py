"""Run the bilimovich command line in-process, as the tests see it."""

from __future__ import annotations

import contextlib
import io

from explorer_core.cli import main


def run_cli(*args: str) -> tuple[int, str, str]:
    """``(exit status, stdout, stderr)`` of ``bilimovich ARGS``; argparse's SystemExit becomes the status.

    Redirects the streams itself (no capsys), so it also works across hypothesis examples.
    """
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            rc = main(list(args))
        except SystemExit as exc:  # argparse exits on usage errors
            rc = exc.code
    return rc, out.getvalue(), err.getvalue()
