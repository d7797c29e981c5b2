"""Per-job random generators.

A job's generator depends only on (global seed, dataset, variant, level, relative source
path), so its output does not depend on worker count, order or what was built before.
A level is keyed by its canonical text (``3``; ``2.5`` for a decimal level), so integer
levels keep the streams they always had. A chain's step ``k`` is keyed by (global seed,
dataset, the chain's canonical text, ``step k``, relative source path).
"""

from __future__ import annotations

import hashlib

import numpy as np

from .sourcekeys import level_text


def job_seed_sequence(seed: int, dataset: str, variant: str, level, relpath: str) -> np.random.SeedSequence:
    return _seed_sequence(seed, dataset, variant, level_text(level), relpath)


def _seed_sequence(seed: int, dataset: str, variant: str, level: str, relpath: str) -> np.random.SeedSequence:
    key = "\x1f".join((str(int(seed)), dataset, variant, level, relpath.replace("\\", "/")))
    digest = hashlib.sha256(key.encode("utf-8")).digest()
    # 256 bits of the digest as entropy: distinct keys give independent streams.
    return np.random.SeedSequence([int.from_bytes(digest[i:i + 4], "little") for i in range(0, 32, 4)])


def job_rng(seed: int, dataset: str, variant: str, level, relpath: str) -> np.random.Generator:
    """The generator of one job."""
    return np.random.Generator(np.random.PCG64(job_seed_sequence(seed, dataset, variant, level, relpath)))


def chain_rngs(seed: int, dataset: str, chain, relpath: str) -> list[np.random.Generator]:
    """One generator per step of ``chain`` (a :class:`~.corruptions.chains.Chain`) for the
    image ``relpath``: step ``k`` (from 1) keyed by the chain's canonical text and
    ``step k``, so each step has its own stream and none is a single corruption's."""
    return [np.random.Generator(np.random.PCG64(_seed_sequence(seed, dataset, chain.text, f"step {k}", relpath)))
            for k in range(1, len(chain.steps) + 1)]


def sample_rng(seed: int, purpose: str, epoch: int, key: str) -> np.random.Generator:
    """The generator of one training sample's draws (``purpose`` names the transform):
    keyed by (seed, purpose, epoch, key), so it is the same in any process or worker."""
    return np.random.Generator(np.random.PCG64(_seed_sequence(seed, purpose, f"epoch {int(epoch)}", "draw", key)))


def content_key(image: np.ndarray) -> str:
    """The draw key of an image known by its pixels alone (``corrupt`` and ``preview``
    without ``--as``): ``"pixels:"`` and the sha256 of its shape, dtype and bytes, so
    byte-identical copies draw alike whatever their file names, and any other image draws
    its own streams."""
    a = np.ascontiguousarray(image)
    h = hashlib.sha256(f"{a.shape}|{a.dtype.str}|".encode("ascii"))
    h.update(a.data)
    return f"pixels:{h.hexdigest()}"


def check_seed(value, where: str = "--seed") -> int:
    """``value`` as a seed: an integer >= 0 (text of one is accepted, as flags arrive).

    The one rule for every command, ``build --seed`` and ``corrupt``/``preview -s`` alike;
    :class:`~robodepth_cli.errors.RobodepthError` naming ``where`` otherwise.
    """
    from .errors import RobodepthError
    from .integers import int_from_text, is_int

    value = int_from_text(value)
    if not is_int(value) or value < 0:
        raise RobodepthError(f"{where}: expected an integer >= 0, got {value!r}")
    return value
