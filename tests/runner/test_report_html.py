"""The HTML page: self-contained, escaped, sortable markup (rendering checked in a browser test)."""

from __future__ import annotations

import re
from pathlib import Path

from repbench.pipeline.suite import load_suite
from repbench.report.leaderboard import Results, encoder_table, metric_table, write_leaderboards

EVIL = "<script>alert('x')</script>"


def _results() -> Results:
    res = Results(load_suite("smoke"))
    encs = ["oracle", "random", "pca", EVIL]
    for i, e in enumerate(encs):
        res.encoder_rows.append({"task": "T-v0", "encoder": e, "latent_dim": 4, "fit_time_s": 1})
        for m, hib in (("ksg", True), ("regression", False)):
            v = float(i) if hib else float(-i)
            res.metric_rows.append({"task": "T-v0", "encoder": e, "metric": m, "value": v,
                                    "higher_is_better": hib, "ci_low": v - 0.1,
                                    "ci_high": v + 0.1, "extras": {}})
        for s in range(2):
            res.rl_rows.append({"task": "T-v0", "encoder": e, "agent": "sac", "seed": s,
                                "eval_return": 10.0 * i + s, "eval_success_rate": 0.1 * i,
                                "curve_steps": [0, 50, 100], "curve_return": [0, i, 2 * i],
                                "curve_success": [0, 0, 0]})
    res.provenance = {"suite": "smoke", "description": EVIL,
                      "directions": {"ksg": True, "regression": False}}
    return res


def test_tables_have_one_row_per_encoder_and_per_metric() -> None:
    res = _results()
    enc = encoder_table(res)
    assert enc["encoder"].iloc[0] == EVIL  # sorted by return, best first
    assert {"ksg", "ksg_ci_low", "regression", "sac_return", "sac_return_ci_low",
            "sac_success", "sac_seeds"} <= set(enc.columns)
    met = metric_table(res, n_bootstrap=50)
    assert len(met) == 2
    assert (met["spearman"] > 0.99).all()  # both metrics rank as RL does, direction respected


def test_page_is_self_contained_and_escaped(tmp_path: Path) -> None:
    out = write_leaderboards(_results(), tmp_path)
    html = (out / "index.html").read_text()
    assert EVIL not in html and "&lt;script&gt;alert(" in html
    assert not re.search(r"""(src|href)=["']https?://""", html)  # nothing from the network
    assert html.count("data:image/png;base64,") >= 2
    assert 'class="sortable"' in html
    assert (out / "encoders.csv").is_file() and (out / "metrics.csv").is_file()
    assert (out / "figures" / "metric_vs_return.png").is_file()


def test_page_has_one_table_per_id(tmp_path: Path) -> None:
    """Each table id appears once (a merge once left two encoder tables on the page)."""
    write_leaderboards(_results(), tmp_path)
    html = (tmp_path / "index.html").read_text()
    assert html.count('id="encoders"') == 1 and html.count('id="metrics"') == 1
    assert "95% t-interval" not in html


def test_page_and_csv_carry_the_checked_claims(tmp_path: Path) -> None:
    write_leaderboards(_results(), tmp_path)
    html = (tmp_path / "index.html").read_text()
    claims = (tmp_path / "claims.csv").read_text()
    assert "Paper claims, checked" in html and "id='claims'" in html
    assert "correlates positively with return" in claims
    assert "Which metric predicts return best (all encoders)?" in claims
    assert html.index("Paper claims, checked") < html.index("Which encoder is best?")


def test_partial_runs_say_so_at_the_top(tmp_path: Path) -> None:
    write_leaderboards(_results(), tmp_path / "full")
    assert "Partial results" not in (tmp_path / "full" / "index.html").read_text()
    res = _results()
    res.missing = ["T-v0 sac × pca s2", "T-v0 sac × vae s0"]
    html = (write_leaderboards(res, tmp_path / "partial") / "index.html").read_text()
    assert "<b>Partial results:</b> 2 stages" in html
    assert html.index("Partial results") < html.index("Metric leaderboard")
    assert "id='missing'" in html
