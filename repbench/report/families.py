"""Encoder families as the figures show them: one colour and marker per family, so a reader
matches a point or a panel to a kind of encoder without a 34-entry legend.

The plugin's ``family`` attribute says ``vae``, ``contrastive``, ``supervised``,
``joint_embedding``, ``control_objective``, ``mae`` or ``baseline``; the VAE family is split
here by name into the paper's VAEs, their low-KL twins (``<name>_lowkl``) and the ablations of
those twins (``<name>_lowkl_<variant>``).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any

from matplotlib.lines import Line2D

#: display family → (colour, marker); the order is the legend's and the panels' order.
FAMILY_STYLE: dict[str, tuple[str, str]] = {
    "paper VAEs": ("#1f77b4", "o"),
    "low-KL twins": ("#ff7f0e", "D"),
    "ablations": ("#9467bd", "v"),
    "contrastive": ("#2ca02c", "^"),
    "supervised": ("#d62728", "P"),
    # the zoo (encoders/joint_embedding.py, control_objectives.py, mae.py)
    "joint embedding": ("#17becf", "*"),
    "control objectives": ("#bcbd22", "h"),
    "masked autoencoder": ("#e377c2", "p"),
    "baselines": ("#3a3a3a", "s"),
}
_OTHER_STYLE = ("#8c564b", "X")
_PLUGIN_FAMILY = {"baseline": "baselines", "contrastive": "contrastive",
                  "supervised": "supervised", "joint_embedding": "joint embedding",
                  "control_objective": "control objectives", "mae": "masked autoencoder"}


def display_family(encoder: str, family: str | None) -> str:
    """The family an encoder is drawn as, from its plugin ``family`` and its name."""
    if family == "vae":
        if encoder.endswith("_lowkl"):
            return "low-KL twins"
        return "ablations" if "_lowkl_" in encoder else "paper VAEs"
    return _PLUGIN_FAMILY.get(str(family), str(family or "learned"))


def family_style(family: str) -> tuple[str, str]:
    """(colour, marker) of a display family; unknown families share one extra style."""
    return FAMILY_STYLE.get(family, _OTHER_STYLE)


def encoder_families(res: Any) -> dict[str, str]:
    """encoder → display family for every encoder of ``res`` (a :class:`Results`)."""
    plugin = _families(res)
    for r in res.rl_rows:
        plugin.setdefault(r["encoder"], _family(r["encoder"]))
    return {n: display_family(n, f) for n, f in plugin.items()}


def family_order(families: Mapping[str, str], encoders: Iterable[str]) -> list[str]:
    """``encoders`` sorted by display family (legend order), then by name."""
    rank = {f: i for i, f in enumerate(FAMILY_STYLE)}
    return sorted(encoders, key=lambda e: (rank.get(families.get(e, ""), len(rank)), e))


def family_legend(fig: Any, families: Iterable[str], y: float = 1.0) -> Any:
    """One small legend (a row of family markers) centred at the top of ``fig``."""
    present = [f for f in (*FAMILY_STYLE, *sorted(set(families) - set(FAMILY_STYLE)))
               if f in set(families)]
    handles = [Line2D([], [], ls="none", marker=family_style(f)[1], color=family_style(f)[0],
                      ms=6, label=f) for f in present]
    return fig.legend(handles=handles, loc="lower center", bbox_to_anchor=(0.5, y),
                      ncol=len(handles), fontsize=9, frameon=False, handletextpad=0.3,
                      columnspacing=1.4)


def _family(encoder: str) -> str:
    """An encoder's family from its class (records written before families were stored)."""
    from repbench.registry import encoders

    try:
        return str(getattr(encoders.get(encoder), "family", "learned"))
    except Exception:  # unknown or unimportable plugin: count it as learned
        return "learned"


def _families(res: Any) -> dict[str, str]:
    """encoder → family for every encoder in the records."""
    families = {r["encoder"]: r.get("family") or _family(r["encoder"])
                for r in res.encoder_rows}
    for r in res.metric_rows:
        families.setdefault(r["encoder"], _family(r["encoder"]))
    return families


def learned_encoders(res: Any) -> dict[str, list[str]]:
    """task → the learned encoders (plugin family not ``baseline``) with metric records in
    ``res``, sorted: the encoders the within-learned statistics are over."""
    from repbench.analysis.correlation import BASELINE_FAMILY

    families = _families(res)
    out: dict[str, set[str]] = {}
    for r in res.metric_rows:
        if families.get(r["encoder"], "learned") != BASELINE_FAMILY:
            out.setdefault(r["task"], set()).add(r["encoder"])
    return {t: sorted(e) for t, e in sorted(out.items())}
