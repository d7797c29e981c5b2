"""`robodepth verify OUT`: re-hash the tree against its manifest."""

from __future__ import annotations

from tests.helpers.trees import kitti_key, kitti_tree


def test_verify_reports_missing_changed_and_extra(tmp_path, cli):
    root = tmp_path / "kitti_raw"
    split = kitti_tree(root, [(3, "l", ".png")])
    out = tmp_path / "out"
    res = cli("build", "kitti-c", "--root", root, "--split", split, "--out", out, "--size", "64x96",
              "--corruptions", "contrast,color_quant", "--levels", "1,2", "--jobs", "1")
    assert res.exit_code == 0, res.output
    ok = cli("verify", out)
    assert ok.exit_code == 0 and "5 files match the manifest" in ok.output

    missing, changed = f"contrast/2/{kitti_key(3)}", f"color_quant/1/{kitti_key(3)}"
    (out / missing).unlink()
    data = bytearray((out / changed).read_bytes())
    data[-20] ^= 1  # one bit, same size
    (out / changed).write_bytes(bytes(data))
    (out / "contrast/3").mkdir()
    (out / "contrast/3/stray.png").write_bytes(b"x")

    res = cli("verify", out)
    assert res.exit_code == 1
    lines = res.output.splitlines()
    assert lines[lines.index("missing: 1") + 1].strip() == missing
    assert lines[lines.index("changed: 1") + 1].strip() == changed
    assert lines[lines.index("extra: 1") + 1].strip() == "contrast/3/stray.png"
    assert "4 files checked; the tree does not match its manifest" in res.output


def test_verify_refuses_a_directory_without_manifest(tmp_path, cli):
    res = cli("verify", tmp_path)
    assert res.exit_code == 2
    assert res.output.strip() == f"robodepth: error: {tmp_path}: no manifest.csv; not a robodepth build output"
    res = cli("verify", tmp_path / "nowhere")
    assert res.exit_code == 2 and "nowhere: does not exist" in res.output


def test_verify_progress_bar_has_a_total(tmp_path, cli, monkeypatch):
    """The bar counts to the number of files to hash (not `3640file [00:00, ...]` with no
    end in sight): the total is given once the manifest is read, and reached (issue 26)."""
    from robodepth_cli import progress

    root = tmp_path / "kitti_raw"
    split = kitti_tree(root, [(3, "l", ".png"), (4, "l", ".png")])
    out = tmp_path / "out"
    res = cli("build", "kitti-c", "--root", root, "--split", split, "--out", out, "--size", "64x96",
              "--corruptions", "contrast", "--levels", "1,2", "--jobs", "1")
    assert res.exit_code == 0, res.output
    bars = []

    class Bar:  # what a tqdm bar is told
        def __init__(self, unit, total=None, **options):
            self.total, self.n = total, 0
            bars.append(self)

        def reset(self, total=None):
            self.total, self.n = total, 0

        def update(self, n=1):
            self.n += n

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            return False

    monkeypatch.setattr(progress, "bar", Bar)
    res = cli("verify", out)
    assert res.exit_code == 0 and "6 files match the manifest" in res.output
    assert [(b.total, b.n) for b in bars] == [(6, 6)]
