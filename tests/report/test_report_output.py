"""`robodepth report`'s OUT: checked by creating before any work, written whole or not at
all, an earlier report's stale figures removed (and said so), and no NaN or infinity in
what it writes (issue 26 items 5, 6, 7)."""

from __future__ import annotations

import json

import pytest

from tests.helpers.messages import one_line_error
from tests.helpers.report import evaluate_csv
from tests.helpers.report import extra_rows

pytest.importorskip("matplotlib")


@pytest.fixture
def no_work(monkeypatch):
    """Reading the results is the first work a report does: fail the test if it starts."""
    from robodepth_cli.report import write as W

    def refuse(*_):
        raise AssertionError("the report started work before refusing its --out")

    monkeypatch.setattr(W, "assemble", refuse)


@pytest.mark.parametrize("out", ["/proc/robodepth-report", "/proc/robodepth-a/b/report"])
def test_out_where_nothing_can_be_made_is_refused_first(tmp_path, cli, no_work, out):
    """/proc lets root pass os.access, yet nothing can be made there: the check creates."""
    k = evaluate_csv(tmp_path / "k.csv", "kitti-c", "MonoViT")
    one_line_error(cli("report", k, "--out", out), f"--out {out}: cannot write (")


def test_read_only_out_is_refused_first(tmp_path, cli, no_work, read_only_dir):  # noqa: F811
    k = evaluate_csv(tmp_path / "k.csv", "kitti-c", "MonoViT")
    for out in (read_only_dir / "rep", read_only_dir / "a" / "rep"):
        one_line_error(cli("report", k, "--out", out), f"--out {out}: cannot write (")


def _interrupt_at_third_figure(monkeypatch):
    from robodepth_cli.report import plot

    save, calls = plot.save, []

    def interrupted(fig, stem, *args, **kwargs):
        calls.append(stem)
        if len(calls) == 3:
            raise KeyboardInterrupt
        return save(fig, stem, *args, **kwargs)

    monkeypatch.setattr(plot, "save", interrupted)
    return calls


def test_interrupt_leaves_no_partial_report(tmp_path, cli, monkeypatch):
    k = evaluate_csv(tmp_path / "k.csv", "kitti-c", "MonoViT")
    out = tmp_path / "out"
    calls = _interrupt_at_third_figure(monkeypatch)
    res = cli("report", k, "--out", out)
    assert res.exit_code == 130 and len(calls) == 3
    assert res.output.strip().endswith("robodepth: interrupted; nothing was written")
    assert not out.exists() and list(tmp_path.iterdir()) == [k]  # no temporary folder left


@pytest.mark.slow
def test_interrupt_keeps_the_earlier_report_whole(tmp_path, cli, monkeypatch):
    k = evaluate_csv(tmp_path / "k.csv", "kitti-c", "MonoViT")
    out = tmp_path / "out"
    assert cli("report", k, "--out", out).exit_code == 0
    before = {p: p.read_bytes() for p in out.rglob("*") if p.is_file()}
    other = evaluate_csv(tmp_path / "other.csv", "kitti-c", "DIFFNet")
    _interrupt_at_third_figure(monkeypatch)
    res = cli("report", other, "--out", out)
    assert res.exit_code == 130 and "nothing was written" in res.output
    assert {p: p.read_bytes() for p in out.rglob("*") if p.is_file()} == before


@pytest.mark.slow
def test_second_report_leaves_nothing_stale(tmp_path, cli):
    """A report with a figure (severity) then one without it into the same OUT: the old
    figure files go, and the message says so; the user's own files stay."""
    plain = evaluate_csv(tmp_path / "plain.csv", "kitti-c", "MonoViT")
    extra = tmp_path / "extra.csv"
    extra.write_text(plain.read_text() + extra_rows({("fog", "2.5"): 0.24}))
    out = tmp_path / "out"
    assert cli("report", extra, "--out", out).exit_code == 0
    assert (out / "figures" / "severity.svg").exists()
    (out / "notes.txt").write_text("mine")
    (out / "figures" / "README").write_text("mine too")
    res = cli("report", plain, "--out", out)
    assert res.exit_code == 0, res.output
    figures = sorted(p.name for p in (out / "figures").iterdir())
    assert figures == sorted([f"{s}.{x}" for s in ("radar", "ce", "levels", "summary")
                              for x in ("svg", "pdf", "png")] + ["README"])
    assert (out / "notes.txt").read_text() == "mine" and (out / "figures" / "README").read_text() == "mine too"
    assert ("removed 3 figure files of the earlier report there: figures/severity.pdf, "
            "figures/severity.png, figures/severity.svg)") in res.output
    assert "Beyond the benchmark" not in (out / "index.html").read_text()
    assert not [p for p in out.rglob("*") if p.name.endswith(".part")]


def test_nan_in_an_unscored_column_is_refused_not_written(tmp_path, cli):
    """A NaN sq_rel was copied into scores.json as `NaN` (not JSON); abs_rel 1e308 crashed."""
    k = evaluate_csv(tmp_path / "k.csv", "kitti-c", "MonoViT")
    lines = k.read_text().splitlines()
    cells = lines[5].split(",")
    nan, huge = tmp_path / "nan.csv", tmp_path / "huge.csv"
    nan.write_text("\n".join(lines[:5] + [",".join(cells[:3] + ["nan"] + cells[4:])] + lines[6:]) + "\n")
    huge.write_text("\n".join(lines[:5] + [",".join(cells[:2] + ["1e308"] + cells[3:])] + lines[6:]) + "\n")
    out = tmp_path / "out"
    one_line_error(cli("report", nan, "--out", out), f"{nan}:6: sq_rel 'nan' is not a finite number")
    one_line_error(cli("report", huge, "--out", out), f"{huge}:6: abs_rel 1e+308 is absurd")
    assert not out.exists()


@pytest.mark.slow
def test_interrupt_while_moving_into_place_is_held_and_told(tmp_path, cli, monkeypatch):
    """Ctrl-C during the renames that replace an earlier report acts once they are done,
    and says the report was written (not "nothing was written")."""
    import os
    import signal

    from robodepth_cli.report import write as W

    k = evaluate_csv(tmp_path / "k.csv", "kitti-c", "MonoViT")
    out = tmp_path / "out"
    assert cli("report", k, "--out", out).exit_code == 0
    replace = W._replace

    def interrupted(*args):
        os.kill(os.getpid(), signal.SIGINT)
        return replace(*args)

    monkeypatch.setattr(W, "_replace", interrupted)
    other = evaluate_csv(tmp_path / "other.csv", "kitti-c", "DIFFNet")
    res = cli("report", other, "--name", "other", "--out", out)
    assert res.exit_code == 130, res.output
    assert res.output.strip().endswith(f"robodepth: interrupted; the report was written to {out}")
    assert json.loads((out / "scores.json").read_text())["models"][0]["model"] == "other"
