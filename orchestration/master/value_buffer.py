"""Prepared value-reference and value arrays for the Real fast path of FMU units."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np


@dataclass
class ValueBuffer:
    """Value references and a C double array (with a numpy view on it) for one prepared reference set."""

    vrs: Any
    buf: Any
    view: np.ndarray
    n: int
