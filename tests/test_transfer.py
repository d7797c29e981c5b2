"""`robodepth transfer`: Spearman's rank correlation between a synthetic corruption and a
real condition, with a bootstrap interval, from results CSVs; values worked out by hand."""

from __future__ import annotations

import json

import pytest

from robodepth_cli.evaluation.transfer import bootstrap, spearman


def test_spearman_by_hand():
    # no ties: rho = 1 - 6 sum d^2 / (n (n^2 - 1)) = 1 - 6 * 2 / 60
    assert spearman([1, 2, 3, 4], [10, 30, 20, 40]) == pytest.approx(0.8)
    assert spearman([1, 2, 3], [3, 2, 1]) == pytest.approx(-1.0)
    # ties share their average rank: x ranks 1.5, 1.5, 3 against 1, 2, 3 -> 1.5 / sqrt(1.5 * 2)
    assert spearman([5, 5, 7], [1, 2, 3]) == pytest.approx(1.5 / 3 ** 0.5)
    assert spearman([1, 1, 1], [1, 2, 3]) != spearman([1, 1, 1], [1, 2, 3])  # NaN: no ranking


def test_bootstrap_is_seeded_and_bounded():
    x, y = [0.1, 0.2, 0.3, 0.4, 0.5], [0.2, 0.1, 0.4, 0.3, 0.5]
    low, high = bootstrap(x, y, n=500, seed=3)
    assert (low, high) == bootstrap(x, y, n=500, seed=3)
    assert -1 <= low <= spearman(x, y) <= high <= 1
    assert bootstrap(x, x, n=200) == (1.0, 1.0)  # any resample of a perfect agreement


def _results(path, rows):
    path.write_text("corruption,level,abs_rel,a1\n" + "".join(f"{c},{lv},{a},{d}\n" for c, lv, a, d in rows))
    return path


def test_command(tmp_path, cli):
    # DEE = (abs_rel + 1 - a1) / 2. Synthetic fog DEE (mean of levels 1, 2) per model, real
    # foggy DEE (clean row):
    #   a: fog (0.2+0.4)/2 -> 0.3,  b: 0.4,  c: 0.5,  d: 0.6
    #   real: a 0.25, b 0.45, c 0.35, d 0.65  -> ranks 1 3 2 4 against 1 2 3 4: rho 0.8
    fog = {"a": (0.2, 0.4), "b": (0.3, 0.5), "c": (0.4, 0.6), "d": (0.5, 0.7)}
    real = {"a": 0.25, "b": 0.45, "c": 0.35, "d": 0.65}
    args = []
    for m, (l1, l2) in fog.items():
        # abs_rel = DEE, a1 = 1 gives DEE = abs_rel / 2; so write abs_rel = 2 DEE
        rows = [("clean", 0, 0.1, 1.0), ("fog", 1, 2 * l1, 1.0), ("fog", 2, 2 * l2, 1.0)]
        args += ["--synthetic", f"{m}={_results(tmp_path / f'{m}_syn.csv', rows)}"]
        clean = _results(tmp_path / f"{m}_foggy.csv", [("clean", 0, 2 * real[m], 1.0)])
        args += ["--real", f"{m}:foggy={clean}"]
    res = cli("transfer", *args, "--json")
    assert res.exit_code == 0, res.output
    (fog_row,) = [r for r in json.loads(res.stdout) if r["synthetic"] == "fog"]
    assert fog_row["rho"] == pytest.approx(0.8)
    assert fog_row["models"]["b"] == {"synthetic_dee": pytest.approx(0.4), "real_dee": pytest.approx(0.45)}
    assert fog_row["interval"][0] <= 0.8 <= fog_row["interval"][1]
    res = cli("transfer", *args, "--plot", tmp_path / "t.png")
    assert res.exit_code == 0, res.output
    assert "fog" in res.output and "0.800" in res.output
    assert (tmp_path / "t.png").read_bytes()[:4] == b"\x89PNG"
    # fewer than three models on a pair, a malformed flag, a custom table
    res = cli("transfer", *args[:8])
    assert res.exit_code == 2 and "at least 3 models" in res.output
    res = cli("transfer", *args, "--real", "a=x.csv")
    assert res.exit_code == 2 and "expected MODEL:CONDITION=CSV" in res.output
    (tmp_path / "p.yaml").write_text("pairs:\n  - {synthetic: haze, real: foggy}\n")
    res = cli("transfer", *args, "--pairs", tmp_path / "p.yaml")
    assert res.exit_code == 2 and "unknown corruption 'haze'" in res.output
