"""The numerics' messages in the page's words: what happened and what to change on this page.

The core's reliability warnings (:mod:`explorer_core.analyses.reliability`) are written for the command line: they
name its options (``max_steps``), its formulas (``rho*T/beta``, ``10*eps*|t|``) and the statuses' file names
(``'too_many_steps'``). The page has no ``max_steps``; its settings are the controls' (Method, Accuracy, RK4 steps
per period, Periods, t0). :func:`page_words` rewrites a message into those words; the statuses are said by their
:attr:`explorer_core.status.Status.word`, as everywhere on the page.
"""

from __future__ import annotations

import re

from explorer_core.status import Status

#: (pattern, the page's words), applied in order. Each pattern is a piece of a message of
#: explorer_core.analyses.reliability (tests/test_app_words.py checks that none of the code words survive).
REWRITES: tuple[tuple[re.Pattern[str], str], ...] = tuple(
    (re.compile(p), w)
    for p, w in (
        # step_budget
        (
            r" \(stability: rho\*T/beta = [^)]*\)",
            " (the fastest rate of the field there, times the period, over the method's stability limit)",
        ),
        (
            r"more than the budget max_steps = (\d+): expect '\w+'\.",
            r"more than the step budget of \1 per period: those trajectories will stop unfinished. Compute fewer "
            "periods, zoom in on a smaller view, or choose values of the parameters nearer the sliders' ranges.",
        ),
        # step_collapsed
        (r"for rtol = ([^ ]+) fell", r"for the tolerance \1 fell"),
        (r"the round-off floor 10\*eps\*\|t\| = ", "the smallest step double precision resolves at that time, "),
        (r"Loosen the tolerance or move t0 nearer 0\.", "Choose Accuracy 'plot', or a section phase t0 nearer 0."),
        # too_many_steps
        (r"the step budget \(max_steps = (\d+) per period\)", r"the step budget (\1 steps per period)"),
        (
            r"Raise max_steps or compute fewer periods\.",
            "Compute fewer periods, or start nearer the attractor (the page's step budget is fixed).",
        ),
        # rk4: the product of the rate and the step, and the method's names as the Method control says them
        (r"rho\*h = ([^ ]+) \(\|r\|\*h = [^)]*\)", r"the fastest rate times the step, \1,"),
        (
            r"Use at least (\d+) steps per period, or dop853",
            r"Set 'RK4 steps per period' to at least \1, or Method "
            "DOP853",
        ),
        (r"Use more steps or dop853\.", "Raise 'RK4 steps per period', or choose Method DOP853."),
        (r"tolerance rtol = ([^,]+), atol = ([^ ]+) is loose", r"the tolerance (\1) of Accuracy 'plot' is loose"),
        (
            r" \(measured: ([^ ]+) x \(atol \+ rtol \|x\|\) per period on regular orbits, \|x\| up to ([^ ]+) here\)",
            r" (measured: \1 tolerances per period on regular orbits, states up to \2 here)",
        ),
        (r"Tighten the tolerance\.", "Choose Accuracy 'high'."),
    )
)
#: The statuses' file names ('step_collapsed') as the page says them ('step collapsed').
_STATUS = re.compile("|".join(re.escape(f"'{s.label}'") for s in Status if s.label != s.word))


def page_words(message: str) -> str:
    """A message of the numerics in the page's words (:data:`REWRITES`, then the statuses' words)."""
    for pattern, words in REWRITES:
        message = pattern.sub(words, message)
    return _STATUS.sub(lambda m: f"'{Status[m.group(0)[1:-1].upper()].word}'", message)


__all__ = ["REWRITES", "page_words"]


def counted(n: int, noun: str, grouped: bool = False) -> str:
    """``n`` and the noun in the number it takes: "1 trajectory", "2 trajectories", "0 branches" (English plurals of
    the page's nouns: -y after a consonant -> -ies; -s, -x, -ch, -sh -> -es; else -s); ``grouped``: 1,234."""
    number = f"{n:,}" if grouped else str(n)
    if n == 1:
        return f"{number} {noun}"
    if noun.endswith("y") and noun[-2:-1] not in "aeiou":
        return f"{number} {noun[:-1]}ies"
    return f"{number} {noun}{'es' if noun.endswith(('s', 'x', 'ch', 'sh')) else 's'}"
