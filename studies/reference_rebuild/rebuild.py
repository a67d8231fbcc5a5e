"""Rebuild quick's reference one encoder at a time (issue 54), so that a rebuild cut off anywhere
loses at most the encoder in progress.

Each encoder runs as a one-encoder copy of quick (the same stage keys: a stage's key is its
config, never the suite's encoder list) on one task, into a shared store; several lanes can run
side by side on one store (the store locks each stage). ``fold`` then moves every encoder whose
latents and SAC seeds are all in the store into the repo: its latents into
``leaderboards/quick/latents`` (``repbench export-latents``) and its encoder, latents, metric and
RL records into ``leaderboards/quick/records``, replacing the older ones of the same identity.

    python studies/reference_rebuild/rebuild.py run --store S --task PegInHole-v0 --lane 0 --lanes 2
    python studies/reference_rebuild/rebuild.py fold --store S --task PegInHole-v0

``run --no-rl-for ENC`` skips the RL of encoders whose committed RL records already belong to the
weights the rebuild reproduces (``fold`` checks ``encoder_weights`` and refuses a mismatch).
"""

from __future__ import annotations

import argparse
import re
import shutil
import sys
import tempfile
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
QUICK = ROOT / "repbench" / "suites" / "quick.toml"
BOARD = ROOT / "leaderboards" / "quick"
KINDS = ("encoder", "latents", "metric", "rl")


def one_encoder_suite(encoder: str, folder: Path) -> Path:
    """quick's suite file with ``encoders = [encoder]``."""
    text = QUICK.read_text(encoding="utf-8")
    text, n = re.subn(r"(?ms)^encoders = \[.*?^\]", f'encoders = ["{encoder}"]', text)
    assert n == 1, "quick.toml's encoders list not found"
    # the other encoders' [encoder_params.<name>] tables: a suite refuses params of an encoder
    # it does not run
    others = r"(?ms)^\[encoder_params\.(?!" + re.escape(encoder) + r"\])[^\]]+\]\n.*?(?=^\[|\Z)"
    text = re.sub(others, "", text)
    path = folder / f"quick_{encoder}.toml"
    path.write_text(text, encoding="utf-8")
    return path


def quick_encoders() -> list[str]:
    from repbench.pipeline.suite import load_suite

    return list(load_suite("quick").encoders)


def run(args: argparse.Namespace) -> None:
    from repbench.pipeline.runner import run_suite

    names = args.encoder or quick_encoders()
    mine = names[args.lane::args.lanes]
    with tempfile.TemporaryDirectory() as tmp:
        for enc in mine:
            print(f"== {args.task} {enc}", flush=True)
            run_suite(one_encoder_suite(enc, Path(tmp)), store=args.store,
                      out=Path(tmp) / "board", workers=args.workers, tasks=[args.task],
                      no_rl=enc in (args.no_rl_for or []), progress=False)


def fold(args: argparse.Namespace) -> None:
    """Export the latents and copy the records of every encoder complete in the store."""
    from repbench.analysis.results import load_records, write_records
    from repbench.pipeline.latents_export import export_latents
    from repbench.pipeline.store import Store

    store = Store(args.store)
    new = [r for r in load_records(store) if r["task"]["name"] == args.task]
    old = [r for r in load_records(BOARD / "records") if r["task"]["name"] == args.task]
    folded = []
    for enc in args.encoder or quick_encoders():
        mine = [r for r in new if (r.get("encoder") or {}).get("name") == enc]
        kinds = {r["kind"] for r in mine}
        rl_new = [r for r in mine if r["kind"] == "rl"]
        rl_old = [r for r in old if r["kind"] == "rl"
                  and (r.get("encoder") or {}).get("name") == enc]
        weights = {r.get("encoder_weights") for r in mine}
        if not {"encoder", "latents", "metric"} <= kinds:
            continue
        if len(weights) != 1:
            sys.exit(f"{enc}: the store's records carry several encoder weights {weights}")
        # RL not rerun: the committed RL must be of these very weights
        if len(rl_new) < 3 and (not rl_old
                                or {r.get("encoder_weights") for r in rl_old} != weights):
            print(f"-- {enc}: waiting for its RL (committed RL is of other weights)")
            continue
        # same identities, same file names: the older records of this encoder are replaced
        write_records_into(mine, BOARD / "records", write_records)
        export_latents("quick", store=args.store, out=BOARD / "latents", tasks=[args.task],
                       encoders=[enc])
        folded.append(enc)
    if folded:  # the data the shipped latents were computed on
        write_records_into([r for r in new if not r.get("encoder")], BOARD / "records",
                           write_records)
    print("folded:", " ".join(folded) or "none")


def write_records_into(records: list[dict], folder: Path, write_records: Any) -> None:
    """Write ``records`` into ``folder`` without touching its other records (write_records
    replaces a whole folder's records: it writes into a scratch folder here, then copies)."""
    with tempfile.TemporaryDirectory() as tmp:
        for path in write_records(records, Path(tmp)):
            target = folder / path.relative_to(tmp)
            target.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(path, target)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    for name in ("run", "fold"):
        p = sub.add_parser(name)
        p.add_argument("--store", required=True)
        p.add_argument("--task", required=True)
        p.add_argument("--encoder", action="append", help="only these (default: quick's)")
        if name == "run":
            p.add_argument("--lane", type=int, default=0)
            p.add_argument("--lanes", type=int, default=1)
            p.add_argument("--workers", type=int, default=1)
            p.add_argument("--no-rl-for", action="append")
    args = parser.parse_args()
    (run if args.command == "run" else fold)(args)


if __name__ == "__main__":
    main()
