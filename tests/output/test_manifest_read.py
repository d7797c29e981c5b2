"""Reading a manifest: every row as Python's csv module reads the file, whether the text
has quoted fields (read by csv) or none (split at the commas)."""

from __future__ import annotations

import csv
import dataclasses

import pytest

from robodepth_cli.output.manifest import HEADER, Row, read_manifest_file, write_manifest_file

SHA = "ab" * 32


def _row(i: int, **kw) -> Row:
    return Row(**{**dict(output=f"fog/{i % 5 + 1}/k{i}.png", source=f"k{i}.png", variant="fog", level=i % 5 + 1,
                         seed=i, height=192, width=640, sha256=SHA, params="engine=numpy",
                         source_size=1000 + i, source_mtime=10 ** 18 + i, source_sha256=SHA), **kw})


def _as_csv_reads(path) -> list[list[str]]:
    with open(path, newline="", encoding="utf-8") as fh:
        return list(csv.reader(fh))[1:]


def _fields(row: Row) -> list[str]:
    return ["" if v is None else str(v) for v in dataclasses.astuple(row)]


@pytest.mark.parametrize("errors", [
    {},  # no quote anywhere: split at the commas
    {3: "ValueError: a, b and \"c\"", 7: "two\nlines"},  # quoted fields, one over two lines
])
def test_rows_are_read_as_csv_reads_them(tmp_path, errors):
    rows = [_row(i, sha256="", error=errors[i]) if i in errors else _row(i) for i in range(12)]
    rows.append(_row(12, level=2.5, output="fog/2.5/k12.png", source_size=None, source_mtime=None))
    path = tmp_path / "manifest.csv"
    write_manifest_file(path, rows)
    got = read_manifest_file(path)
    assert list(got.values()) == rows
    assert [_fields(r) for r in got.values()] == _as_csv_reads(path)
    assert all(type(r) is Row and hash(r) == hash(dataclasses.replace(r)) for r in got.values())


def test_a_damaged_row_is_named_by_its_line(tmp_path):
    path = tmp_path / "manifest.csv"
    path.write_text(HEADER + ",".join(_fields(_row(0))) + "\n" + "fog/1/k1.png,k1.png,fog,1,x,1,1," + SHA
                    + ",,,,,\n")
    from robodepth_cli.output.manifest import ManifestError

    with pytest.raises(ManifestError, match=r"manifest\.csv:3: damaged row \(invalid literal for int"):
        read_manifest_file(path)
