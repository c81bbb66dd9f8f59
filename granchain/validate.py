"""One-line checks of scene values: every problem is a
:class:`~granchain.errors.SceneError` naming the field and the fix. Shared by the scene
parser (``granchain.scene``) and the effects, which validate their own scene sections
(``granchain.effects``)."""
from __future__ import annotations

import difflib
import math

from .errors import SceneError


def short(value, limit: int = 60) -> str:
    """repr of a value for a one-line message, cut to ``limit`` characters."""
    text = repr(value)
    return text if len(text) <= limit else text[:limit - 3] + "..."


def number(node, field: str, *, positive=False, nonneg=False, integer=False,
           allow_none=False, lo=None, hi=None, fix=None):
    """A number (``field`` names it in errors) checked against the given bounds."""
    if node is None and allow_none:
        return None
    given = node
    if isinstance(node, bool) or not isinstance(node, (int, float)):
        # YAML 1.1 reads "1e-9" (no dot) as a string: accept numeric strings.
        try:
            node = float(node) if isinstance(node, str) else None
        except (TypeError, ValueError, OverflowError):
            node = None
        if node is None:
            raise SceneError(field, f"expected a number, got {short(given)}",
                             fix or "give a number in SI units")
    try:
        value = float(node)
    except OverflowError:
        value = math.inf
    if not math.isfinite(value):
        raise SceneError(field, f"{short(given)} is not a finite number",
                         fix or "give a finite number")
    if integer and value != int(value):
        raise SceneError(field, f"{value} is not a whole number", fix or "give an integer")
    if positive and value <= 0:
        raise SceneError(field, f"{value:g} must be > 0", fix or "give a positive value")
    if nonneg and value < 0:
        raise SceneError(field, f"{value:g} must be >= 0", fix or "give a value >= 0")
    if lo is not None and value < lo:
        raise SceneError(field, f"{value:g} is below {lo:g}", fix or f"give a value >= {lo:g}")
    if hi is not None and value > hi:
        raise SceneError(field, f"{value:g} is above {hi:g}", fix or f"give a value <= {hi:g}")
    return int(value) if integer else value


def choice(value, field, options, what):
    """A value that must be one of ``options``, with a 'did you mean' on a typo."""
    if isinstance(value, str) and value in options:
        return value
    close = difflib.get_close_matches(str(value), options, n=1) if isinstance(value, str) else []
    hint = f"did you mean '{close[0]}'?" if close else f"use one of {', '.join(options)}"
    raise SceneError(field, f"unknown {what} {short(value)}", hint)
