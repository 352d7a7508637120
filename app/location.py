"""The page's URL: the location the app writes, and the query as the server received it."""

from __future__ import annotations

from typing import Any

from panel.io.location import Location


class AppLocation(Location):
    """The page's URL, written by the app (``publish`` in :func:`app.main.create_app`) and never parsed by Panel.

    Panel parses the query of every URL it is given (``panel.util.parse_query``): ``int()`` on any value
    of digits (``?n=²`` or 5000 digits raise, the page is blank and the server logs a traceback), JSON or
    ``literal_eval`` on ``[``/``{`` values (``?ics=[1,2]`` arrived as the list ``[1, 2]``). The app reads
    the raw query itself (:func:`raw_query`, then :func:`app.state.parse_query`, which reports every bad
    value by its key) and syncs no parameter through Panel, so nothing here needs Panel's parsing.
    """

    def _update_synced(self, event: Any = None) -> None:
        if self._synced:  # nothing of the app is synced through Panel; kept for any other use
            super()._update_synced(event)


def raw_query(request: Any) -> dict[str, list[bytes]]:
    """The URL's query as the server received it (key -> raw values), without Panel's parsing."""
    args = getattr(request, "arguments", None) or {}
    return {str(k): list(v) if isinstance(v, list | tuple) else [v] for k, v in args.items()}
