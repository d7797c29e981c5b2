"""The draw of a challenge set: which source frame, corruption and level each image is.

:func:`draw` is a pure function of its arguments; its generator is seeded from (seed,
"challenge", dataset), so the same call gives the same draw on any machine.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ..errors import InvalidValueError
from ..seeding import sample_rng

ID_HEX = 10  # digits of an image id: 16^10 ids, so a clash among a few thousand is rare (redrawn)


@dataclass(frozen=True)
class Pick:
    """One image of the challenge: its id, its place in the list, and what it is."""

    id: str
    position: int  # 0-based place in list.txt
    source: str  # the source frame's key
    corruption: str
    level: int


def balanced(n: int, names: Sequence, rng: np.random.Generator) -> list:
    """``n`` items of ``names``, each ``n // len(names)`` times and ``n % len(names)`` of
    them (chosen by ``rng``) once more: the counts differ by at most one."""
    q, r = divmod(n, len(names))
    extra = set(rng.permutation(len(names))[:r].tolist())
    return [name for i, name in enumerate(names) for _ in range(q + (i in extra))]


def draw(n: int, sources: Sequence[str], corruptions: Sequence[str], levels: Sequence[int],
         seed: int, dataset: str) -> list[Pick]:
    """``n`` picks, in list order.

    - Corruptions: each ``n // C`` or one more time (:func:`balanced`); within a corruption,
      its levels likewise.
    - Source frames: a random permutation of ``sources`` for the first ``len(sources)``
      images, another for the next, and so on: a frame is used at most ``ceil(n / S)``
      times, once while ``n <= S``. The (corruption, level) pairs are shuffled onto them;
      a frame never gets the same pair twice (:func:`_separate`).
    - The list order is another permutation, and each id ``ID_HEX`` random hex digits.
    """
    if n < 1:
        raise InvalidValueError(f"{n} images: need at least 1")
    if not sources or not corruptions or not levels:
        raise InvalidValueError("need at least one source frame, corruption and level")
    rng = sample_rng(seed, "challenge", 0, dataset)
    per_corruption = balanced(n, list(corruptions), rng)
    pairs = [(c, lv) for c in corruptions
             for lv in balanced(per_corruption.count(c), list(levels), rng)]
    frames = [sources[i] for _ in range(-(-n // len(sources))) for i in rng.permutation(len(sources))][:n]
    assigned = [pairs[k] for k in rng.permutation(n)]
    _separate(frames, assigned, rng)
    triples = [(f, *pair) for f, pair in zip(frames, assigned)]
    ids: list[str] = []
    seen: set[str] = set()
    while len(ids) < n:
        i = "".join(f"{d:x}" for d in rng.integers(0, 16, ID_HEX))
        if i not in seen:
            seen.add(i)
            ids.append(i)
    place = rng.permutation(n)
    picks = [Pick(ids[k], int(place[k]), *triples[k]) for k in range(n)]
    return sorted(picks, key=lambda p: p.position)


def _separate(frames: list, pairs: list, rng: np.random.Generator) -> None:
    """Swap ``pairs`` in place until no frame has the same pair twice: each repeat swaps with
    the first position (in an order drawn from ``rng``) of another frame where both swapped
    triples are new. :class:`InvalidValueError` when no such swap exists."""
    from collections import Counter

    used = Counter(zip(frames, pairs))
    for i in range(len(frames)):
        if used[(frames[i], pairs[i])] < 2:
            continue
        for j in rng.permutation(len(frames)).tolist():
            a, b = (frames[i], pairs[j]), (frames[j], pairs[i])
            if frames[j] != frames[i] and used[a] == 0 and used[b] == 0:
                used[(frames[i], pairs[i])] -= 1
                used[(frames[j], pairs[j])] -= 1
                pairs[i], pairs[j] = pairs[j], pairs[i]
                used[a] += 1
                used[b] += 1
                break
        else:
            raise InvalidValueError(f"{len(frames)} images from {len(set(frames))} frames: more "
                                    "than there are distinct (frame, corruption, level) triples")
