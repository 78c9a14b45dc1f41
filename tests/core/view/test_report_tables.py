"""report.md's tables as the run page reads them."""

from __future__ import annotations

from safeembodai_core.view import report_tables as rt


def test_tables_are_read_under_their_headings_with_escaped_pipes(tmp_path):
    report = tmp_path / "report.md"
    report.write_text("# run\n\n| run | |\n|---|---|\n| backend | `mock` |\n\ntext\n\n## Metrics per cell\n\n"
                      "| env | note |\n|---|---|\n| MO | a \\| b <script>x</script> |\n| OF | c |\n", encoding="utf-8")
    tables = rt.report_tables(report)
    assert [(t.heading, t.header) for t in tables] == [("run", ["run", ""]), ("Metrics per cell", ["env", "note"])]
    assert tables[0].rows == [["backend", "mock"]]
    assert tables[1].rows == [["MO", "a | b <script>x</script>"], ["OF", "c"]]  # text: the page escapes it


def test_a_missing_or_oversized_report_has_no_tables(tmp_path, monkeypatch):
    assert rt.report_tables(tmp_path / "absent.md") == []
    big = tmp_path / "report.md"
    big.write_text("| a |\n|---|\n| b |\n", encoding="utf-8")
    monkeypatch.setattr(rt, "MAX_BYTES", 4)
    assert rt.report_tables(big) == []
