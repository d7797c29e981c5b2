"""Every file robodepth writes for another command carries its format version, and a file
of another version is refused in one line naming the release that made it."""

from __future__ import annotations

import json

import pytest

from robodepth_cli import formats
from tests.helpers.builds import copy_build

OTHER = {"schema_version": 99, "robodepth": "9.9.0"}


def _rewrite(path, **change):
    doc = json.loads(path.read_text())
    path.write_text(json.dumps({**doc, **change}))
    return doc


def _one_line(res, path):
    assert res.exit_code == 2 and res.output.count("\n") == 1, res.output
    assert res.output.startswith(f"robodepth: error: {path}: made by robodepth 9.9.0"), res.output
    assert "or use robodepth 9.9.0" in res.output


def test_the_stamp_and_the_check():
    doc = formats.stamp("robodepth-build")
    assert doc == {"schema": "robodepth-build", "schema_version": 1, "robodepth": formats.RELEASE}
    formats.check(doc, "robodepth-build", "build.json", "rebuild")
    with pytest.raises(formats.FormatError, match=r"^x: made by robodepth 9\.9\.0 \(robodepth-build "
                                                   r"version 99, this one reads 1\); rebuild or use"):
        formats.check({**doc, **OTHER}, "robodepth-build", "x", "rebuild")
    with pytest.raises(formats.FormatError, match="^x: not a robodepth-build file of a format version"):
        formats.check({"robodepth": "0.0.9"}, "robodepth-build", "x", "rebuild")


def test_a_build_record_of_another_version_gets_one_line(kitti_c_build, tmp_path_factory, cli):
    out = copy_build(kitti_c_build, tmp_path_factory)
    record = out / "build.json"
    doc = _rewrite(record)
    assert (doc["schema"], doc["schema_version"]) == ("robodepth-build", 1)
    _rewrite(record, **OTHER)
    _one_line(cli("verify", out), record)
    _one_line(cli("evaluate", out, "--pred", tmp_path_factory.mktemp("p"), "--out",
                  tmp_path_factory.mktemp("r") / "r.csv"), record)


def test_predictions_of_another_version_get_one_line(tmp_path, cli):
    from robodepth_cli.predictions import PredictionsError, read_record, write_record

    write_record(tmp_path, {"model": "m", "evaluate": {"kind": "depth"}})
    doc = read_record(tmp_path)
    assert (doc["schema"], doc["schema_version"], doc["model"]) == ("robodepth-predictions", 1, "m")
    _rewrite(tmp_path / "predictions.json", **OTHER)
    with pytest.raises(PredictionsError, match=r"predictions\.json: made by robodepth 9\.9\.0"):
        read_record(tmp_path)


def test_an_export_record_of_another_version_gets_one_line(tmp_path):
    from robodepth_cli.export.plan import ExportError
    from robodepth_cli.export.reader import read_export_record

    (tmp_path / "robodepth").mkdir()
    (tmp_path / "robodepth" / "export.json").write_text(json.dumps({"schema": "robodepth-export", **OTHER}))
    with pytest.raises(ExportError, match=r"export\.json: made by robodepth 9\.9\.0"):
        read_export_record(tmp_path)
