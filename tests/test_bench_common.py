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
    edited = [str(p.relative_to(BENCH)) for p in sorted(BENCH.rglob("*.py")) if "sys.path" in p.read_text()]
    assert not edited, f"run benches as python -m bench.GROUP.NAME instead of editing sys.path: {edited}"


def test_each_bench_lives_in_its_capability_group() -> None:
    """bench/'s top holds only what the benches share; every group is a package, so that
    ``python -m bench.GROUP.NAME`` runs and pytest imports a group's tests by their dotted name."""
    top = sorted(p.name for p in BENCH.glob("*.py"))
    groups = sorted(p for p in BENCH.iterdir() if p.is_dir() and any(p.glob("*.py")))
    assert top == ["__init__.py", "common.py"], top
    assert len(groups) >= 5 and all((g / "__init__.py").is_file() for g in groups), groups


def test_a_written_report_records_its_provenance(tmp_path: Path) -> None:
    out = tmp_path / "reports" / "r.json"
    write_report(out, {"checkpoint": str(GENERATOR), "n": 1}, [trained.SHIPPED], GENERATOR)
    report = json.loads(out.read_text())
    shipped = trained.digest()
    assert report["n"] == 1
    assert report["provenance"]["decoder_sha256"] == {"torch_models/neural/weights": shipped}
    assert not problems(report, "[r](reports/r.json)", shipped)
