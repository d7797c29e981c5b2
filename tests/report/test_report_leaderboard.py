"""robodepth report on challenge scores.json files: a leaderboard per track."""

from __future__ import annotations

import json

from tests.helpers.messages import one_line_error


def _scores(path, abs_rel, a1, nyu=False, **dees):
    path.parent.mkdir(parents=True, exist_ok=True)
    doc = {"abs_rel": abs_rel, "sq_rel": 1.0, "rmse": 4.0, "rmse_log": 0.2, "a1": a1, "a2": 0.9, "a3": 0.95,
           "dee": (abs_rel - a1 + 1) / 2, "mdee": 0.3, "images": 10, **{f"dee_{k}": v for k, v in dees.items()}}
    if nyu:
        doc.update(log10=0.05, silog=10.0)
    path.write_text(json.dumps(doc))
    return path


def test_leaderboard_per_track_ranked(cli, tmp_path):
    a = _scores(tmp_path / "alpha" / "scores.json", 0.20, 0.70, fog=0.31, dark=0.25)
    b = _scores(tmp_path / "beta" / "scores.json", 0.12, 0.85, fog=0.21, dark=0.18)
    c = _scores(tmp_path / "gamma" / "scores.json", 0.15, 0.80, nyu=True, dark=0.2)
    d = _scores(tmp_path / "delta.json", 0.10, 0.90, nyu=True, dark=0.1)
    res = cli("report", a, b, c, d, "--out", tmp_path / "out")
    assert res.exit_code == 0, res.output
    md = (tmp_path / "out" / "leaderboard.md").read_text()
    kitti, nyu = md.split("## Track nyu")
    rows = [line for line in kitti.splitlines() if line.startswith("| 1") or line.startswith("| 2")]
    assert rows[0].startswith("| 1 | beta | 0.1200") and rows[1].startswith("| 2 | alpha | 0.2000")
    header = next(line for line in kitti.splitlines() if line.startswith("| rank"))
    assert header.endswith("| dee | mdee | DEE dark | DEE fog |")  # benchmark order: dark, then fog
    nyu_rows = [line for line in nyu.splitlines() if line.startswith("| 1") or line.startswith("| 2")]
    assert nyu_rows[0].startswith("| 1 | delta | 0.1000") and "silog" in nyu
    page = (tmp_path / "out" / "index.html").read_text()
    assert page.count("<table>") == 2 and "beta" in page


def test_leaderboard_refusals(cli, tmp_path):
    a = _scores(tmp_path / "a" / "scores.json", 0.2, 0.7)
    csv = tmp_path / "m.csv"
    csv.write_text("corruption,level,abs_rel,a1\nclean,0,0.1,0.9\n")
    one_line_error(cli("report", a, csv, "--out", tmp_path / "o"), "m.csv", "not a challenge scores.json")
    b = _scores(tmp_path / "b" / "scores.json", 0.2, 0.7)
    one_line_error(cli("report", a, b, "--name", "x", "--name", "x", "--out", tmp_path / "o"), "also the name")
