"""Matplotlib figures as inline SVG with hover text: each artist given a ``gid`` gets a
``<title>`` (the browser's tooltip) inside its ``<g id=…>``. Works offline, nothing to load."""

from __future__ import annotations

import html
import io
import os
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import matplotlib

_PROLOG = re.compile(r"^.*?(?=<svg\b)", re.S)
_METADATA = re.compile(r"\s*<metadata>.*?</metadata>", re.S)


def figure_svg(fig: Any, titles: Mapping[str, str]) -> str:
    """``fig`` as compact SVG text; ``titles`` maps an artist's gid to its hover text (escaped
    here). Ids are deterministic (fixed hash salt) so the page does not change between
    rebuilds. Text stays text (the browser's sans-serif font) instead of glyph outlines, and
    coordinates are kept to 0.1 px (:func:`compact_svg`): quick's ~1000-point
    ``metric_vs_return.svg`` is 1.03 MB instead of 1.36 MB with glyph outlines."""
    buf = io.StringIO()
    with matplotlib.rc_context({"svg.hashsalt": "repbench", "svg.fonttype": "none"}):
        fig.savefig(buf, format="svg", bbox_inches="tight", metadata={"Date": None})
    return add_titles(compact_svg(buf.getvalue()), titles)


_GEOMETRY = re.compile(r'\b(d|x|y|x1|x2|y1|y2|points)="([^"]*)"')
_DECIMAL = re.compile(r"-?\d+\.\d{2,}")


def compact_svg(svg: str) -> str:
    """``svg`` with the numbers of its geometry attributes (``d``, ``x``, ``y``, ...) rounded
    to one decimal, indentation dropped and ``style`` attributes without spaces. Text,
    titles and transforms (glyph scales) are left as they are."""

    def short(m: re.Match[str]) -> str:
        text = f"{float(m.group(0)):.1f}"
        return "0.0" if text == "-0.0" else text

    svg = _GEOMETRY.sub(lambda m: f'{m.group(1)}="{_DECIMAL.sub(short, m.group(2))}"', svg)
    svg = re.sub(r"[ \t]*\n[ \t]*", "\n", svg)
    return re.sub(r'style="([^"]*)"',
                  lambda m: 'style="' + re.sub(r"\s*([:;])\s*", r"\1", m.group(1)) + '"', svg)


def add_titles(svg: str, titles: Mapping[str, str]) -> str:
    """Insert ``<title>text</title>`` as the first child of each ``<g id="gid">``."""

    def put(m: re.Match[str]) -> str:
        gid = html.unescape(m.group(1))
        if gid not in titles:
            return m.group(0)
        return f"{m.group(0)}<title>{html.escape(titles[gid])}</title>"

    return re.sub(r'<g id="([^"]+)"[^>]*>', put, svg)


def inline_svg(svg: str) -> str:
    """SVG text ready to sit in an HTML page: no XML prolog, doctype or metadata (it holds the
    date); its natural size, shrunk to the width of its container when wider (the viewBox
    keeps the aspect ratio)."""
    svg = _METADATA.sub("", _PROLOG.sub("", svg, count=1), count=1)
    return svg.replace("<svg ", '<svg style="max-width:100%;height:auto" ', 1)


def write_svg(svg: str, path: str | os.PathLike[str]) -> Path:
    """Write SVG text to ``path`` (parent folders created); return the path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(svg, encoding="utf-8")
    return path
