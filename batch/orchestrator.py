"""The farm driver: pick this shard's assets, skip finished ones, run the rest, report.

Never imports bpy (under ``blender -b -P`` it only reads ``bpy.app.binary_path``
from the module Blender already loaded, to start more of the same Blender).
SIGINT/SIGTERM kill every running child's process group and exit; finished
assets stay, unfinished ones are ``.partial`` folders the next run redoes.
"""
from __future__ import annotations

import argparse
import signal
import sys
import threading
from collections import Counter
from concurrent.futures import ThreadPoolExecutor, as_completed
from pathlib import Path
from typing import Sequence

from tqdm import tqdm

from richmat_addon.core import dataset_index

from . import index, options, publish, runner
from .assets import Asset, collect
from .ledger import Ledger
from .pipeline import Commands, Job, Result, default_commands, process
from .sharding import Shard, parse_shard, shard_from_environment

LEDGER_DIR = "_ledger"


def select_shard(text: str | None) -> Shard:
    if text:
        return parse_shard(text)
    return shard_from_environment() or Shard(0, 1)


def _record(result: Result, shard: Shard, settings_hash: str) -> dict:
    return {"asset_id": result.asset.id, "source": result.asset.key, "status": result.status,
            "reason": result.reason, "attempts": result.attempts, "seconds": round(result.seconds, 2),
            "shard": shard.label, "settings_hash": settings_hash, **result.outcome,
            **({"notes": result.notes} if result.notes else {})}


def _run_one(asset: Asset, job: Job) -> Result:
    try:
        return process(asset, job)
    except Exception as exc:  # a bug or a full disk must not stop the other assets
        return Result(asset, "failed", f"orchestrator error: {type(exc).__name__}: {exc}")


def summary(results: Sequence[Result], skipped: int) -> str:
    counts = Counter(r.status for r in results)
    lines = [f"done {counts['done']}, skipped {skipped} (already rendered with these settings), "
             f"failed {counts['failed']}"]
    lines += [f"  FAILED {r.asset.key}: {r.reason}" for r in results if r.status == "failed"]
    return "\n".join(lines)


def _interrupt(signum: int, frame: object) -> None:
    raise KeyboardInterrupt(signal.Signals(signum).name)


def run(args: argparse.Namespace, commands: Commands | None = None) -> int:
    """Exit status: 0 when every asset is done or skipped, 1 when some failed, 130 when interrupted.

    ``commands`` replaces the child programs (tests use stand-ins for Blender and torch).
    """
    shard = select_shard(args.shard)
    settings = options.settings_of(args)
    settings_hash = settings.hash()
    output: Path = args.output
    output.mkdir(parents=True, exist_ok=True)
    job = Job(settings, settings_hash, output.resolve(), args.probe.resolve(), args.decoder.resolve(),
              args.timeout, args.retries, args.workers, args.max_triangles,
              commands or default_commands(args.blender, args.python))
    mine = [a for a in collect(args.input, exclude=job.output) if shard.owns(a.id)]
    todo = [a for a in mine if not publish.is_done(job.output, a.id, settings_hash)]
    ledger = Ledger(job.output / LEDGER_DIR / f"shard-{shard.label}.jsonl")
    for asset in mine:
        if asset not in todo:
            ledger.append({"asset_id": asset.id, "source": asset.key, "status": "skipped",
                           "reason": "finished with the same settings hash", "shard": shard.label,
                           "settings_hash": settings_hash})
    print(f"shard {shard.index}/{shard.count}: {len(mine)} assets, {len(mine) - len(todo)} already done, "
          f"{len(todo)} to render (settings {settings_hash})", file=sys.stderr)

    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, _interrupt)
    results: list[Result] = []
    pool = ThreadPoolExecutor(max_workers=args.workers)
    try:
        futures = [pool.submit(_run_one, asset, job) for asset in todo]
        with tqdm(total=len(todo), unit="asset", desc=f"shard {shard.label}", dynamic_ncols=True) as bar:
            for future in as_completed(futures):
                result = future.result()
                results.append(result)
                ledger.append(_record(result, shard, settings_hash))
                bar.update(1)
                bar.set_postfix_str(f"{result.status}: {result.asset.id}")
    except KeyboardInterrupt:
        pool.shutdown(wait=False, cancel_futures=True)
        runner.kill_all()
        print(f"interrupted; {summary(results, len(mine) - len(todo))}", file=sys.stderr)
        return 130
    pool.shutdown()
    print(summary(results, len(mine) - len(todo)), file=sys.stderr)
    _write_index(output)
    return 1 if any(r.status == "failed" for r in results) else 0


def _write_index(output: Path) -> None:
    records = index.write(output)
    print(f"{output / dataset_index.INDEX}: {len(records)} published assets", file=sys.stderr)


def main(argv: Sequence[str] | None = None) -> int:
    parser = options.build_parser()
    args = parser.parse_args(argv)
    if args.rebuild_index is not None:
        if not args.rebuild_index.is_dir():
            parser.error(f"--rebuild-index {args.rebuild_index}: no such folder")
        _write_index(args.rebuild_index)
        return 0
    try:
        options.validate(args)
    except ValueError as exc:
        parser.error(str(exc))
    return run(args)
