"""Issue 43, item 2, part 2: the committed SurfacePress-v0 numbers of the encoders that differ in
their inputs and in the image loss, in one table (no training, < 1 s).

Reads ``leaderboards/quick/surface_press/encoders.csv`` (metric values, intervals and SAC return)
and, from ``leaderboards/quick/records/``, the extras it does not carry: ``task_r2_gain``'s
R² of the complementary task state from z ⊕ robot state (``r2_z_and_robot``; robot state alone
``r2_robot_only``) and the per-seed SAC returns.

    python studies/surface_press_why/records.py
"""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd

ROOT = Path(__file__).resolve().parents[2]
BOARD = ROOT / "leaderboards/quick"
TASK = "SurfacePress-v0"
ENCODERS = ("vae_lowkl", "vae_lowkl_image", "vae_lowkl_ft_proprio", "supervised",
            "supervised_task", "random", "proprio_only", "oracle", "oracle_task")
METRICS = ("task_cmi", "task_r2_gain", "task_probe", "action_probe")


def record(kind: str, pattern: str) -> list[dict]:
    return [json.loads(p.read_text()) for p in sorted((BOARD / "records" / kind).glob(pattern))]


def extras(encoder: str) -> dict[str, object]:
    gain = record("metric", f"{TASK}.{encoder}.task_r2_gain-*.json")[0]["values"]["extras"]
    returns = [r["values"]["eval_return"] for r in record("rl", f"{TASK}.{encoder}.sac.s*.json")]
    return {"r2_z_and_robot": gain["r2_z_and_robot"], "r2_robot_only": gain["r2_robot_only"],
            "sac_seeds": " / ".join(f"{x:.0f}" for x in returns)}


def interval(df: pd.DataFrame, name: str, digits: int) -> pd.Series:
    fmt = f"{{:.{digits}f}} [{{:.{digits}f}}, {{:.{digits}f}}]"
    return df.apply(lambda r: fmt.format(r[name], r[f"{name}_ci_low"], r[f"{name}_ci_high"]),
                    axis=1)


def table() -> pd.DataFrame:
    df = pd.read_csv(BOARD / "surface_press/encoders.csv").set_index("encoder").loc[list(ENCODERS)]
    out = pd.DataFrame(index=df.index)
    for m in METRICS:
        out[m] = interval(df, m, 3)
    extra = pd.DataFrame([extras(e) for e in ENCODERS], index=df.index)
    out["r2(c | z+r)"] = extra["r2_z_and_robot"].round(3)
    out["sac_return"] = interval(df, "sac_return", 0)
    out["sac_seeds"] = extra["sac_seeds"]
    out["sac_success"] = df["sac_success"].round(2)
    print(f"r2(c | r) alone (task_r2_gain's floor): {extra['r2_robot_only'].iloc[0]:.3f}")
    return out


def markdown(df: pd.DataFrame) -> str:
    cols = [df.index.name or "", *df.columns]
    lines = ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    lines += ["| " + " | ".join([str(i), *map(str, r)]) + " |" for i, r in df.iterrows()]
    return "\n".join(lines)


if __name__ == "__main__":
    print(markdown(table()))
