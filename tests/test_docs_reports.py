"""Every report the README or a design note links to exists and says how it was made.

A report is a file under docs/reports/ (JSON, or a chart). A cited JSON report must
record the decoder weights it used: new reports carry a ``provenance`` block
(bench/common.py: git commit, command, date, machine, ``decoder_sha256`` per
weights folder, ``generator_sha256`` when a generator checkpoint was used); older ones
a top-level ``decoder_sha256`` only. The weights must be the shipped decoder's
(torch_models/neural/weights/weights.safetensors; with several decoders the shipped
one among them) unless the citing line (the line holding the link) names the weights:
the first 8 hex digits of the report's decoder sha256, or "earlier decoder" /
"previous decoder". A report with no provenance at all is accepted only where the
citing line says "no provenance recorded".
"""
from __future__ import annotations

import hashlib
import json
import re
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
REPORTS = REPO / "docs" / "reports"
SHIPPED_WEIGHTS = REPO / "torch_models" / "neural" / "weights" / "weights.safetensors"
PROVENANCE_KEYS = ("git_commit", "command", "date", "machine", "decoder_sha256")
NAMES_EARLIER = ("earlier decoder", "previous decoder")
NO_PROVENANCE = "no provenance recorded"
# a Markdown link or image; the link text may run over lines, the target may not
LINK = re.compile(r"!?\[[^\]]*\]\(([^)\s]+)\)")


def documents() -> list[Path]:
    return [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))]


def citations(doc: Path) -> list[tuple[int, str, Path]]:
    """(line number, line, resolved target) of each link to a .json or .png file in ``doc``."""
    text = doc.read_text()
    lines = text.splitlines()
    out = []
    for m in LINK.finditer(text):
        target = m.group(1).split("#")[0]
        if not target.endswith((".json", ".png")) or "://" in target:
            continue
        n = text.count("\n", 0, m.start(1))
        out.append((n + 1, lines[n], (doc.parent / target).resolve()))
    return out


def decoder_digests(report: dict) -> list[str] | None:
    """The decoder sha256s a report records, or None when it records none."""
    prov = report.get("provenance")
    found = prov.get("decoder_sha256") if isinstance(prov, dict) else report.get("decoder_sha256")
    if found is None:
        return None
    return list(found.values()) if isinstance(found, dict) else [found]


def problems(report: dict, line: str, shipped: str) -> list[str]:
    """What is wrong with citing ``report`` on ``line``, the shipped decoder being ``shipped``."""
    said = line.lower()
    prov = report.get("provenance")
    if prov is None and "decoder_sha256" not in report and "generator_sha256" not in report:
        return [] if NO_PROVENANCE in said else [f"records no provenance and the line does not say {NO_PROVENANCE!r}"]
    out = []
    if prov is not None:
        missing = [k for k in PROVENANCE_KEYS if k not in prov]
        if "checkpoint" in report and "generator_sha256" not in prov:
            missing.append("generator_sha256")
        if missing:
            out.append(f"provenance lacks {missing}")
    digests = decoder_digests(report) or []
    if digests and shipped not in digests:
        named = any(d[:8].lower() in said for d in digests) or any(w in said for w in NAMES_EARLIER)
        if not named:
            out.append(f"made with decoder {[d[:8] for d in digests]}, not the shipped {shipped[:8]}, "
                       "and the line does not name the weights it used")
    return out


def all_citations():
    return [(doc, n, line, target) for doc in documents() for n, line, target in citations(doc)]


@pytest.fixture(scope="module")
def shipped() -> str:
    assert SHIPPED_WEIGHTS.is_file(), f"{SHIPPED_WEIGHTS} missing: the shipped decoder is part of the repository"
    return hashlib.sha256(SHIPPED_WEIGHTS.read_bytes()).hexdigest()


def test_reports_live_under_docs_reports():
    stray = sorted(p.name for p in (REPO / "docs").iterdir() if p.suffix in (".json", ".png"))
    assert not stray, f"reports at the top of docs/ (move them to docs/reports/): {stray}"


def test_linked_files_exist():
    missing = [f"{doc.relative_to(REPO)}:{n}: {t}" for doc, n, _, t in all_citations() if not t.is_file()]
    assert not missing, "links to missing files:\n" + "\n".join(missing)


def test_cited_reports_record_their_provenance(shipped):
    bad = []
    for doc, n, line, target in all_citations():
        if target.suffix != ".json" or not target.is_file() or not target.is_relative_to(REPORTS):
            continue
        for why in problems(json.loads(target.read_text()), line, shipped):
            bad.append(f"{doc.relative_to(REPO)}:{n}: {target.relative_to(REPO)}: {why}")
    assert not bad, "\n".join(bad)


def test_some_reports_are_cited():
    cited = {t for *_, t in all_citations() if t.suffix == ".json" and t.is_relative_to(REPORTS)}
    assert len(cited) >= 10, cited


# The rules themselves, on made-up reports.
SHIPPED = "a" * 64
OTHER = "b" * 64


def full(decoders: dict, **extra) -> dict:
    return {"provenance": {"git_commit": "0" * 40, "command": "python -m bench.x", "date": "2026-01-01",
                           "machine": {}, "decoder_sha256": decoders, **extra}}


@pytest.mark.parametrize("report, line, ok", [
    (full({"w": SHIPPED}), "[r](reports/r.json)", True),
    (full({"w": OTHER}), "[r](reports/r.json)", False),
    (full({"w": OTHER}), f"made with `{OTHER[:8]}`: [r](reports/r.json)", True),
    (full({"w": OTHER}), "the previous decoder: [r](reports/r.json)", True),
    (full({"w": OTHER, "v": SHIPPED}), "[r](reports/r.json)", True),
    (full({}), "[r](reports/r.json)", True),
    ({"decoder_sha256": SHIPPED}, "[r](reports/r.json)", True),
    ({"decoder_sha256": OTHER}, "[r](reports/r.json)", False),
    ({"decoder_sha256": OTHER}, "an Earlier decoder's [r](reports/r.json)", True),
    ({"seed": 0}, "[r](reports/r.json)", False),
    ({"seed": 0}, "[r](reports/r.json) (no provenance recorded)", True),
    ({"checkpoint": "g", **full({"w": SHIPPED})}, "[r](reports/r.json)", False),
    ({"checkpoint": "g", **full({"w": SHIPPED}, generator_sha256="c" * 64)}, "[r](reports/r.json)", True),
    ({"provenance": {"decoder_sha256": {"w": SHIPPED}}}, "[r](reports/r.json)", False),
])
def test_rules(report, line, ok):
    assert (not problems(report, line, SHIPPED)) == ok, problems(report, line, SHIPPED)


def test_link_parsing(tmp_path):
    doc = tmp_path / "note.md"
    doc.write_text("intro\n[a long\nlink text](reports/x.json) and ![c](reports/x.png)\n[n](other.md)\n")
    found = [(n, t.name) for n, _, t in citations(doc)]
    assert found == [(3, "x.json"), (3, "x.png")]
