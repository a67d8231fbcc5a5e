"""Small HTML pieces the leaderboard page and its answer section share: number formatting,
figures (SVG inline, PNG as a data URI) and the verdict colours. A leaf module, so that
:mod:`repbench.report.report_html` and :mod:`repbench.report.answer` both import it without
importing each other."""

from __future__ import annotations

import base64
import html
import math
from pathlib import Path
from typing import Any

VERDICT_COLORS = {"reproduced": "#dff5e1", "not reproduced": "#fbe0e0",
                  "inconclusive": "#f3f0dc", "significant": "#dff5e1",
                  "not significant": "#f3f0dc", "holds": "#dff5e1",
                  "does not hold": "#fbe0e0", "holds, too wide": "#f3f0dc"}


def fmt(v: Any) -> str:
    """A value as a table shows it: 4 significant digits, '–' for missing or non-finite."""
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "–"
    if isinstance(v, float):
        return f"{v:.4g}"
    return str(v)


def fmt2(v: Any) -> str:
    """A statistic as the answer shows it: two decimals, '–' for missing or non-finite."""
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "–"
    if isinstance(v, (int, float)) and not isinstance(v, bool):
        return f"{float(v):.2f}"
    return str(v)


def img(path: Path, alt: str) -> str:
    """A PNG file as an inlined ``<img>`` (data URI)."""
    data = base64.b64encode(path.read_bytes()).decode()
    return f'<img alt="{html.escape(alt)}" src="data:image/png;base64,{data}">'


#: An SVG larger than this (bytes) is not inlined when its PNG twin exists: the page inlines the
#: PNG and links the SVG (quick's metric–return grid with the metric search's 12 candidates is
#: 1.4 MB of SVG against 0.34 MB of PNG, and the page must stay small).
MAX_INLINE_SVG = 1_000_000


def figure(path: Path, alt: str) -> str:
    """A figure for the page: SVG inline (its hover titles work), anything else as an image.
    An SVG over :data:`MAX_INLINE_SVG` with a PNG beside it is inlined as that PNG, with a link
    to the SVG (relative to the page's folder, where the figures are) for the hover titles."""
    if path.suffix == ".svg":
        png = path.with_suffix(".png")
        if path.stat().st_size > MAX_INLINE_SVG and png.is_file():
            link = f"{path.parent.name}/{path.name}"
            return (img(png, alt) + f"<p class='sub'>Too large to inline with its hover labels: "
                    f"<a href='{html.escape(link)}'>{html.escape(path.name)}</a> names every "
                    "point's encoder.</p>")
        return f"<div class='svgfig' role='img' aria-label='{html.escape(alt)}'>" + (
            path.read_text(encoding="utf-8")) + "</div>"
    return img(path, alt)
