"""`robodepth report` with rows beyond the benchmark: decimal levels and chains get their
own table, figure and JSON, and change no benchmark score (issue 23)."""

from __future__ import annotations

import json

import pytest

from tests.helpers.report import evaluate_csv, extra_rows

@pytest.mark.slow
def test_report_keeps_curves_and_chains_apart(tmp_path, cli):
    pytest.importorskip("matplotlib")
    plain = evaluate_csv(tmp_path / "plain.csv", "kitti-c", "MonoViT")
    extra = tmp_path / "extra.csv"
    dees = {("fog", "1.5"): 0.21, ("fog", "2.5"): 0.24, ("snow", "4.5"): 0.4,
            ("fog:3+gaussian_noise:2.5", "0"): 0.37}
    extra.write_text(plain.read_text() + extra_rows(dees))
    out = tmp_path / "out"
    res = cli("report", extra, "--out", out)
    assert res.exit_code == 0, res.output
    doc = json.loads((out / "scores.json").read_text())["models"][0]
    want = json.loads(cli("score", extra, "-b", "kitti-c", "--json").output)
    base = json.loads(cli("score", plain, "-b", "kitti-c", "--json").output)
    assert doc["beyond_benchmark"] == want["beyond_benchmark"]
    assert doc["beyond_benchmark"]["chains"] == {"fog:3+gaussian_noise:2.5": pytest.approx(0.37)}
    assert doc["beyond_benchmark"]["severity_curves"]["fog"]["2.5"] == pytest.approx(0.24)
    assert (doc["scores"]["mce"], doc["scores"]["mrr"]) == (base["mce"], base["mrr"])
    assert len(doc["variants"]) == 91 + len(dees)
    assert {(v["corruption"], v["level"]) for v in doc["variants"][-4:]} == {
        ("fog", 1.5), ("fog", 2.5), ("snow", 4.5), ("fog:3+gaussian_noise:2.5", 0)}
    md = (out / "table.md").read_text()
    assert "Beyond the benchmark" not in md or "0.370" in md
    page = (out / "index.html").read_text()
    assert "Beyond the benchmark" in page and "0.370" in page and "0.240" in page
    svg = (out / "figures" / "severity.svg").read_text()
    assert "fog" in svg and "snow" in svg and "KITTI-C" in svg


@pytest.mark.slow
def test_report_without_extra_rows_has_no_such_section(tmp_path, cli):
    pytest.importorskip("matplotlib")
    plain = evaluate_csv(tmp_path / "plain.csv", "kitti-c", "MonoViT")
    out = tmp_path / "out"
    assert cli("report", plain, "--out", out).exit_code == 0
    assert "beyond_benchmark" not in json.loads((out / "scores.json").read_text())["models"][0]
    assert not (out / "figures" / "severity.svg").exists()
    assert "Beyond the benchmark" not in (out / "index.html").read_text()
