"""Make docs/images/report-size.png, report-modality.png and report-finetune.png, the
figures of docs/report.md's further analyses:

    PYTHONPATH=. python docs/images/report_analyses.py

The results files are written from the paper's published per-corruption DEE (as the report
tests write them, tests/helpers/report.py), so the numbers are the paper's models' under
other names; the sizes are given by hand (--params, --flops): an illustration, not
measurements.
"""

from __future__ import annotations

import shutil
import tempfile
from pathlib import Path

from click.testing import CliRunner

from robodepth_cli.cli import main
from tests.helpers.report import evaluate_csv

HERE = Path(__file__).resolve().parent


def report(tmp: Path, files: list[tuple[str, str, float]], *flags: str) -> Path:
    paths, names = [], []
    for name, published, tilt in files:
        paths.append(str(evaluate_csv(tmp / f"{len(paths)}.csv", "kitti-c", published, tilt)))
        names += ["--name", name]
    out = tmp / f"out{len(list(tmp.glob('out*')))}"
    res = CliRunner().invoke(main, ["report", *paths, *names, *flags, "--out", str(out)],
                             catch_exceptions=False)
    assert res.exit_code == 0, res.output
    return out / "figures"


def main_() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        figs = report(tmp, [("model A", "MonoViT", 0.04), ("model B", "Lite-Mono Large", 0.04),
                            ("model C", "DNet R18", 0.04)],
                      "--params", "model A=27.9M", "--flops", "model A=32G",
                      "--params", "model B=8.7M", "--flops", "model B=15G",
                      "--params", "model C=14.3M", "--flops", "model C=16G")
        shutil.copy(figs / "size.png", HERE / "report-size.png")
        figs = report(tmp, [("ours", "DNet R18", 0.04)], "--groups", "all")
        shutil.copy(figs / "groups-modality.png", HERE / "report-modality.png")
        figs = report(tmp, [("baseline", "MonoDepth2 R18", 0.04), ("+ fog", "MonoDepth2 HR", 0.1),
                            ("+ snow", "MonoDepth2 nopt", 0.02), ("+ dark", "DNet R18", 0.05),
                            ("+ gaussian noise", "CADepth", 0.03)],
                      "--tag", "+ fog:finetune=fog", "--tag", "+ snow:finetune=snow",
                      "--tag", "+ dark:finetune=dark", "--tag", "+ gaussian noise:finetune=gaussian_noise")
        shutil.copy(figs / "finetune.png", HERE / "report-finetune.png")


if __name__ == "__main__":
    main_()
