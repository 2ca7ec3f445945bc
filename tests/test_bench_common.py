"""bench/ is one package: benches import each other as ``bench.X`` and write their reports
through ``support.reports``, whose provenance passes the rules the docs' citations are held to."""
from __future__ import annotations

import json
from pathlib import Path

from support.reports import write_report
from tests.test_docs_reports import problems
from torch_models.generator.generate import SHIPPED as GENERATOR
from torch_models.neural import trained

BENCH = Path(__file__).resolve().parents[1] / "bench"


def test_no_bench_edits_sys_path() -> None:
    edited = [p.name for p in sorted(BENCH.glob("*.py")) if "sys.path" in p.read_text()]
    assert not edited, f"run benches as python -m bench.NAME instead of editing sys.path: {edited}"


def test_a_written_report_records_its_provenance(tmp_path: Path) -> None:
    out = tmp_path / "reports" / "r.json"
    write_report(out, {"checkpoint": str(GENERATOR), "n": 1}, [trained.SHIPPED], GENERATOR)
    report = json.loads(out.read_text())
    shipped = trained.digest()
    assert report["n"] == 1
    assert report["provenance"]["decoder_sha256"] == {"torch_models/neural/weights": shipped}
    assert not problems(report, "[r](reports/r.json)", shipped)
