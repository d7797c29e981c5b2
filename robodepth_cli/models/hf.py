"""Hugging Face ``transformers`` depth-estimation models: ``AutoModelForDepthEstimation`` with
its own image processor, from a local folder or the local cache only (nothing is
downloaded). Each map goes through the processor's ``post_process_depth_estimation`` at its
image's size (without that method, DPT's rule: bicubic, ``align_corners=False``). What the
maps hold (relative disparity or metric depth) is the config's ``depth_estimation_type``,
else the model type's, as docs/predict.md lists."""

from __future__ import annotations

import inspect
from pathlib import Path

import numpy as np

from ..errors import RobodepthError
from .base import KINDS, Model, default_alignment, torch_device

RELATIVE_TYPES = ("dpt",)
METRIC_TYPES = ("zoedepth", "depth_pro", "glpn")


def load(arg: str, spec: str, *, device: str = "auto", kind: str | None = None,
         metric: bool | None = None) -> Model:
    """The transformers model ``arg`` (a folder, or a name in the local cache)."""
    import torch
    import transformers

    transformers.utils.logging.set_verbosity_error()
    transformers.utils.logging.disable_progress_bar()
    source, where = _source(arg, spec)
    config, model, processor = _load_parts(source, where, arg, spec)
    model_type = getattr(config, "model_type", "?")
    kind, metric = _output(config, model_type, kind, metric, spec)
    dev = torch_device(device)
    model = model.to(dev).eval()
    post = getattr(processor, "post_process_depth_estimation", None)
    post_args = set(inspect.signature(post).parameters) if post is not None else set()

    def run(images: np.ndarray):
        sizes = [tuple(img.shape[:2]) for img in images]
        inputs = processor(images=list(images), return_tensors="pt")
        inputs = {k: v.to(dev) if hasattr(v, "to") else v for k, v in inputs.items()}
        with torch.no_grad():
            outputs = model(**inputs)
        if post is None:
            return _resize_bicubic(outputs.predicted_depth, sizes)
        kwargs = {"target_sizes": sizes}
        if "source_sizes" in post_args:
            kwargs["source_sizes"] = sizes
        maps = [r["predicted_depth"] for r in post(outputs, **kwargs)]
        return [m.reshape(size) for m, size in zip(maps, sizes)]

    align, space = default_alignment(metric)
    identity = {"source": str(source), "model_type": model_type,
                "commit": getattr(config, "_commit_hash", None)}
    if where == "folder":
        identity["files"] = _files(Path(source))
    return Model(spec=spec, adapter="hf", kind=kind, metric=metric, align=align,
                 align_space=space, input_size=_input_size(processor), identity=identity,
                 run=run, device=dev, options={"model_type": model_type}, modules=(model,))


def _load_parts(source, where: str, arg: str, spec: str):
    """(config, model, image processor) of the transformers model at ``source``, from local
    files only; :class:`RobodepthError` saying which part is missing or unusable."""
    from transformers import AutoConfig, AutoImageProcessor, AutoModelForDepthEstimation

    try:
        config = AutoConfig.from_pretrained(source, local_files_only=True)
    except OSError:
        if where == "cache":
            from huggingface_hub import constants

            raise RobodepthError(f"{spec}: {arg} is not in the local Hugging Face cache "
                                 f"({constants.HF_HUB_CACHE}); download it first with "
                                 f"'hf download {arg}' (needs internet), or give a local folder "
                                 "(hf:PATH)") from None
        raise RobodepthError(f"{spec}: {source} holds no transformers model (no readable "
                             "config.json)") from None
    except ValueError as exc:
        raise RobodepthError(f"{spec}: {source}: unusable config ({_first_line(exc)})") from None
    model_type = getattr(config, "model_type", "?")
    try:
        model = AutoModelForDepthEstimation.from_pretrained(source, local_files_only=True)
    except ValueError as exc:
        if "Unrecognized configuration class" in str(exc):
            raise RobodepthError(f"{spec}: a {model_type} model, not a depth-estimation model "
                                 "(transformers' AutoModelForDepthEstimation does not know it)") from None
        raise RobodepthError(f"{spec}: cannot load the model ({_first_line(exc)})") from None
    except (OSError, RuntimeError) as exc:
        raise RobodepthError(f"{spec}: cannot load the model ({_first_line(exc)})") from None
    try:
        processor = AutoImageProcessor.from_pretrained(source, local_files_only=True)
    except (OSError, ValueError) as exc:
        raise RobodepthError(f"{spec}: no usable image processor beside the model "
                             f"(preprocessor_config.json; {_first_line(exc)})") from None
    return config, model, processor


def _source(arg: str, spec: str) -> tuple[str, str]:
    """(what to pass to from_pretrained, "folder" or "cache")."""
    path = Path(arg).expanduser()
    if path.is_dir():
        return str(path.resolve()), "folder"
    if path.exists():
        raise RobodepthError(f"{spec}: {arg} is not a folder (give a folder written by "
                             "save_pretrained, or a model name such as org/name)")
    # A Hub name is org/name (a few old ones are a bare name): anything else (a leading ./
    # or ~, several slashes, a trailing one, a backslash, a bare name not in the cache) was
    # meant as a folder, and "download it" would be no advice.
    looks_like_path = (arg.startswith((".", "/", "~")) or arg.count("/") > 1
                       or arg.endswith("/") or "\\" in arg
                       or ("/" not in arg and not _cached(arg)))
    if looks_like_path:
        raise RobodepthError(f"{spec}: no folder {arg} (from {Path.cwd()}); give a folder written "
                             "by save_pretrained, or a cached model's name such as org/name")
    return arg, "cache"


def _cached(name: str) -> bool:
    """Whether the local Hugging Face cache holds a model of this name."""
    from huggingface_hub import constants

    return (Path(constants.HF_HUB_CACHE) / f"models--{name.replace('/', '--')}").is_dir()


def _output(config, model_type: str, kind: str | None, metric: bool | None,
            spec: str) -> tuple[str, bool]:
    declared = getattr(config, "depth_estimation_type", None)
    if metric is None:
        if declared in ("relative", "metric"):
            metric = declared == "metric"
        elif model_type in RELATIVE_TYPES or model_type in METRIC_TYPES:
            metric = model_type in METRIC_TYPES
        elif kind is None:
            raise RobodepthError(f"{spec}: cannot tell whether this {model_type} model predicts "
                                 "relative inverse depth or metric depth; say --kind disp "
                                 "--relative, or --kind depth --metric")
        else:
            metric = False
    if kind is None:
        kind = "depth" if metric else "disp"
    if kind not in KINDS:
        raise RobodepthError(f"--kind {kind!r}: valid: {', '.join(KINDS)}")
    return kind, metric


def _input_size(processor):
    size = getattr(processor, "size", None)
    if size is None:
        return None
    try:
        return dict(size)
    except (TypeError, ValueError):
        return size if isinstance(size, (int, list)) else str(size)


def _files(folder: Path) -> dict:
    """Name -> sha256 of the folder's files, to notice a model saved anew over it."""
    from ..files import sha256_file

    return {p.name: sha256_file(p) for p in sorted(folder.iterdir()) if p.is_file()}


def _resize_bicubic(depth, sizes):
    import torch

    return [torch.nn.functional.interpolate(d[None, None], size=s, mode="bicubic",
                                            align_corners=False)[0, 0]
            for d, s in zip(depth, sizes)]


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__
