"""`report` on results of a custom or zero-shot dataset with depth-aware rows: taken, and
(as in `score`) kept out of mDEE and mRR, which have no baseline for them."""

from __future__ import annotations

import re

ROWS = [("clean", 0, 0.10, 0.90), ("fog", 1, 0.12, 0.88), ("fog", 3, 0.20, 0.70),
        ("fog_3d", 1, 0.14, 0.86), ("fog_3d", 3, 0.30, 0.60)]


def _csv(path, rows):
    path.write_text("corruption,level,abs_rel,sq_rel,rmse,rmse_log,a1,a2,a3\n" + "".join(
        f"{c},{lv},{ar},0.5,4.0,0.2,{a1},0.95,0.98\n" for c, lv, ar, a1 in rows))
    return path


def _dee(ar, a1):
    return (ar - a1 + 1) / 2


def test_report_scores_depth_aware_rows_of_a_custom_set(tmp_path, cli):
    res = cli("report", _csv(tmp_path / "mine.csv", ROWS), "--on", "custom:night", "--out",
              tmp_path / "rep", "--published", "none")
    assert res.exit_code == 0, res.output
    page = (tmp_path / "rep" / "index.html").read_text()
    # mDEE: fog's mean DEE over its levels; fog_3d's rows are left out of it.
    fog = (_dee(0.12, 0.88) + _dee(0.20, 0.70)) / 2
    fog_3d = (_dee(0.14, 0.86) + _dee(0.30, 0.60)) / 2
    text = re.sub(r"<[^>]+>", " ", page)
    assert f"{fog:.3f}" in text and f"{(fog + fog_3d) / 2:.3f}" not in text


def test_report_takes_a_zero_shot_set_of_depth_aware_rows_alone(tmp_path, cli):
    rows = [r for r in ROWS if r[0] != "fog"]
    res = cli("report", _csv(tmp_path / "m.csv", rows), "--on", "diode-c", "--out", tmp_path / "rep",
              "--published", "none")
    assert res.exit_code == 0, res.output
    text = re.sub(r"<[^>]+>", " ", (tmp_path / "rep" / "index.html").read_text())
    assert f"{_dee(0.10, 0.90):.3f}" in text  # the clean DEE
    assert f"{(_dee(0.14, 0.86) + _dee(0.30, 0.60)) / 2:.3f}" not in text  # fog_3d: no mDEE
