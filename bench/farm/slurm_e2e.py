"""Issue 29, item 1: the committed sbatch file on a real SLURM, with a task cancelled mid-asset and requeued.

A farm operator cannot trust docs/slurm_render_dataset.sbatch until it has run on a
scheduler. This bench makes a one-node cluster on this machine from Debian's
``slurm-wlm`` and ``munge`` (it installs nothing: without them it prints the install
command and exits): a slurm.conf for this host, munged, slurmctld and slurmd run as
the current user with their key, socket, state, spool and logs in a work folder.
It submits the sbatch file as committed, as an array over the sample models plus
broken files, with small render settings as trailing arguments (and 1 CPU / 2 GB
per task on the sbatch command line, which leaves the file as it is). When the task
owning the most good assets has published one and is inside another (its
``.partial`` folder holds the prepared scene: the fit or render is running), it is
cancelled (``scancel``) and requeued (``scontrol requeue``). When the array is done
it checks that every good asset is published exactly once, every bad one is in the
ledgers with its reason, no ``.partial`` is left, and that the shards' ledgers merge
to what one process without shards (same inputs, same settings) records. It stops
the daemons it started, also on failure.

    python -m bench.farm.slurm_e2e [--work DIR] [--tasks 3] [--out docs/reports/slurm_e2e.json]

Per-task states come from ``scontrol show job`` and the jobcomp/filetxt log:
``sacct`` needs slurmdbd and a database, which a one-node test does not run.
"""
from __future__ import annotations

import argparse
import datetime
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from collections import Counter
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

import numpy as np

from batch import ledger
from batch.assets import collect
from batch.options import DEFAULT_DECODER
from batch.pipeline import SCENE_FILE
from batch.sharding import shard_of
from bench.common import REPO, add_out_argument, child_env, file_sha256, write_report
from support.paths import SHARED_ASSETS

SBATCH = REPO / "docs" / "slurm_render_dataset.sbatch"
INSTALL = "apt-get install -y slurm-wlm munge"
TOOLS = ("munged", "slurmctld", "slurmd", "sbatch", "scancel", "scontrol", "squeue")
# The sbatch file's own arguments to render_dataset.py; the single-process reference uses the same.
SBATCH_ARGS = ["--workers", "1", "--timeout", "3600", "--retries", "1", "--seed", "0"]
# Small settings, passed to the sbatch file as trailing arguments: 2 shared cores render the whole array.
RENDER_ARGS = ["--resolution", "32", "--frames", "2", "--samples", "2", "--aov-samples", "1",
               "--fit-steps", "2", "--max-texture", "16"]
TASK_RESOURCES = ["--cpus-per-task=1", "--mem=2G"]  # the file asks 16 CPUs / 32 GB: more than this node has
ENDED = {"COMPLETED", "FAILED", "CANCELLED", "TIMEOUT", "NODE_FAIL", "OUT_OF_MEMORY", "PREEMPTED",
         "BOOT_FAIL", "DEADLINE"}
# Broken inputs and a piece of the reason each must be recorded with.
BAD = {"truncated.glb": "prepare: import failed",
       "missing_buffer.gltf": "which is missing",
       "escape/outside_uri.gltf": "which is refused",
       "corrupt.ply": "prepare: import failed",
       "points.xyz": "unsupported format '.xyz'"}


# ---- pure parts (bench/farm/test_slurm_e2e.py) ----

def missing_tools(path: str | None = None) -> list[str]:
    """The SLURM and munge commands not found on ``path`` (default: $PATH plus the sbin folders)."""
    search = path if path is not None else os.pathsep.join([os.environ.get("PATH", ""), "/usr/sbin", "/sbin"])
    return [tool for tool in TOOLS if shutil.which(tool, path=search) is None]


def key_values(line: str) -> dict[str, str]:
    """``A=1 B=x y C=2`` (scontrol -o, slurmd -C, jobcomp lines) as a dict; a word without ``=``
    belongs to the value before it (a command line with its arguments)."""
    out: dict[str, str] = {}
    last = None
    for word in line.split():
        key, eq, value = word.partition("=")
        if eq and key:
            out[key], last = value, key
        elif last is not None:
            out[last] += " " + word
    return out


def expand_tasks(text: str) -> list[int]:
    """Array task ids as scontrol prints them for a pending group: ``0-2,5`` (a ``%N`` throttle dropped)."""
    ids: list[int] = []
    for part in text.split("%")[0].split(","):
        first, _, last = part.partition("-")
        ids += range(int(first), int(last or first) + 1)
    return ids


def slurm_conf(folder: Path, node: dict[str, str], ports: tuple[int, int], munge_socket: Path) -> str:
    """A one-node cluster: controller and node on this host (``node`` is ``slurmd -C``'s line, so
    the CPUs and memory declared are the machine's), every file in ``folder``, no cgroups."""
    name = node["NodeName"]
    hardware = " ".join(f"{k}={node[k]}" for k in ("CPUs", "Boards", "SocketsPerBoard", "CoresPerSocket",
                                                   "ThreadsPerCore", "RealMemory") if k in node)
    user = _user()
    lines = [
        "ClusterName=richmat-e2e",
        f"SlurmctldHost={name}(127.0.0.1)",
        f"SlurmctldPort={ports[0]}",
        f"SlurmdPort={ports[1]}",
        f"SlurmUser={user}",
        f"SlurmdUser={user}",
        "AuthType=auth/munge",
        "CredType=cred/munge",
        f"AuthInfo=socket={munge_socket}",
        f"StateSaveLocation={folder / 'state'}",
        f"SlurmdSpoolDir={folder / 'spool'}",
        f"SlurmctldPidFile={folder / 'slurmctld.pid'}",
        f"SlurmdPidFile={folder / 'slurmd.pid'}",
        f"SlurmctldLogFile={folder / 'log' / 'slurmctld.log'}",
        f"SlurmdLogFile={folder / 'log' / 'slurmd.log'}",
        "ProctrackType=proctrack/linuxproc",  # no cgroups: a container may not delegate them
        "TaskPlugin=task/none",
        "SelectType=select/cons_tres",
        "SelectTypeParameters=CR_Core_Memory",
        "SchedulerType=sched/backfill",
        "AccountingStorageType=accounting_storage/none",
        "JobAcctGatherType=jobacct_gather/none",
        "JobCompType=jobcomp/filetxt",  # one line per task end (and per requeue): the states sacct would give
        f"JobCompLoc={folder / 'log' / 'jobcomp.log'}",
        "MpiDefault=none",
        "ReturnToService=2",
        "MinJobAge=86400",  # keep ended tasks visible to scontrol until the report is written
        "KillWait=10",
        f"NodeName={name} NodeAddr=127.0.0.1 {hardware} State=UNKNOWN",
        f"PartitionName=main Nodes={name} Default=YES MaxTime=INFINITE State=UP",
    ]
    return "\n".join(lines) + "\n"


def merged_outcomes(records: Iterable[dict[str, Any]]) -> dict[str, dict[str, Any]]:
    """Per asset id, how it ended over all ledgers, in the order given: the last ``done`` or ``failed``
    record (``skipped`` only confirms an earlier render); ``done_records`` counts its publications."""
    merged: dict[str, dict[str, Any]] = {}
    for record in records:
        entry = merged.setdefault(record["asset_id"], {"source": record["source"], "status": "skipped",
                                                       "reason": record.get("reason"), "done_records": 0,
                                                       "shards": []})
        if record.get("shard") not in entry["shards"]:
            entry["shards"].append(record.get("shard"))
        if record["status"] == "skipped":
            continue
        entry.update(status=record["status"], reason=record.get("reason"),
                     settings_hash=record.get("settings_hash"), notes=record.get("notes", []))
        entry["done_records"] += record["status"] == "done"
    return merged


COMPARED = ("source", "status", "reason", "settings_hash", "notes")  # not timings, attempts or the shard


def outcome_differences(a: dict[str, dict[str, Any]], b: dict[str, dict[str, Any]]) -> list[str]:
    """What differs between two merged ledgers, asset by asset (empty: the same result)."""
    diffs = [f"{i}: only in the first" for i in sorted(set(a) - set(b))]
    diffs += [f"{i}: only in the second" for i in sorted(set(b) - set(a))]
    for asset_id in sorted(set(a) & set(b)):
        diffs += [f"{asset_id}: {key} {a[asset_id].get(key)!r} != {b[asset_id].get(key)!r}"
                  for key in COMPARED if a[asset_id].get(key) != b[asset_id].get(key)]
    return diffs


def read_ledgers(output: Path) -> list[dict[str, Any]]:
    """Every record of every shard ledger of an output folder, shard by shard, in append order."""
    return [r for path in sorted((output / "_ledger").glob("*.jsonl")) for r in ledger.read(path)]


def published(output: Path) -> dict[str, dict[str, Any]]:
    """Asset folders with a manifest, by asset id (the folder name)."""
    found = {}
    for manifest in sorted(output.glob("*/manifest.json")):
        found[manifest.parent.name] = json.loads(manifest.read_text(encoding="utf-8"))
    return found


# ---- inputs ----

TRIANGLE = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32).tobytes()


def triangle_gltf(uri: str) -> str:
    """A one-triangle .gltf whose vertex buffer is the external file ``uri``."""
    doc = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
           "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
           "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                          "min": [0, 0, 0], "max": [1, 1, 0]}],
           "bufferViews": [{"buffer": 0, "byteLength": len(TRIANGLE)}],
           "buffers": [{"uri": uri, "byteLength": len(TRIANGLE)}]}
    return json.dumps(doc)


def build_inputs(folder: Path) -> None:
    """The sample models and the broken files of ``BAD``; the file the escaping URI names exists
    (outside the input folder), so only the refusal keeps it from being read."""
    folder.mkdir(parents=True)
    for model in sorted((SHARED_ASSETS / "models").iterdir()):
        shutil.copy(model, folder / model.name)
    box = (SHARED_ASSETS / "models" / "Box.glb").read_bytes()
    (folder / "truncated.glb").write_bytes(box[: len(box) // 2])
    (folder / "missing_buffer.gltf").write_text(triangle_gltf("triangle.bin"))
    secret = folder.parent / "outside" / "triangle.bin"
    secret.parent.mkdir(exist_ok=True)
    secret.write_bytes(TRIANGLE)
    (folder / "escape").mkdir()
    (folder / "escape" / "outside_uri.gltf").write_text(triangle_gltf("../../outside/triangle.bin"))
    (folder / "corrupt.ply").write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vertex 3\n\x00\x01")
    (folder / "points.xyz").write_text("0 0 0\n")


# ---- the cluster ----

def _user() -> str:
    import pwd

    return pwd.getpwuid(os.getuid()).pw_name


def free_ports(count: int) -> tuple[int, ...]:
    """Ports nothing listens on now (the defaults 6817/6818 may belong to a real cluster)."""
    sockets = [socket.socket() for _ in range(count)]
    for s in sockets:
        s.bind(("127.0.0.1", 0))
    ports = tuple(s.getsockname()[1] for s in sockets)
    for s in sockets:
        s.close()
    return ports


class Cluster:
    """munged, slurmctld and slurmd started in ``folder``, stopped by ``stop`` (also on failure)."""

    def __init__(self, folder: Path) -> None:
        self.folder = folder
        self.conf = folder / "slurm.conf"
        self.env = child_env(folder / "blender_user") | {"SLURM_CONF": str(self.conf)}
        self.processes: dict[str, subprocess.Popen] = {}

    def start(self) -> str:
        """Start the three daemons; returns the node line the slurm.conf declares."""
        munge = self.folder / "munge"  # munged wants every folder above its socket searchable
        for sub in ("munge", "state", "spool", "log"):
            (self.folder / sub).mkdir(mode=0o755, exist_ok=True)
        self.folder.chmod(0o755)
        key = munge / "munge.key"
        key.write_bytes(os.urandom(1024))
        key.chmod(0o600)
        sock = munge / "munge.sock"
        self._spawn("munged", ["munged", "--foreground", f"--socket={sock}", f"--key-file={key}",
                               f"--pid-file={munge / 'munged.pid'}", f"--log-file={munge / 'munged.log'}",
                               f"--seed-file={munge / 'munged.seed'}"])
        _wait_for(lambda: sock.exists(), 30, "munged's socket")
        node = key_values(subprocess.run(["slurmd", "-C"], capture_output=True, text=True,
                                         check=True).stdout.splitlines()[0])
        self.conf.write_text(slurm_conf(self.folder, node, free_ports(2), sock))
        self._spawn("slurmctld", ["slurmctld", "-D", "-f", str(self.conf)])
        self._spawn("slurmd", ["slurmd", "-D", "-f", str(self.conf), "-N", node["NodeName"]])
        _wait_for(lambda: "idle" in self.run("sinfo", "-h", "-o", "%T", check=False), 60, "an idle node")
        return next(ln for ln in self.conf.read_text().splitlines() if ln.startswith("NodeName="))

    def _spawn(self, name: str, cmd: list[str]) -> None:
        with open(self.folder / "log" / f"{name}.console", "wb") as log:  # the child keeps its own copy
            self.processes[name] = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, env=self.env,
                                                    stdin=subprocess.DEVNULL)

    def run(self, *cmd: str, check: bool = True, cwd: Path | None = None,
            env: dict[str, str] | None = None) -> str:
        """A SLURM command against this cluster (``env`` adds variables: sbatch passes them to the job)."""
        proc = subprocess.run(cmd, capture_output=True, text=True, env=self.env | (env or {}), cwd=cwd, check=False)
        if check and proc.returncode != 0:
            raise RuntimeError(f"{' '.join(cmd)}: exit {proc.returncode}: {proc.stderr.strip()}")
        return proc.stdout + ("" if check else proc.stderr)

    def stop(self) -> None:
        """Stop the daemons in reverse order of their start; SIGKILL what does not stop in 30 s."""
        for name in reversed(list(self.processes)):
            proc = self.processes.pop(name)
            proc.terminate()
            try:
                proc.wait(timeout=30)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()


def _wait_for(ready: Callable[[], bool], seconds: float, what: str) -> None:
    deadline = time.monotonic() + seconds
    while not ready():
        if time.monotonic() > deadline:
            raise RuntimeError(f"no {what} after {seconds:.0f} s")
        time.sleep(0.5)


class Array:
    """One submitted array: polls its tasks' states and keeps a timeline of what happened."""

    def __init__(self, cluster: Cluster, job_id: str, tasks: int) -> None:
        self.cluster, self.job_id, self.tasks = cluster, job_id, tasks
        self.t0 = time.monotonic()
        self.timeline: list[dict[str, Any]] = []
        self.last: dict[int, tuple[str, str]] = {}  # task -> (state, reason)

    def event(self, event: str, **detail: Any) -> None:
        now = datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds")
        self.timeline.append({"t_s": round(time.monotonic() - self.t0, 1), "at": now, "event": event, **detail})
        print(f"[{self.timeline[-1]['t_s']:7.1f} s] {event} {detail or ''}", flush=True)

    def states(self) -> dict[int, dict[str, str]]:
        """Every task's scontrol record (a pending group record stands for each of its tasks)."""
        out: dict[int, dict[str, str]] = {}
        for line in self.cluster.run("scontrol", "-o", "show", "job", self.job_id).splitlines():
            record = key_values(line)
            for task in expand_tasks(record["ArrayTaskId"]):
                out[task] = record
        return out

    def poll(self) -> dict[int, dict[str, str]]:
        """The states now; each change of a task's state or pending reason goes into the timeline."""
        states = self.states()
        for task, record in sorted(states.items()):
            now = (record["JobState"], record.get("Reason", "None"))
            if self.last.get(task) != now:
                self.event(f"task {task} {now[0]}", job_id=record["JobId"], reason=now[1],
                           restarts=int(record.get("Restarts", 0)))
                self.last[task] = now
        return states

    def wait(self, done: Callable[[dict[int, dict[str, str]]], bool], seconds: float, what: str) -> dict:
        deadline = time.monotonic() + seconds
        while True:
            states = self.poll()
            if done(states):
                return states
            if time.monotonic() > deadline:
                raise RuntimeError(f"{what}: not after {seconds:.0f} s; states {self.last}")
            time.sleep(1.0)

    def ended(self, states: dict[int, dict[str, str]]) -> bool:
        return len(states) == self.tasks and all(r["JobState"] in ENDED for r in states.values())


# ---- the run ----

def plan(inputs: Path, tasks: int) -> dict[str, Any]:
    """Which task owns which asset (the farm's own hash split), and the task to cancel: the one
    with the most good assets, so it can be stopped after one is published and inside another."""
    assets = collect(inputs)
    shards = {t: [a for a in assets if shard_of(a.id, tasks) == t] for t in range(tasks)}
    good = {t: [a.id for a in owned if a.key not in BAD] for t, owned in shards.items()}
    target = max(good, key=lambda t: (len(good[t]), -t))
    if len(good[target]) < 2:
        raise SystemExit(f"no task owns two good assets with --tasks {tasks}: nothing to cancel mid-asset")
    return {"assets": {a.key: a.id for a in assets}, "good_by_task": good, "target": target,
            "shards": {t: [a.key for a in owned] for t, owned in shards.items()}}


def cancel_mid_asset(array: Array, task: int, output: Path, good: list[str], seconds: float) -> dict[str, Any]:
    """Wait until ``task`` has published one of its ``good`` assets and is past the prepare stage of
    another (its ``.partial`` holds the saved scene), then ``scancel`` it, wait for CANCELLED and
    ``scontrol requeue`` it."""
    deadline = time.monotonic() + seconds
    while True:
        states = array.poll()
        done = [i for i in good if (output / i / "manifest.json").is_file()]
        partial = [i for i in good if (output / f"{i}.partial" / SCENE_FILE).is_file()]
        if states.get(task, {}).get("JobState") == "RUNNING" and done and partial:
            break
        if states.get(task, {}).get("JobState") in ENDED or time.monotonic() > deadline:
            raise RuntimeError(f"task {task} ended before it was inside a second good asset (published {done})")
        time.sleep(0.5)
    target = f"{array.job_id}_{task}"
    files = sorted(p.relative_to(output / f"{partial[0]}.partial").as_posix()
                   for p in (output / f"{partial[0]}.partial").rglob("*") if p.is_file())
    array.cluster.run("scancel", target)
    array.event(f"scancel {target}", asset_in_progress=partial[0], published_before=done,
                partial_files=files)
    array.wait(lambda s: s[task]["JobState"] == "CANCELLED", 120, f"task {task} cancelled")
    left = (output / f"{partial[0]}.partial").is_dir()
    for _ in range(60):  # a task still completing (its processes being killed) is not requeued yet
        try:
            array.cluster.run("scontrol", "requeue", target)
            break
        except RuntimeError as exc:
            array.event("requeue refused, retrying", error=str(exc))
            time.sleep(2)
    array.event(f"scontrol requeue {target}", partial_left_by_cancel=left)
    return {"task": task, "asset_in_progress": partial[0], "published_before": done,
            "partial_files_at_cancel": files, "partial_left_by_cancel": left}


def identity(folders: dict[str, dict[str, Any]]) -> dict[str, tuple]:
    """What must not depend on sharding, per published asset (the seed hashes the id, not the shard)."""
    return {i: (m["settings_hash"], m["caption"], m["enhancement_type"]) for i, m in folders.items()}


def check(name: str, ok: bool, detail: Any = None) -> dict[str, Any]:
    print(f"{'PASS' if ok else 'FAIL'} {name}" + (f": {detail}" if detail and not ok else ""), flush=True)
    return {"check": name, "ok": bool(ok), **({"detail": detail} if detail is not None else {})}


def checks(output: Path, reference: Path, layout: dict[str, Any], cancel: dict[str, Any],
           states: dict[int, dict[str, str]]) -> list[dict[str, Any]]:
    ids = layout["assets"]
    good = {ids[k] for k in ids if k not in BAD}
    records = read_ledgers(output)
    merged = merged_outcomes(records)
    folders = published(output)
    leftovers = sorted(p.name for p in output.iterdir() if p.name.endswith(".partial"))
    stray = sorted(p.name for p in output.iterdir() if p.is_dir() and not p.name.startswith("_")
                   and p.name not in good)
    done_counts = {i: merged.get(i, {}).get("done_records", 0) for i in sorted(good)}
    bad_reasons = {key: merged.get(ids[key], {}).get("reason") for key in BAD}
    target = [r for r in records if r["shard"].startswith(f"{cancel['task']:04d}-")]
    skipped = sorted(r["asset_id"] for r in target if r["status"] == "skipped")
    redone = [r for r in target if r["asset_id"] == cancel["asset_in_progress"]]
    single = merged_outcomes(read_ledgers(reference))
    single_folders = published(reference)
    exits = {t: (r["JobState"], r["ExitCode"]) for t, r in sorted(states.items())}
    again = states[cancel["task"]]
    expected_exits = {t: ("FAILED", "1:0") if any(k in BAD for k in layout["shards"][t]) else ("COMPLETED", "0:0")
                      for t in range(len(states))}
    edited = subprocess.run(["git", "status", "--porcelain", str(SBATCH)], cwd=REPO, capture_output=True,
                            text=True, check=True).stdout.strip()
    return [
        check("sbatch file submitted as committed", not edited),
        check("every task ended with its shard's exit status (1: some asset failed)", exits == expected_exits,
              {"states": exits, "expected": expected_exits}),
        check("the cancelled task was requeued once and ran again",
              int(again["Restarts"]) == 1 and again["JobState"] in ENDED - {"CANCELLED"}),
        check("the cancel left the asset in progress as .partial, with no ledger record; the requeue rendered it",
              cancel["partial_left_by_cancel"] and [r["status"] for r in redone] == ["done"],
              {"asset": cancel["asset_in_progress"], "records": [r["status"] for r in redone]}),
        check("the requeued task skipped the assets it had published", set(cancel["published_before"]) <= set(skipped),
              {"published_before": cancel["published_before"], "skipped": skipped}),
        check("every good asset published exactly once", set(folders) == good and all(
            n == 1 for n in done_counts.values()) and not stray, {"done_records": done_counts, "stray": stray}),
        check("every bad asset in the ledgers as failed, with its reason",
              all(merged.get(ids[k], {}).get("status") == "failed" and part in (bad_reasons[k] or "")
                  for k, part in BAD.items()), bad_reasons),
        check("no .partial left", not leftovers, leftovers),
        check("merged shard ledgers == single-process ledger (ids, status, reason, settings hash, notes)",
              not outcome_differences(merged, single), outcome_differences(merged, single)),
        check("same assets published as the single-process run, same settings hash, caption and type",
              identity(folders) == identity(single_folders)),
    ]


def run_array(cluster: Cluster, inputs: Path, output: Path, layout: dict[str, Any], tasks: int,
              report: dict[str, Any]) -> dict[int, dict[str, str]]:
    """Submit the array, cancel and requeue the target task, wait for the end; fills ``report``."""
    submit = cluster.folder / "submit"
    (submit / "logs").mkdir(parents=True)  # the file's --output=logs/...: Slurm opens it before the script runs
    cmd = ["sbatch", "--parsable", f"--array=0-{tasks - 1}", *TASK_RESOURCES, str(SBATCH), str(inputs),
           str(output), *RENDER_ARGS]
    env = {"RICHMAT_REPO": str(REPO), "RICHMAT_WORKERS": "1", "OMP_NUM_THREADS": "1", "OMP_WAIT_POLICY": "PASSIVE"}
    job_id = cluster.run(*cmd, cwd=submit, env=env).strip().split(";")[0]
    report["submit"] = {"command": [c.replace(str(cluster.folder.parent), "<work>") for c in cmd],
                        "cwd": "<work>/slurm/submit", "job_id": job_id, "environment": env}
    array = Array(cluster, job_id, tasks)
    array.event("submitted", job_id=job_id)
    report["timeline"] = array.timeline
    target = layout["target"]
    report["cancel"] = cancel_mid_asset(array, target, output, layout["good_by_task"][target], 3600)
    states = array.wait(array.ended, 4 * 3600, "array finished")
    array.event("array finished", states={t: r["JobState"] for t, r in sorted(states.items())})
    report["task_states"] = {t: {k: r.get(k) for k in ("JobId", "JobState", "ExitCode", "Restarts", "RunTime",
                                                      "SubmitTime", "StartTime", "EndTime")}
                             for t, r in sorted(states.items())}
    jobcomp = cluster.folder / "log" / "jobcomp.log"
    report["jobcomp_log"] = [{k: r.get(k) for k in ("JobId", "ArrayTaskId", "JobState", "ExitCode", "StartTime",
                                                     "EndTime")}
                             for r in map(key_values, jobcomp.read_text().splitlines())]
    report["task_logs_tail"] = {p.name: p.read_text(errors="replace")[-600:]
                                for p in sorted((submit / "logs").glob("*.out"))}
    report["sacct"] = cluster.run("sacct", check=False).strip()  # says why it has nothing: no slurmdbd
    return states


def reference_run(inputs: Path, output: Path, env: dict[str, str]) -> dict[str, Any]:
    """The same inputs and settings in one process, no shards (what the array must add up to)."""
    cmd = [sys.executable, str(REPO / "batch" / "render_dataset.py"), "--input", str(inputs), "--output",
           str(output), *SBATCH_ARGS, *RENDER_ARGS, "--shard", "0/1"]
    print("single-process reference run ...", flush=True)
    start = time.monotonic()
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True, check=False)
    return {"command": " ".join(cmd).replace(str(inputs.parent), "<work>"), "exit_code": proc.returncode,
            "seconds": round(time.monotonic() - start, 1), "stderr_tail": proc.stderr[-800:]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--work", type=Path, help="work folder (default: a new temporary one, removed after)")
    parser.add_argument("--tasks", type=int, default=3, help="array tasks (shards)")
    add_out_argument(parser, "slurm_e2e.json")
    args = parser.parse_args()

    missing = missing_tools()
    if missing:
        raise SystemExit(f"not installed: {', '.join(missing)}. This bench installs nothing; on Debian/Ubuntu "
                         f"run (as root):\n  {INSTALL}")
    work = args.work
    if work is None:
        work = Path(tempfile.mkdtemp(prefix="richmat_slurm_"))
        work.chmod(0o755)  # mkdtemp makes it 0700; munged refuses a socket below a folder others cannot search
    work.mkdir(parents=True, exist_ok=True)
    for stale in ("inputs", "outside", "slurm", "array_out", "single_out"):
        shutil.rmtree(work / stale, ignore_errors=True)
    inputs, output, single = work / "inputs", work / "array_out", work / "single_out"
    build_inputs(inputs)
    layout = plan(inputs, args.tasks)
    report: dict[str, Any] = {
        "what": "docs/slurm_render_dataset.sbatch as committed, on a one-node SLURM on this machine: an array over "
                "the sample models plus broken files, one task cancelled mid-asset and requeued",
        "inputs": {"good": sorted(k for k in layout["assets"] if k not in BAD), "bad": BAD},
        "tasks": args.tasks, "shards": layout["shards"], "render_args": RENDER_ARGS,
        "sbatch_overrides": TASK_RESOURCES, "sbatch_sha256": file_sha256(SBATCH)}
    cluster = Cluster(work / "slurm")
    (work / "slurm").mkdir()
    signal.signal(signal.SIGTERM, lambda signum, frame: sys.exit(143))  # a killed bench still stops its daemons
    try:
        version = subprocess.run(["slurmctld", "-V"], capture_output=True, text=True, check=True).stdout.strip()
        report["slurm"] = {"version": version, "node": cluster.start()}
        report["slurm"]["conf"] = cluster.conf.read_text().replace(str(work), "<work>").splitlines()
        states = run_array(cluster, inputs, output, layout, args.tasks, report)
    finally:
        if "submit" in report and "task_states" not in report:
            cluster.run("scancel", report["submit"]["job_id"], check=False)
        cluster.stop()
    report["reference"] = reference_run(inputs, single, child_env(work / "blender_user") | {
        "OMP_NUM_THREADS": "1", "OMP_WAIT_POLICY": "PASSIVE"})
    report["checks"] = checks(output, single, layout, report["cancel"], states)
    report["all_ok"] = all(c["ok"] for c in report["checks"])
    merged = merged_outcomes(read_ledgers(output))
    report["outcomes"] = {m["source"]: {"status": m["status"], "reason": m["reason"], "shards": m["shards"]}
                          for m in sorted(merged.values(), key=lambda m: m["source"])}
    report["counts"] = dict(Counter(m["status"] for m in merged.values()))
    write_report(args.out, report, [DEFAULT_DECODER])
    print(f"{args.out}: all checks {'passed' if report['all_ok'] else 'did NOT pass'}")
    if args.work is None:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
