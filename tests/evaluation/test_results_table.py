"""The results CSV's one owner: what evaluate writes is what score and report read, its
format version travels in a sidecar, and a results file of another version is refused in
one line naming the release that wrote it."""

from __future__ import annotations

import json

from robodepth_cli.evaluation.csvrows import ResultsTable, sidecar

TEXT = ("# scene depth: predictions of abc (m)\n"
        "corruption,level,abs_rel,a1,dataset,split\n"
        "clean,0,0.1,0.9,kitti-c,\n\n"
        "fog,1,0.2,0.8,kitti-c,\n")


def test_a_table_reads_its_comments_header_and_rows():
    t = ResultsTable.parse(TEXT, "r.csv")
    assert t.comments == ("# scene depth: predictions of abc (m)",)
    assert t.header == ("corruption", "level", "abs_rel", "a1", "dataset", "split")
    assert [line for line, _ in t.rows] == [2, 3, 5]  # the blank line is skipped, lines kept
    assert t.column("a1") == ["0.9", "0.8"] and t.column("dee") is None
    assert t.dataset() == ("kitti-c", "")
    assert t.records()[1] == {"corruption": "fog", "level": "1", "abs_rel": "0.2", "a1": "0.8",
                              "dataset": "kitti-c", "split": ""}


def test_written_with_a_sidecar_and_read_back(tmp_path):
    t = ResultsTable.of(("corruption", "level", "abs_rel", "a1"), [("clean", 0, "0.1", "0.9")],
                        ("# a note",))
    t.write(tmp_path / "r.csv")
    assert (tmp_path / "r.csv").read_text() == "# a note\ncorruption,level,abs_rel,a1\nclean,0,0.1,0.9\n"
    doc = json.loads(sidecar(tmp_path / "r.csv").read_text())
    assert doc["schema"] == "robodepth-results" and doc["schema_version"] == 1
    back = ResultsTable.read(tmp_path / "r.csv")
    assert back.text() == t.text() and back.source == str(tmp_path / "r.csv")


def test_a_results_file_of_another_version_gets_one_line(tmp_path, cli):
    csv = tmp_path / "r.csv"
    csv.write_text("corruption,level,abs_rel,a1\nclean,0,0.1,0.9\nfog,1,0.2,0.8\n")
    sidecar(csv).write_text(json.dumps({"schema": "robodepth-results", "schema_version": 7,
                                        "robodepth": "9.9.0"}))
    for args in (("score", csv, "--benchmark", "kitti-c", "--allow-partial"),
                 ("report", csv, "--on", "custom", "--out", tmp_path / "rep")):
        res = cli(*args)
        assert res.exit_code == 2 and res.output.count("\n") == 1, res.output
        assert res.output.startswith(f"robodepth: error: {csv}: made by robodepth 9.9.0")
        assert "use robodepth 9.9.0" in res.output
    # Without a sidecar (results typed by hand, or from elsewhere) the header decides.
    sidecar(csv).unlink()
    assert cli("score", csv, "--benchmark", "kitti-c", "--allow-partial").exit_code == 0
