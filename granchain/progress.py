"""Progress bars for long work (an ensemble, the inference's simulated grid, the warm-up):
tqdm on stderr, with the time left estimated from the rate so far.

A bar is shown only when stderr is a terminal (``enabled=None``), so pipes, tests and the
workflow's logs get nothing from it; ``--no-progress`` turns it off. It writes to stderr
only and is updated between kernel calls, so it changes no result and no output file.
"""
from __future__ import annotations

import sys


def shown(enabled: bool | None = None) -> bool:
    """Is a bar shown? ``enabled`` None: when stderr is a terminal."""
    if enabled is None:
        return sys.stderr.isatty()
    return bool(enabled)


class _Silent:
    """What :func:`bar` returns when no bar is shown: the calls a bar takes, doing nothing
    (so a run without a terminal does not import tqdm)."""

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False

    def update(self, n: int = 1) -> None:
        pass

    def external_write_mode(self, file=None):
        return self


def bar(total: int, desc: str, unit: str = "chain", enabled: bool | None = None):
    """A tqdm bar on stderr counting ``total`` ``unit``s (``update(n)`` as they finish),
    cleared when it closes, when :func:`shown`; else a silent stand-in."""
    if not shown(enabled):
        return _Silent()
    from tqdm import tqdm
    return tqdm(total=total, desc=desc, unit=unit, file=sys.stderr, leave=False,
                dynamic_ncols=True)
