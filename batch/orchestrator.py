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

from torch_models.assets import dataset_index

from . import index, options, publish, runner
from .assets import Asset, Ignored, asset_id, scan
from .cores import CoreShares
from .ledger import Ledger
from .pipeline import Commands, Job, Result, check_fit_python, default_commands, device_problem, process
from .progress import progress
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


def summary(results: Sequence[Result], skipped: int, ignored: Sequence[Ignored] = ()) -> str:
    counts = Counter(r.status for r in results)
    sidecars = sum(i.sidecar for i in ignored)
    lines = [f"done {counts['done']}, skipped {skipped} (already rendered with these settings), "
             f"failed {counts['failed']}, ignored {len(ignored)} (not assets)"]
    lines += [f"  FAILED {r.asset.key}: {r.reason}" for r in results if r.status == "failed"]
    lines += [f"  IGNORED {i.key}: {i.reason}" for i in ignored if not i.sidecar]
    if sidecars:
        lines.append(f"  IGNORED {sidecars} texture, buffer or material file(s): read by the assets that refer "
                     "to them, not assets themselves (each is in the ledger)")
    return "\n".join(lines)


def _interrupt(signum: int, frame: object) -> None:
    raise KeyboardInterrupt(signal.Signals(signum).name)


def run(args: argparse.Namespace, commands: Commands | None = None) -> int:
    """Exit status: 0 when every asset is done or skipped, 1 when some failed or the run was refused
    (a ``--device`` that is not there), 130 when interrupted; a crash is recorded in the ledger and raised.

    ``commands`` replaces the child programs (tests use stand-ins for Blender and torch).
    """
    shard = select_shard(args.shard)
    settings = options.settings_of(args)
    settings_hash = settings.hash()
    output: Path = args.output
    output.mkdir(parents=True, exist_ok=True)
    job = Job(settings, settings_hash, output.resolve(), args.probe.resolve(), args.decoder.resolve(),
              args.timeout, args.retries, args.workers, args.max_triangles,
              commands or default_commands(args.blender, args.python), CoreShares(args.workers))
    ledger = Ledger(job.output / LEDGER_DIR / f"shard-{shard.label}.jsonl")
    try:
        return _run(args, job, shard, ledger)
    except Exception as exc:  # the run itself broke (a bug, a full disk): say so where the farm looks
        _abort(ledger, shard, settings_hash, f"the run crashed: {type(exc).__name__}: {exc}")
        raise


def _abort(ledger: Ledger, shard: Shard, settings_hash: str, reason: str) -> None:
    """A ledger line for the whole run (no asset): it stopped, and why."""
    ledger.append({"asset_id": None, "source": None, "status": "aborted", "reason": reason, "shard": shard.label,
                   "settings_hash": settings_hash})


def _run(args: argparse.Namespace, job: Job, shard: Shard, ledger: Ledger) -> int:
    settings_hash = job.settings_hash
    base = {"shard": shard.label, "settings_hash": settings_hash}
    problem = device_problem(job)
    if problem is not None:
        _abort(ledger, shard, settings_hash, problem)
        print(f"aborted: {problem}", file=sys.stderr)
        return 1
    found, passed_over = scan(args.input, exclude=job.output)
    mine = [a for a in found if shard.owns(a.id)]
    ignored = [i for i in passed_over if shard.owns(asset_id(i.key))]
    for item in ignored:
        ledger.append({"asset_id": asset_id(item.key), "source": item.key, "status": "ignored",
                       "reason": item.reason, **base})
    todo = [a for a in mine if not publish.is_done(job.output, a.id, settings_hash)]
    for asset in mine:
        if asset not in todo:
            ledger.append({"asset_id": asset.id, "source": asset.key, "status": "skipped",
                           "reason": "finished with the same settings hash", **base})
    print(f"shard {shard.index}/{shard.count}: {len(mine)} assets, {len(mine) - len(todo)} already done, "
          f"{len(todo)} to render, {len(ignored)} input files ignored (settings {settings_hash})", file=sys.stderr)

    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, _interrupt)
    results: list[Result] = []
    pool = ThreadPoolExecutor(max_workers=args.workers)
    bar = progress(len(todo), f"shard {shard.label}")
    try:
        futures = [pool.submit(_run_one, asset, job) for asset in todo]
        for future in as_completed(futures):
            result = future.result()
            results.append(result)
            ledger.append(_record(result, shard, settings_hash))
            bar.step(result.status, result.asset.id)
    except KeyboardInterrupt:
        pool.shutdown(wait=False, cancel_futures=True)
        runner.kill_all()
        print(f"interrupted; {summary(results, len(mine) - len(todo), ignored)}", file=sys.stderr)
        return 130
    finally:
        bar.close()
    pool.shutdown()
    print(summary(results, len(mine) - len(todo), ignored), file=sys.stderr)
    _write_index(job.output)
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
        commands = default_commands(args.blender, args.python)
        check_fit_python(commands.python)
    except ValueError as exc:
        parser.error(str(exc))
    return run(args, commands)
