"""The HTML page: self-contained, escaped, sortable markup (rendering checked in a browser test)."""

from __future__ import annotations

import re
import urllib.parse
from pathlib import Path

import pandas as pd
import pytest

from repbench.pipeline.suite import load_suite
from repbench.report.leaderboard import Results, encoder_table, metric_table, write_leaderboards

EVIL = "<script>alert('x')</script>"


def _results() -> Results:
    res = Results(load_suite("smoke"))
    encs = ["oracle", "random", "pca", "vae", EVIL]
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


def test_claims_table_names_the_task_when_there_are_several(tmp_path: Path) -> None:
    one = (write_leaderboards(_results(), tmp_path / "one") / "index.html").read_text()
    res = _results()
    res.rl_rows = [{**r, "train_steps": 100} for r in res.rl_rows]  # as real RL rows have
    for rows in (res.encoder_rows, res.metric_rows, res.rl_rows):
        rows.extend([{**r, "task": "U-v0"} for r in rows])
    two = (write_leaderboards(res, tmp_path / "two") / "index.html").read_text()

    def claims_head(html: str) -> list[str]:
        table = html[html.index("<table id='claims'>"):]
        return re.findall(r"<th class='txt'>([^<]*)</th>", table[:table.index("</thead>")])

    assert claims_head(one)[:2] == ["agent", "claim"]
    assert claims_head(two)[:3] == ["task", "agent", "claim"]
    body = two[two.index("<table id='claims'>"):]
    body = body[:body.index("</table>")]
    assert body.count("<td class='txt'>T-v0</td>") == body.count("<td class='txt'>U-v0</td>") > 0


def test_partial_runs_say_so_at_the_top(tmp_path: Path) -> None:
    write_leaderboards(_results(), tmp_path / "full")
    assert "Partial results" not in (tmp_path / "full" / "index.html").read_text()
    res = _results()
    res.missing = ["T-v0 sac × pca s2", "T-v0 sac × vae s0"]
    html = (write_leaderboards(res, tmp_path / "partial") / "index.html").read_text()
    assert "<b>Partial results:</b> 2 stages" in html
    assert html.index("Partial results") < html.index("Metric leaderboard")
    assert "id='missing'" in html


def _many_encoders(n: int = 12) -> Results:
    """More encoders than a legend can hold, with the smoothness extras of Fig. 5."""
    res = _results()
    for i in range(n):
        e = f"vae_{i}_lowkl" if i % 2 else f"enc_{i}"
        res.encoder_rows.append({"task": "T-v0", "encoder": e, "latent_dim": 4,
                                 "fit_time_s": 1, "family": "vae"})
        extras = {"latent_distance": {"offsets": [1, 2, 5], "mean_distance": [0.1, 0.2 * i, i]},
                  "histogram": {"bin_edges": [0.0, 0.5 + i, 2.0 + i], "counts": [3, 1 + i]},
                  "quantiles": {"0.95": 1.0 + i}}
        for m in ("ksg", "smoothness"):
            res.metric_rows.append({"task": "T-v0", "encoder": e, "metric": m, "value": 0.1 * i,
                                    "higher_is_better": True, "extras": extras})
        res.rl_rows += [{"task": "T-v0", "encoder": e, "agent": "sac", "seed": s,
                         "eval_return": 3.0 * i + s, "eval_success_rate": 0.0,
                         "curve_steps": [0, 50], "curve_return": [0, i]} for s in range(2)]
    return res


def test_figures_have_no_legend_with_an_entry_per_encoder(tmp_path: Path, monkeypatch) -> None:
    """23 encoders once made 23-line legends nobody could match to lines: legends now name
    families (at most 8), encoders are named in panel titles, labels and hover titles."""
    from repbench.report import figures

    saved: list = []
    real_save = figures.save_figure

    def capture(fig, path, *args, **kwargs):
        saved.append((Path(path).stem, [len(lg.get_texts()) for lg in (
            *fig.legends, *(ax.get_legend() for ax in fig.axes if ax.get_legend()))]))
        return real_save(fig, path, *args, **kwargs)

    monkeypatch.setattr(figures, "save_figure", capture)
    write_leaderboards(_many_encoders(), tmp_path)
    stems = {stem for stem, _ in saved}
    assert {"metric_vs_return", "learning_curves", "latent_distance", "smoothness_hist"} <= stems
    for stem, legends in saved:
        assert all(n <= 8 for n in legends), (stem, legends)


def test_metric_vs_return_names_every_point_on_hover(tmp_path: Path) -> None:
    """The central figure is inline SVG with one hover title per encoder × metric point."""
    res = _many_encoders()
    html = (write_leaderboards(res, tmp_path) / "index.html").read_text()
    assert (tmp_path / "figures" / "metric_vs_return.png").is_file()
    assert html.count("<svg ") == 1 and "<?xml" not in html
    svg = html[html.index("<svg "):html.index("</svg>")]
    titles = re.findall(r'<g id="mvr-\d+"[^>]*><title>([^<]*)</title>', svg)
    points = {(r["encoder"], r["metric"]) for r in res.metric_rows}
    assert len(titles) == len(points) == 5 * 2 + 12 * 2
    for enc, metric in points:
        name = enc.replace("<", "&lt;").replace(">", "&gt;").replace("'", "&#x27;")
        assert any(t.startswith(f"{name} (") and f"{metric}=" in t for t in titles), enc
    assert EVIL not in html


def test_per_encoder_figures_are_closed_by_default(tmp_path: Path) -> None:
    """Training curves and reconstructions of each encoder sit in a closed <details>."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    res = _results()
    for kind in ("loss_curves", "reconstructions"):
        for enc in ("pca", EVIL):
            png = tmp_path / "store" / f"{kind}_{len(res.figures_from_store)}.png"
            png.parent.mkdir(parents=True, exist_ok=True)
            fig = plt.figure(figsize=(3, 2))
            fig.savefig(png)
            plt.close(fig)
            res.figures_from_store[f"{kind} {enc}"] = png
    html = (write_leaderboards(res, tmp_path / "out") / "index.html").read_text()
    blocks = re.findall(r"<details>(.*?)</details>", html, re.S)
    per_encoder = [b for b in blocks if "<img " in b]
    assert len(per_encoder) == 4
    assert all(b.startswith("<summary>") and b.count("<img ") == 1 for b in per_encoder)
    assert "<summary>&lt;script&gt;alert(&#x27;x&#x27;)&lt;/script&gt;</summary>" in html
    assert not re.search(r"<details[^>]*\bopen\b", html)
    # linked, not inlined (they are most of a big board's bytes): each src is a file beside
    # the page, an encoder name with a "/" included
    for block in per_encoder:
        assert "data:image" not in block
        src = re.search(r'src="(figures/[^"]+)"', block).group(1)
        assert (tmp_path / "out" / urllib.parse.unquote(src.replace("&amp;", "&"))).is_file()
    assert html.count("data:image/png;base64,") >= 2  # the suite's figures stay inlined, open
    assert (tmp_path / "out" / "figures" / "reconstructions_pca.png").is_file()


def test_figures_of_two_tasks_never_pool_their_returns(tmp_path: Path) -> None:
    """With several tasks every scatter point is one task's metric against that task's own
    mean return (pooled, the first two-task board put each encoder's mean over both tasks
    against either task's metric), and the small multiples get a block per task."""
    res = _results()
    res.rl_rows = [{**r, "train_steps": 100} for r in res.rl_rows]
    res.encoder_rows.extend([{**r, "task": "U-v0"} for r in res.encoder_rows])
    res.metric_rows.extend([{**r, "task": "U-v0", "value": r["value"] + 100}
                            for r in res.metric_rows])
    res.rl_rows.extend([{**r, "task": "U-v0", "eval_return": 1000 + r["eval_return"]}
                        for r in res.rl_rows])
    html = (write_leaderboards(res, tmp_path) / "index.html").read_text()
    svg = html[html.index("<svg "):html.index("</svg>")]
    titles = re.findall(r'<g id="mvr-\d+"[^>]*><title>([^<]*)</title>', svg)
    assert len(titles) == 2 * len(res.metric_rows) // 2 == 20  # 2 tasks × 5 encoders × 2 metrics
    for t in titles:
        task, x, ret = re.search(r": (\w-v0) \w+=(-?[\d.]+), sac return=([\d.]+)", t).groups()
        assert (abs(float(x)) >= 96) == (task == "U-v0")   # U's metric values are shifted
        assert (float(ret) >= 1000) == (task == "U-v0"), t   # and so are its returns
    assert re.search(r"T-v0 · ksg ↑\s+ρ", svg) and re.search(r"U-v0 · ksg ↑\s+ρ", svg)


def test_sac_vs_ddpg_panels_take_each_agent_at_its_own_budget() -> None:
    """DDPG joined at 50k beside SAC at 10k: the figure's panel pairs each encoder's SAC mean at
    10k with its DDPG mean at 50k (it took both at SAC's 10k and drew an empty panel), and its
    axes name both budgets."""
    from repbench.report.figures import agent_agreement_panels

    res = _results()
    res.rl_rows = [{**r, "train_steps": 10000} for r in res.rl_rows]
    ddpg = [{**r, "agent": "ddpg", "train_steps": 50000, "eval_return": 2 * r["eval_return"]}
            for r in res.rl_rows]
    res.robustness = {"other_agent_rl": ddpg}
    [(sac, dd, title, xlabel, ylabel)] = agent_agreement_panels(res)
    assert set(sac) == set(dd) == {r["encoder"] for r in res.rl_rows}
    for enc in sac:
        assert dd[enc][0] == pytest.approx(2 * sac[enc][0])
    assert title == "T-v0"
    assert "10000 steps" in xlabel and "50000 steps" in ylabel


def test_the_answers_agreement_row_names_both_budgets_when_they_differ() -> None:
    """SAC at 10k against DDPG at 50k: the answer's row says so under the check's name (it was
    only in the row's hover text); a row at one budget gets no such line."""
    from repbench.report.answer import _checks_table
    from repbench.report.html_parts import VERDICT_COLORS, fmt

    detail = "; 20 encoders; holds if the 95 % interval is above 0.5, fails if below"
    checks = pd.DataFrame([
        {"check": "SAC vs DDPG ranking T-v0", "statistic": "Spearman ρ", "value": 0.79,
         "ci_low": 0.36, "ci_high": 0.90, "verdict": "inconclusive",
         "detail": "SAC at 10k steps, DDPG at 50k steps" + detail},
        {"check": "SAC vs DDPG ranking U-v0", "statistic": "Spearman ρ", "value": 0.5,
         "ci_low": 0.1, "ci_high": 0.9, "verdict": "inconclusive", "detail": detail[2:]}])
    page = "".join(_checks_table(checks, fmt, VERDICT_COLORS))
    row_t = page[page.index("ranking T-v0"):page.index("ranking U-v0")]
    assert "ranking T-v0<br><span class='ci'>SAC at 10k steps, DDPG at 50k steps</span>" in row_t
    row_u = page[page.index("ranking U-v0"):]
    assert "steps</span>" not in row_u[:row_u.index("</td>")]


def test_the_answers_agreement_row_says_when_the_other_runs_used_other_trainings() -> None:
    """The 10k-vs-30k runs of other (unrecorded) trainings of the encoders: the row says so
    under the check's name; a row whose runs used the board's encoders gets no such line."""
    from repbench.analysis.robustness import same_trainings
    from repbench.report.answer import _checks_table
    from repbench.report.html_parts import VERDICT_COLORS, fmt

    base = [{"task": "T-v0", "encoder": e, "agent": "sac", "encoder_weights": e}
            for e in ("a", "b", "c")]
    clause = same_trainings(base, [dict(r, encoder_weights=None) for r in base[:2]], "T-v0")
    assert clause is not None
    checks = pd.DataFrame([
        {"check": "SAC 10k vs 30k ranking T-v0", "statistic": "Kendall τ", "value": 0.5,
         "ci_low": -0.1, "ci_high": 0.9, "verdict": "inconclusive",
         "detail": f"10 encoders; {clause}"},
        {"check": "SAC 10k vs 30k ranking U-v0", "statistic": "Kendall τ", "value": 0.5,
         "ci_low": -0.1, "ci_high": 0.9, "verdict": "inconclusive", "detail": "10 encoders"}])
    page = "".join(_checks_table(checks, fmt, VERDICT_COLORS))
    row_t = page[page.index("ranking T-v0"):page.index("ranking U-v0")]
    assert ("ranking T-v0<br><span class='ci'>its RL used the board's trained encoders for 0 of 2 "
            "encoders</span>") in row_t
    row_u = page[page.index("ranking U-v0"):]
    assert "trained encoders" not in row_u[:row_u.index("</td>")]


def test_a_rebuild_leaves_no_figure_the_page_does_not_show(tmp_path: Path) -> None:
    """A board rebuilt from records copies each encoder's training curves from its earlier
    figures; when the board gains a task the copy is renamed ``<stem>_<enc>_<task>.png``, and the
    one-task original (which the page no longer shows) goes. A source outside the board stays."""
    out = tmp_path / "board"
    (out / "figures").mkdir(parents=True)
    old = out / "figures" / "loss_curves_vae.png"
    elsewhere = tmp_path / "store" / "loss_curves.png"
    elsewhere.parent.mkdir()
    png = (Path(__file__).parents[2] / "leaderboards" / "quick" / "figures"
           / "loss_curves_vae_PegInHole-v0.png").read_bytes()  # any real figure
    old.write_bytes(png)
    elsewhere.write_bytes(png)
    res = _results()
    res.figures_from_store = {"loss_curves vae T-v0": old, "loss_curves pca T-v0": elsewhere}
    write_leaderboards(res, out)
    names = sorted(p.name for p in (out / "figures").glob("loss_curves_*.png"))
    assert names == ["loss_curves_pca_T-v0.png", "loss_curves_vae_T-v0.png"]
    assert elsewhere.is_file()


def test_a_one_task_figure_is_not_taken_for_another_tasks_encoder(tmp_path: Path) -> None:
    """A records folder of several tasks' encoders never falls back to a figure named by the
    encoder alone (a one-task board's name): it belongs to whichever task that board had, so
    quick's SurfacePress-v0 VAE was shown PegInHole-v0's curves. With one task it is that task's."""
    from repbench.analysis.results import _encoder_figure

    board = tmp_path / "board"
    encoder_records = board / "records" / "encoder"
    encoder_records.mkdir(parents=True)
    (board / "figures").mkdir()
    one_task_name = board / "figures" / "loss_curves_vae.png"
    one_task_name.write_bytes(b"\x89PNG peg-in-hole's curves")
    peg = encoder_records / "PegInHole-v0.vae-0123abcd.json"
    peg.write_text("{}")
    record = {"_path": str(peg)}
    assert _encoder_figure(record, "loss_curves", "vae", "vae", "loss_curves.png") == one_task_name

    press = encoder_records / "SurfacePress-v0.vae-4567ef01.json"
    press.write_text("{}")
    for path in (peg, press):
        label = f"vae {path.name.split('.')[0]}"
        assert _encoder_figure({"_path": str(path)}, "loss_curves", label, "vae",
                               "loss_curves.png") is None
    own = board / "figures" / "loss_curves_vae_SurfacePress-v0.png"
    own.write_bytes(b"\x89PNG surface press's curves")
    assert _encoder_figure({"_path": str(press)}, "loss_curves", "vae SurfacePress-v0", "vae",
                           "loss_curves.png") == own
    # a board of that one task, rebuilt from this folder of several, labels it "vae" alone
    assert _encoder_figure({"_path": str(press), "task": {"name": "SurfacePress-v0"}},
                           "loss_curves", "vae", "vae", "loss_curves.png") == own


def test_the_shipped_quick_page_is_small_and_answers_first() -> None:
    """quick's page: at most 3 MB, its answer before any other table, the answer's best metric
    per task × agent that of claims.csv, and every figure it links shipped beside it."""
    import pandas as pd

    board = Path(__file__).parents[2] / "leaderboards" / "quick"
    page = (board / "index.html").read_text(encoding="utf-8")
    assert (board / "index.html").stat().st_size <= 3_000_000
    start, end = page.index("<section id='answer'>"), page.index("</section>")
    assert page.index("<table") > start and "<table id='ranking'" not in page[:end]
    claims = pd.read_csv(board / "claims.csv")
    best = claims[claims["claim"] == "Which metric predicts return best (learned encoders)?"]
    shown = re.findall(r"<tr data-task='([^']+)' data-agent='([^']+)' data-metric='([^']+)'>",
                       page[start:end])
    assert shown == [(r.task, r.agent, r.statistic.rsplit(": ", 1)[-1])
                     for r in best.itertuples()]
    linked = re.findall(r'<img [^>]*src="(figures/[^"]+)"', page)
    assert len(linked) >= 60 and all((board / src).is_file() for src in linked)


def test_every_shipped_encoder_family_is_drawn_in_its_own_style() -> None:
    """The figures tell families apart by colour and marker: every family a shipped encoder
    belongs to (the zoo's joint-embedding, control-objective and masked-autoencoder ones
    included) has its own style, and no two families share one."""
    from repbench import registry
    from repbench.report.families import _OTHER_STYLE, FAMILY_STYLE, display_family, family_style

    shown = {display_family(name, getattr(registry.encoders.get(name), "family", None))
             for name in registry.encoders.names()}
    assert {"joint embedding", "control objectives", "masked autoencoder"} <= shown
    assert all(family_style(f) != _OTHER_STYLE for f in shown), shown - set(FAMILY_STYLE)
    assert len(set(FAMILY_STYLE.values())) == len(FAMILY_STYLE)


def test_compact_svg_rounds_geometry_only_and_keeps_text_and_titles() -> None:
    """The inline figure is kept small (the page has a size budget): geometry to 0.1 px, no
    indentation, no spaces in styles; the text, hover titles and glyph transforms untouched."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from repbench.report.svg import compact_svg, figure_svg

    raw = ('<g id="p1"><path d="M 152.821138 144.922298 \n L -0.01 2.5 \n" '
           'style="fill: none; stroke: #3a3a3a"/>\n'
           '  <text x="10.123456" transform="scale(0.015625)">ρ = 0.4517</text></g>')
    assert compact_svg(raw) == (
        '<g id="p1"><path d="M 152.8 144.9\nL 0.0 2.5\n" style="fill:none;stroke:#3a3a3a"/>\n'
        '<text x="10.1" transform="scale(0.015625)">ρ = 0.4517</text></g>')
    fig, ax = plt.subplots()
    for i in range(200):
        ax.plot([i * 0.01234567], [i * 0.07654321], "o", gid=f"mvr-{i}")
    ax.set_title("T-v0 · ksg ↑")
    svg = figure_svg(fig, {f"mvr-{i}": f"point {i}: 0.123456" for i in range(200)})
    plt.close(fig)
    assert "T-v0 · ksg ↑</text>" in svg  # text as text, not glyph outlines
    assert '<g id="mvr-7"' in svg and "<title>point 7: 0.123456</title>" in svg
    assert not re.search(r'\bd="[^"]*\d\.\d{2}', svg)  # no geometry beyond 0.1 px


def _ranking_row(task: str, metric: str, group: str, rho: float, holm: float) -> dict:
    return {"task": task, "agent": "sac", "metric": metric, "group": group,
            "spearman_learned": rho, "spearman_learned_ci_low": rho - 0.2,
            "spearman_learned_ci_high": rho + 0.1, "spearman_learned_p_holm": holm,
            "of_ceiling": rho / 0.9}


def test_the_answer_opens_with_a_sentence_per_reader_naming_each_groups_best_metric() -> None:
    """Issue 55: the page's answer opens in words with the metric a simulator user should use
    and the one a real-robot user can, each with its ρ, interval and share of the ceiling."""
    from repbench.report.answer import opening_sentence

    ranking = pd.DataFrame([
        _ranking_row("A-v0", "task_cmi", "privileged", 0.78, 0.001),
        _ranking_row("A-v0", "ksg", "privileged", -0.2, 1.0),
        _ranking_row("A-v0", "rankme", "observable", 0.45, 0.02),
        _ranking_row("A-v0", "nesum", "observable", 0.30, 0.2),
        _ranking_row("B-v0", "regression", "privileged", 0.29, 0.6),
    ])
    said = opening_sentence(ranking)
    simulator, robot = said.split("A real-robot user")
    assert ("on A-v0 <code>task_cmi</code>, ρ 0.78 [0.58, 0.88], 87% of the noise ceiling"
            in simulator)
    assert "ksg" not in said and "nesum" not in said  # only each group's best
    # a best metric whose Holm p is not below 0.05 is said not to predict
    assert "on B-v0 <code>regression</code>" in simulator and "not significant" in simulator
    assert "on A-v0 <code>rankme</code>, ρ 0.45 [0.25, 0.55], 50% of" in robot
    assert "not significant" not in robot
    assert "None is scored on B-v0 yet." in robot  # the observable metrics are A-v0's only
    none = opening_sentence(ranking[ranking["group"] == "privileged"])
    assert "A real-robot user</b> (metrics that read only what a robot logs" in none
    assert none.endswith("has no metric on this board yet.</p>")
    # a reader none of whose best metrics predicts is not told to "use" one
    weak = opening_sentence(ranking[ranking["metric"] != "rankme"])
    robot = weak.split("A real-robot user")[1]
    assert "should use" not in robot
    assert ("has no metric shown to predict return yet; the best of its kind: on A-v0 "
            "<code>nesum</code>, ρ 0.30 [0.10, 0.40], 33% of the noise ceiling — not "
            "significant.") in robot
    assert opening_sentence(None) == "" and opening_sentence(pd.DataFrame()) == ""



def test_the_shipped_quick_page_opens_its_answer_in_words() -> None:
    board = Path(__file__).parents[2] / "leaderboards" / "quick"
    page = (board / "index.html").read_text(encoding="utf-8")
    start = page.index("<section id='answer'>")
    assert page.index("id='answer-words'") < page.index("<table", start)


def test_a_large_svg_is_inlined_as_its_png_with_a_link(tmp_path: Path,
                                                       monkeypatch: pytest.MonkeyPatch) -> None:
    """The page stays small: an SVG over the limit is shown as its PNG twin, the SVG linked."""
    from repbench.report import html_parts

    figures = tmp_path / "figures"
    figures.mkdir()
    svg, png = figures / "grid.svg", figures / "grid.png"
    svg.write_text("<svg xmlns='http://www.w3.org/2000/svg'>" + " " * 200 + "</svg>")
    png.write_bytes(b"\x89PNG small")
    assert html_parts.figure(svg, "grid").startswith("<div class='svgfig'")
    monkeypatch.setattr(html_parts, "MAX_INLINE_SVG", 100)
    said = html_parts.figure(svg, "grid")
    assert said.startswith('<img alt="grid" src="data:image/png;base64,')
    assert "<a href='figures/grid.svg'>grid.svg</a>" in said and "<svg" not in said
    png.unlink()  # no PNG twin: the SVG is inlined whatever its size
    assert html_parts.figure(svg, "grid").startswith("<div class='svgfig'")
