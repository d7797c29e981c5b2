"""Every refusal of the command line is one line, `robodepth: error: --flag: problem`, exit
2, as the refusals of the commands themselves are: a bad option value, a missing or unknown
option, never click's usage block and `Error: Invalid value` (issue 26). And `-j` means one
thing everywhere: N workers, or 'auto' or -1 for one per CPU."""

from __future__ import annotations

import click
import pytest

from robodepth_cli import workers
from robodepth_cli.cli import main
from robodepth_cli.commands.common import Jobs

from tests.helpers.messages import one_line_error


def one_line(res, start: str) -> str:
    line = one_line_error(res, start=start.removeprefix("robodepth: error: "))
    assert "Usage" not in res.output and "Error:" not in res.output
    return line


@pytest.mark.parametrize("args, flag", [
    (["evaluate", "D", "--pred", "P", "-j", "0"], "--jobs"),
    (["predict", "D", "-m", "x", "-o", "P", "--device", "tpu"], "--device"),
    (["preview", "x.png", "--thumb-width", "10"], "--thumb-width"),
    (["list", "--format", "xml"], "--format"),
    (["build", "kitti-c", "--root", "R", "--out", "O", "-j", "0"], "--jobs"),
    (["gt", "kitti", "--root", "R", "--out", "o.npz", "-j", "zero"], "--jobs"),
    (["report", "r.csv", "-o", "{FILE}"], "--out"),
], ids=["evaluate-j", "predict-device", "preview-thumb", "list-format", "build-j", "gt-j", "report-o"])
def test_bad_option_values_are_one_line(cli, tmp_path, args, flag):
    a_file = tmp_path / "a_file"
    a_file.write_text("")
    res = cli(*[str(a).replace("{FILE}", str(a_file)) for a in args])
    one_line(res, f"robodepth: error: {flag}: ")


def test_jobs_has_one_message_everywhere(cli):
    messages = {one_line(cli(*args, "-j", "0"), "robodepth: error: --jobs: ")
                for args in (["evaluate", "D", "--pred", "P"], ["build", "kitti-c", "--root", "R", "--out", "O"],
                             ["gt", "kitti", "--root", "R", "--out", "o.npz"])}
    assert messages == {"robodepth: error: --jobs: expected an integer >= 1, got 0 (or 'auto' or -1: "
                        "one worker per CPU)"}


def _options(command, path=()):
    """(command path, option) for every option of every command, subcommands included."""
    if isinstance(command, click.Group):
        for name, sub in command.commands.items():
            yield from _options(sub, (*path, name))
        return
    for p in command.params:
        yield path, command, p


def _bad_value(param):
    t = param.type
    if isinstance(t, click.Choice):
        return "nonsense"
    if isinstance(t, (click.IntRange, click.FloatRange)) and t.min is not None:
        return str(t.min - 1000)
    if isinstance(t, Jobs):
        return "0"
    if t is click.INT or t is click.FLOAT:
        return "ten"
    return None


BAD = [(path, param) for path, command, param in _options(main)
       if isinstance(param, click.Option) and not param.is_flag and _bad_value(param) is not None]


@pytest.mark.parametrize("path, param", BAD, ids=[f"{' '.join(p)} {o.opts[0]}" for p, o in BAD])
def test_every_typed_option_refuses_in_one_line(cli, path, param):
    """Every option click checks (a choice, a range, a number) of every command: the required
    arguments and options given, the bad value refused in one line naming the flag."""
    command = main
    for name in path:
        command = command.commands[name]
    args = [*path]
    for p in command.params:
        if isinstance(p, click.Argument):
            args.append("x")
        elif p.required and p is not param:
            args += [p.opts[0], "x"]
    flag = next(o for o in param.opts if o.startswith("--"))
    one_line(cli(*args, flag, _bad_value(param)), f"robodepth: error: {flag}: ")


def test_unknown_and_missing_options_are_one_line(cli):
    assert one_line(cli("evaluate", "D", "--pred", "P", "--bogus"), "robodepth: error: ") == (
        "robodepth: error: no such option '--bogus' (did you mean one of: '--jobs', '--out'?); "
        "see robodepth evaluate --help")
    assert one_line(cli("evaluate", "D"), "robodepth: error: ") == (
        "robodepth: error: --pred: required; see robodepth evaluate --help")
    assert one_line(cli("evaluate", "D", "--pred"), "robodepth: error: ") == (
        "robodepth: error: option '--pred' requires an argument; see robodepth evaluate --help")
    assert one_line(cli("gt", "kitti", "--bogus"), "robodepth: error: ").endswith(
        "; see robodepth gt kitti --help")
    assert one_line(cli("nonsense"), "robodepth: error: ") == (
        "robodepth: error: no such command 'nonsense'; see robodepth --help")


def test_a_bare_group_still_shows_its_help():
    from click.testing import CliRunner

    res = CliRunner().invoke(main, ["gt"])
    assert "Usage" in res.output and "kitti" in res.output


@pytest.mark.parametrize("value", ["-1", "auto", " auto "])
def test_jobs_minus_one_and_auto_mean_one_per_cpu_everywhere(cli, monkeypatch, tmp_path, value):
    from robodepth_cli.errors import RobodepthError
    from robodepth_cli.evaluation import evaluate as E
    from robodepth_cli.groundtruth import kitti as kitti_raw

    monkeypatch.setattr(workers, "default_jobs", lambda: 7)
    seen = []

    def record(*args, jobs, **kwargs):
        seen.append(jobs)
        raise RobodepthError("stop here")

    monkeypatch.setattr(E, "evaluate", record)
    monkeypatch.setattr(kitti_raw, "export", record)
    monkeypatch.setattr("robodepth_cli.api.open_dataset", lambda *a, **k: _FakeDataset())
    res = cli("evaluate", "D", "--pred", tmp_path, "--out", tmp_path / "r.csv", "-j", value)
    assert res.output.strip() == "robodepth: error: stop here", res.output
    (tmp_path / "raw").mkdir()
    split = tmp_path / "split.txt"
    split.write_text("2011_09_26/2011_09_26_drive_0002_sync 0000000069 l\n")
    res = cli("gt", "kitti", "--root", tmp_path / "raw", "--split", split, "--out", tmp_path / "g.npz",
              "-j", value)
    assert res.output.strip() == "robodepth: error: stop here", res.output
    assert seen == [7, 7]
    assert workers.parse_jobs(value) == 7  # build's --jobs and a config's jobs read it too


class _FakeDataset:
    failed = False
    name = "kitti-c"
