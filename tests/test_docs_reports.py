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

The numbers a reader acts on are checked against their reports' keys: the table in
tests/doc_numbers.py, one row per number; its docstring says which numbers are pinned (the
README's, the design notes' tables, a short list of headline figures in prose), and a test here
holds the table to it.
"""
from __future__ import annotations

import hashlib
import json
import math
import re
import statistics
from pathlib import Path
from typing import Any

import pytest

from .doc_numbers import HEADLINE_PROSE, ROWS, DocNumber

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


# The numbers: each quoted number equals its report's key at the quote's rounding.
BRACED = re.compile(r"\{([^{}]+)\}")
REDUCE = {"min": min, "max": max, "mean": statistics.fmean}


def collapsed(text: str) -> str:
    return " ".join(text.split())


def lookup(report: Any, key: str) -> float:
    """The number ``key`` names in ``report`` (tests/doc_numbers.py says how keys are written)."""
    op, _, path = key.rpartition(":")
    found = [report]
    for part in path.split("/"):
        if part == "*":
            found = [v for item in found for v in (item.values() if isinstance(item, dict) else item)]
        else:
            found = [item[int(part)] if isinstance(item, list) else item[part] for item in found]
    if op in REDUCE:
        return float(REDUCE[op](found))
    (value,) = found
    if op == "len":
        return float(len(value))
    return math.sqrt(value) if op == "sqrt" else float(value)


def number_problems(row: DocNumber, text: str, report: Any) -> list[str]:
    """What is wrong with ``row`` against the document's ``text`` and its ``report``."""
    where = f"{row.doc}: {row.quote!r}"
    out = []
    if collapsed(BRACED.sub(r"\1", row.quote)) not in collapsed(text):
        out.append(f"{where}: not in the document (a changed number must change in its report too)")
    braced = BRACED.findall(row.quote)
    if len(braced) != 1:
        return out + [f"{where}: quotes {len(braced)} braced numbers, not one"]
    quoted = braced[0].replace(" ", "").replace(",", "")
    decimals = len(quoted.partition(".")[2])
    shown = f"{lookup(report, row.key) * row.scale:.{decimals}f}"
    if float(shown) != float(quoted):
        out.append(f"{where}: {row.report} {row.key} gives {shown}")
    return out


def test_quoted_numbers_match_their_reports():
    texts = {doc: (REPO / doc).read_text() for doc in {r.doc for r in ROWS}}
    reports = {r.report: json.loads((REPO / r.report).read_text()) for r in ROWS}
    bad = [p for r in ROWS for p in number_problems(r, texts[r.doc], reports[r.report])]
    assert not bad, "numbers that drifted from their reports:\n" + "\n".join(bad)


HEADLINES_AT_MOST = 6  # the README's table is for newcomers: the rest lives in the design notes


def test_every_headline_row_has_its_numbers_checked():
    text = (REPO / "README.md").read_text().partition("## Headline numbers")[2].partition("\n## ")[0]
    table = [ln for ln in text.splitlines() if ln.startswith("| ") and not ln.startswith("| what ")]
    quotes = [collapsed(BRACED.sub(r"\1", r.quote)) for r in ROWS if r.doc == "README.md"]
    unchecked = [ln[:80] for ln in table if not any(q in collapsed(ln) for q in quotes)]
    assert 1 <= len(table) <= HEADLINES_AT_MOST and not unchecked, (len(table), unchecked)


def test_every_note_citing_reports_has_its_numbers_checked():
    """history.md records superseded numbers; every other note that cites a JSON report has rows."""
    citing = {doc.relative_to(REPO).as_posix() for doc, *_, t in all_citations() if t.suffix == ".json"}
    missing = sorted(citing - {r.doc for r in ROWS} - {"docs/history.md"})
    assert not missing, missing


REPORT = {"runs": [{"flip": 0.0132}, {"flip": 0.0151}], "n": 20}


@pytest.mark.parametrize("doc, quote, key, scale, drifted", [
    ("worst FLIP 0.013 here", "worst FLIP {0.013}", "runs/0/flip", 1, False),
    ("worst FLIP 0.014 here", "worst FLIP {0.014}", "runs/0/flip", 1, True),  # the text moved, the report did not
    ("worst FLIP 0.013 here", "worst FLIP {0.0132}", "runs/0/flip", 1, True),  # quote differs from the text
    ("worst FLIP 1.3 %", "worst FLIP {1.3} %", "runs/0/flip", 100, False),
    ("from 0.013 to 0.015", "from 0.013 to {0.015}", "max:runs/*/flip", 1, False),
    ("from 0.013 to 0.016", "from 0.013 to {0.016}", "max:runs/*/flip", 1, True),
    ("all 20 cases", "all {20} cases", "n", 1, False),
    ("2 runs", "{2} runs", "len:runs", 1, False),
    ("1,024\n texels", "{1,024} texels", "n", 51.2, False),
])
def test_a_drifted_number_fails(doc, quote, key, scale, drifted):
    row = DocNumber("note.md", quote, "r.json", key, scale)
    assert bool(number_problems(row, doc, REPORT)) == drifted, number_problems(row, doc, REPORT)


def test_a_drifted_report_fails_a_real_row():
    """The README's agreement number, against its report re-run to a worse worst case."""
    row = next(r for r in ROWS if r.report.endswith("/agreement.json") and r.key == "worst_flip")
    report = json.loads((REPO / row.report).read_text())
    text = (REPO / row.doc).read_text()
    assert not number_problems(row, text, report)
    report["worst_flip"] += 0.001
    assert number_problems(row, text, report) == [f"{row.doc}: {row.quote!r}: {row.report} worst_flip gives 0.014"]


# Which numbers are pinned: the README's, the design notes' tables and HEADLINE_PROSE; not prose.
HEADLINE_PROSE_AT_MOST = 12


def in_a_table(quote: str, text: str) -> bool:
    """Whether ``quote`` lies inside one Markdown table row (a line starting with "|") of ``text``."""
    said = collapsed(BRACED.sub(r"\1", quote))
    return any(line.lstrip().startswith("|") and said in collapsed(line) for line in text.splitlines())


def prose_rows(rows: tuple[DocNumber, ...], texts: dict[str, str]) -> list[DocNumber]:
    """The rows that pin a design note's prose rather than the README or a table."""
    return [r for r in rows if r.doc != "README.md" and not in_a_table(r.quote, texts[r.doc])]


def test_rows_pin_the_readme_tables_and_headlines_only():
    """Rewording a note's prose must not break a test: prose rows are the listed headlines only."""
    texts = {doc: (REPO / doc).read_text() for doc in {r.doc for r in ROWS}}
    prose = prose_rows(ROWS, texts)
    unlisted = [f"{r.doc}: {r.quote!r}" for r in prose if r.quote not in HEADLINE_PROSE]
    unused = sorted(set(HEADLINE_PROSE) - {r.quote for r in prose})
    assert not unlisted, "rows pinning prose (drop them, or list a headline in HEADLINE_PROSE):\n" + "\n".join(unlisted)
    assert not unused, f"HEADLINE_PROSE names no prose row: {unused}"
    assert len(HEADLINE_PROSE) <= HEADLINE_PROSE_AT_MOST, len(HEADLINE_PROSE)


def test_a_prose_row_is_found():
    text = "| Type | FLIP |\n|---|---|\n| 0 haze | 0.035 |\nThe fit takes 50.8 s.\n"
    rows = (DocNumber("n.md", "| 0 haze | {0.035} |", "r.json"), DocNumber("n.md", "takes {50.8} s", "r.json"),
            DocNumber("README.md", "takes {50.8} s", "r.json"))
    assert prose_rows(rows, {"n.md": text, "README.md": text}) == [rows[1]]


# Every bench and every report is cited: what nothing current cites goes to docs/history.md.
BENCH = REPO / "bench"
NOT_BENCHES = {"__init__.py", "common.py"}


def uncited(names: dict[str, tuple[str, ...]], text: str) -> list[str]:
    """The keys of ``names`` none of whose spellings occurs in ``text``."""
    return sorted(key for key, spellings in names.items() if not any(s in text for s in spellings))


def bench_spellings(module: Path) -> tuple[str, ...]:
    """How the docs name a bench module (a path from the repository root): its path or its ``python -m``
    name, followed by a non-name character."""
    parts = module.with_suffix("").parts
    return tuple(f"{sep.join(parts)}{end}" for sep in "/." for end in (".py", "`", " ", "\n", ")", ","))


def test_every_bench_and_report_is_cited():
    """history.md names retired ones by ``git show``: its mentions do not count."""
    text = "\n".join(doc.read_text() for doc in documents() if doc.name != "history.md")
    benches = {p.relative_to(BENCH).as_posix(): bench_spellings(p.relative_to(REPO))
               for p in sorted(BENCH.rglob("*.py")) if p.name not in NOT_BENCHES and not p.name.startswith("test_")}
    reports = {p.name: (p.name,) for p in sorted(REPORTS.iterdir()) if p.is_file()}
    assert len(benches) >= 20 and len(reports) >= 40, (len(benches), len(reports))
    missing = uncited(benches, text) + uncited(reports, text)
    assert not missing, f"cited by neither README.md nor docs/*.md (cite them, or retire them to docs/history.md): {missing}"


def test_an_uncited_bench_is_found():
    names = {"agreement.py": bench_spellings(Path("bench/material/agreement.py")),
             "agreement_cycles.py": bench_spellings(Path("bench/material/agreement_cycles.py"))}
    assert uncited(names, "run `python -m bench.material.agreement --quick`") == ["agreement_cycles.py"]
    assert uncited(names, "bench/material/agreement.py and bench.material.agreement_cycles)") == []
    assert uncited(names, "bench/agreement.py and bench.agreement_cycles)") == sorted(names)  # not in its group
