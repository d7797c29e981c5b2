"""Where messages go (issue 19): every command says what it wrote with one `wrote ...` line
on stderr (stdout carries only results: tables and JSON, so `--json | jq` works), and
evaluate's progress bar estimates from the images alone, not from the ground-truth load
before them."""

from __future__ import annotations

import json

import pytest

from tests.helpers.gt_trees import write_labeled, write_split, write_tree

FRAME = "kitti_raw/2011_09_26/2011_09_26_drive_0002_sync/image_02/data/0000000069.png"


@pytest.fixture(scope="module")
def ckpt(tmp_path_factory):
    from tests.helpers.adain import save_checkpoints

    return save_checkpoints(tmp_path_factory.mktemp("ckpt"))[:2]


def commands(tmp, fixtures, kitti_c, kitti_pred, ckpt):  # noqa: F811
    root, split, _ = write_tree(tmp, fixtures, frames_per_drive=1)
    mat = tmp / "labeled.mat"
    write_labeled(mat)
    results = tmp / "r.csv"
    results.write_text("corruption,level,abs_rel,a1\nclean,0,0.1,0.9\nfog,1,0.1,0.9\n")
    frame = fixtures / FRAME
    return {
        "corrupt": (["corrupt", frame, "-c", "fog", "-l", "1", "--size", "32x96", "--out", tmp / "f.png"],
                    tmp / "f.png"),
        "corrupt many": (["corrupt", frame, "-c", "fog,contrast", "-l", "1", "--size", "32x96", "--out",
                          tmp / "many/"], tmp / "many"),
        "preview": (["preview", frame, "-c", "fog", "--size", "32x96", "--out", tmp / "p.png"], tmp / "p.png"),
        "stylize": (["stylize", frame, "--style", fixtures / "styles/sketch.png", "--vgg", ckpt[0],
                     "--decoder", ckpt[1], "--size", "32x96", "--style-size", "32", "--out", tmp / "s.png"],
                    tmp / "s.png"),
        "score --plot": (["score", results, "-b", "kitti-c", "--allow-partial", "--plot", tmp / "ce.png"],
                         tmp / "ce.png"),
        "evaluate": (["evaluate", kitti_c[0], "--pred", kitti_pred, "--out", tmp / "e.csv"], tmp / "e.csv"),
        "gt kitti": (["gt", "kitti", "--root", root, "--split", split, "--out", tmp / "g.npz"], tmp / "g.npz"),
        "gt nyu": (["gt", "nyu", "--root", mat, "--split", write_split(tmp / "ns.txt", [0]), "--out",
                    tmp / "NYU"], tmp / "NYU"),
    }


NAMES = ["corrupt", "corrupt many", "preview", "stylize", "score --plot", "evaluate", "gt kitti", "gt nyu"]


@pytest.mark.parametrize("name", NAMES)
def test_every_command_says_what_it_wrote_on_stderr(name, tmp_path, fixtures_dir, kitti_c, kitti_pred,  # noqa: F811
                                                    ckpt, cli):
    args, written = commands(tmp_path, fixtures_dir, kitti_c, kitti_pred, ckpt)[name]
    res = cli(*args)
    assert res.exit_code == 0, res.output
    assert written.exists()
    wrote = [ln for ln in res.stderr.splitlines() if ln.startswith("wrote ")]
    assert len(wrote) == 1 and str(written).rstrip("/") in wrote[0], res.stderr
    assert "wrote" not in res.stdout


def test_json_stdout_stays_json(kitti_c, kitti_pred, tmp_path, cli):  # noqa: F811
    res = cli("evaluate", kitti_c[0], "--pred", kitti_pred, "--out", tmp_path / "r.csv", "--json")
    assert json.loads(res.stdout)["csv"] == str(tmp_path / "r.csv")


def test_evaluate_progress_starts_its_clock_with_the_images(kitti_c, kitti_pred, tmp_path,  # noqa: F811
                                                            monkeypatch, cli):
    """The ground truth takes a while to read before the first image; an estimate that counts
    it predicts hours for minutes of work. A fake clock that only moves while the ground
    truth is read: the bar's elapsed time at the first image must not include it."""
    import tqdm
    import tqdm.std

    from robodepth_cli.evaluation import evaluate as E

    now = [1000.0]
    monkeypatch.setattr(tqdm.std, "time", lambda: now[0])
    real = E.load_ground_truth

    def slow_load(*a, **k):
        now[0] += 3600.0
        return real(*a, **k)

    monkeypatch.setattr(E, "load_ground_truth", slow_load)
    seen = []

    class Shown(tqdm.std.tqdm):
        def __init__(self, *a, **k):
            k["disable"] = False
            super().__init__(*a, **k)

        def update(self, n=1):
            super().update(n)
            seen.append((self.n, self.total, self.format_dict["elapsed"]))

    monkeypatch.setattr(tqdm, "tqdm", Shown)
    res = cli("evaluate", kitti_c[0], "--pred", kitti_pred, "--out", tmp_path / "r.csv")
    assert res.exit_code == 0, res.output
    # The bar advances a block of maps at a time (a variant's maps are judged together); its
    # clock starts with the first images, not before the hour the ground truth took.
    assert seen and seen[0][1] == 10 and 1 <= seen[0][0] <= 10 and seen[0][2] < 3600, seen
    assert seen[-1][:2] == (10, 10), seen
