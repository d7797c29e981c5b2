"""`score --benchmark custom` and `evaluate --score` on a custom set: its levels are those of
its rows (or its build), its categories those it has; nothing invented, nothing n/a."""

from __future__ import annotations

from tests.helpers.trees import random_image, save


def _dee(ar, a1):
    return (ar - a1 + 1) / 2


ROWS = [("clean", 0, 0.10, 0.90), ("fog", 1, 0.12, 0.88), ("fog", 3, 0.20, 0.70),
        ("gaussian_noise", 1, 0.15, 0.85), ("gaussian_noise", 3, 0.25, 0.65)]


def test_score_custom_takes_the_levels_of_its_rows(tmp_path, cli):
    csv = tmp_path / "r.csv"
    csv.write_text("corruption,level,abs_rel,sq_rel,rmse,rmse_log,a1,a2,a3\n" + "".join(
        f"{c},{lv},{ar},0.5,4.0,0.2,{a1},0.95,0.98\n" for c, lv, ar, a1 in ROWS))
    res = cli("score", csv, "--benchmark", "custom")
    assert res.exit_code == 0, res.output
    out = res.output
    assert "missing" not in out and "(levels" not in out
    # RR = 100 * sum_l (1 - DEE_l) / (L * (1 - clean DEE)), over the two levels present.
    clean = _dee(0.10, 0.90)
    rr_fog = 100 * ((1 - _dee(0.12, 0.88)) + (1 - _dee(0.20, 0.70))) / (2 * (1 - clean))
    assert f"{rr_fog:.2f}" in out
    # Only the categories it has: weather (fog) and noise (gaussian_noise).
    assert "sensor & movement" not in out and "weather & lighting" in out
    assert not [ln for ln in out.splitlines() if "mean" in ln and "n/a" in ln.split("mean")[1][:10]]


def test_evaluate_score_on_a_build_with_levels_1_and_3(tmp_path, cli):
    import numpy as np

    (tmp_path / "depth").mkdir()
    for i in range(2):
        save(tmp_path / "img" / f"{i}.png", random_image(32, 40, seed=i))
        np.save(tmp_path / "depth" / f"{i}.npy", np.full((32, 40), 5.0 + i, np.float32))
    out = tmp_path / "out"
    res = cli("build", "custom", "--root", tmp_path / "img", "--depth", tmp_path / "depth", "--out",
              out, "--corruptions", "fog", "--levels", "1,3", "--jobs", "1")
    assert res.exit_code == 0, res.output
    (tmp_path / "m.py").write_text("import numpy as np\n\ndef f(images):\n"
                                   "    return (2 + images.mean(axis=3) / 30).astype(np.float32)\n")
    assert cli("predict", out, "-m", f"python:{tmp_path / 'm.py'}:f", "--kind", "depth", "-o",
               tmp_path / "P").exit_code == 0
    res = cli("evaluate", out, "--pred", tmp_path / "P", "--out", tmp_path / "r.csv", "--score")
    assert res.exit_code == 0, res.output
    assert "(levels" not in res.output and "sensor & movement" not in res.output, res.output
    assert "missing" not in res.output
