"""The case study's report as text: report blocks, and their Markdown and self-contained HTML.

The report's content (:mod:`orchestration.case_study.case_report`) is a list of :class:`Block`;
this module only renders them, and formats numbers for them.
"""

from __future__ import annotations

import base64
import html
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

TIE = 0.01  # relative difference below which two peaks are called a tie


@dataclass
class Block:
    """One report element: heading, paragraph, table, image or bullet list."""

    kind: str
    text: str = ""
    level: int = 2
    header: list[str] = field(default_factory=list)
    rows: list[list[str]] = field(default_factory=list)
    items: list[str] = field(default_factory=list)


def fmt(v: Any, digits: int = 3) -> str:
    """A number for a table: 3 significant digits, whole numbers from 1000 on (``3340``, never ``3.34e+03`` beside
    ``10073``); – for missing or not finite."""
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "–"
    if isinstance(v, float | np.floating):
        return f"{v:.{digits}g}" if abs(v) < 10 ** digits else f"{v:.0f}"
    return str(v)


def pct(a: float, b: float) -> str:
    """a against b in per cent, signed (``+3.5 %``)."""
    return f"{100 * (a / b - 1):+.1f} %"


def compare(a: float, b: float) -> str:
    """'beats' if a is lower than b by more than TIE, 'loses' if higher, else 'ties' (lower is better)."""
    if not (math.isfinite(a) and math.isfinite(b)) or b == 0:
        return "n/a"
    r = a / b - 1
    return "beats" if r < -TIE else "loses to" if r > TIE else "ties with"


def to_markdown(blocks: list[Block]) -> str:
    """Markdown text of the report blocks."""
    out: list[str] = []
    for bl in blocks:
        if bl.kind == "h":
            out.append("#" * bl.level + " " + bl.text)
        elif bl.kind == "p":
            out.append(bl.text)
        elif bl.kind == "ul":
            out.append("\n".join(f"* {it}" for it in bl.items))
        elif bl.kind == "table":
            out.append("\n".join(["| " + " | ".join(bl.header) + " |", "|" + "---|" * len(bl.header),
                                  *("| " + " | ".join(row) + " |" for row in bl.rows)]))
        elif bl.kind == "img":
            out.append(f"![{bl.items[0]}]({bl.text})\n\n*{bl.items[0]}*")
    return "\n\n".join(out) + "\n"


def _html_inline(text: str) -> str:
    t = html.escape(text)
    t = re.sub(r"\*\*(.+?)\*\*", r"<b>\1</b>", t)
    return re.sub(r"`(.+?)`", r"<code>\1</code>", t)


_NUMBER = re.compile(r"^[+\-−]?(\d[\d.,]*|\.\d+)([eE][+\-]?\d+)?( ?(%|s|A|mm|m/s²|N))?$")


def _numeric(cells: list[str]) -> bool:
    """Whether a table column holds numbers (with a unit at most; – for a missing one): drawn right-aligned."""
    values = [c.strip() for c in cells if c.strip() not in ("", "–", "-")]
    return bool(values) and all(_NUMBER.match(v) for v in values)


def _table_html(header: list[str], rows: list[list[str]]) -> str:
    """A table whose number columns are right-aligned, header included, and every other column left-aligned."""
    right = [_numeric([str(row[k]) for row in rows if k < len(row)]) for k in range(len(header))]

    def cell(tag: str, k: int, text: str) -> str:
        return f"<{tag} class='{'n' if k < len(right) and right[k] else 't'}'>{_html_inline(text)}</{tag}>"

    head = "".join(cell("th", k, h) for k, h in enumerate(header))
    body = "".join("<tr>" + "".join(cell("td", k, str(c)) for k, c in enumerate(row)) + "</tr>" for row in rows)
    return f"<table><tr>{head}</tr>{body}</table>"


def to_html(blocks: list[Block], folder: Path) -> str:
    """Self-contained HTML (figures inline as base64 PNG)."""
    parts = ["<!DOCTYPE html><html><head><meta charset='utf-8'><title>case study</title><style>"
             "body{font-family:sans-serif;max-width:1100px;margin:2em auto;line-height:1.4}"
             "table{border-collapse:collapse;font-size:0.85em;margin:1em 0}td,th{border:1px solid #bbb;"
             "padding:2px 6px}.n{text-align:right}.t{text-align:left}"
             "img{max-width:100%}figcaption{font-style:italic}</style></head><body>"]
    for bl in blocks:
        if bl.kind == "h":
            parts.append(f"<h{bl.level}>{_html_inline(bl.text)}</h{bl.level}>")
        elif bl.kind == "p":
            parts.append(f"<p>{_html_inline(bl.text)}</p>")
        elif bl.kind == "ul":
            parts.append("<ul>" + "".join(f"<li>{_html_inline(it)}</li>" for it in bl.items) + "</ul>")
        elif bl.kind == "table":
            parts.append(_table_html(list(bl.header), [list(row) for row in bl.rows]))
        elif bl.kind == "img":
            data = base64.b64encode((folder / bl.text).read_bytes()).decode()
            parts.append(f"<figure><img src='data:image/png;base64,{data}'><figcaption>"
                         f"{_html_inline(bl.items[0])}</figcaption></figure>")
    parts.append("</body></html>\n")
    return "\n".join(parts)
