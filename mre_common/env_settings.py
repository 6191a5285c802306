"""Numbers the user sets in ``MRE_COSIM_*`` environment variables, parsed once and refused when meaningless.

A value that does not parse, is not finite or is outside its domain is an :class:`EnvSettingError`
naming the variable and the value; it is never ignored or turned into another number.
"""

from __future__ import annotations

import math
import os


class EnvSettingError(ValueError):
    """An environment variable whose value means nothing; the message names the variable."""


def env_megabytes(name: str, default_mb: float | None, *, zero_ok: bool = False) -> int | None:
    """Bytes given in MiB by ``$name`` (``default_mb`` when unset or empty; None if that is None).

    The value must be a finite number above 0 (or 0 itself with ``zero_ok``).
    """
    text = os.environ.get(name, "").strip()
    if not text:
        return None if default_mb is None else int(default_mb * 2**20)
    try:
        value = float(text)
    except ValueError:
        raise EnvSettingError(f"environment variable {name}={text!r} is not a number (MiB)") from None
    if not math.isfinite(value) or value < 0 or (value == 0 and not zero_ok):
        bound = "0 or more" if zero_ok else "more than 0"
        raise EnvSettingError(f"environment variable {name}={text!r}: give a finite number of MiB, {bound}")
    if value * 2**20 > 2**62:
        raise EnvSettingError(f"environment variable {name}={text!r}: more than 2^62 bytes")
    return int(value * 2**20)


def env_switch(name: str, default: bool) -> bool:
    """An on/off switch ``$name``: ``1`` on, ``0`` off, unset or empty ``default``; anything else is refused."""
    text = os.environ.get(name, "").strip()
    if not text:
        return default
    if text not in ("0", "1"):
        raise EnvSettingError(f"environment variable {name}={text!r}: give 1 (on) or 0 (off)")
    return text == "1"
