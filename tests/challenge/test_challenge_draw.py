"""The draw: balanced corruptions and levels, frames used once while N allows, seeded."""

from __future__ import annotations

from collections import Counter

import pytest

from robodepth_cli.benchmark_facts import BENCHMARKS
from robodepth_cli.challenge.draw import draw
from robodepth_cli.errors import RobodepthError

KITTI = BENCHMARKS["kitti-c"]
FRAMES = [f"frame{i:03d}.png" for i in range(697)]


def _spread(counter, keys):
    counts = [counter.get(k, 0) for k in keys]
    return max(counts) - min(counts)


@pytest.mark.parametrize("n, frames", [(500, FRAMES), (37, FRAMES), (1000, FRAMES[:100])])
def test_balanced_and_frames_once_while_n_allows(n, frames):
    picks = draw(n, frames, KITTI.corruptions, [1, 2, 3, 4, 5], seed=11, dataset="kitti-c")
    assert len(picks) == n and [p.position for p in picks] == list(range(n))
    per_corruption = Counter(p.corruption for p in picks)
    assert _spread(per_corruption, KITTI.corruptions) <= 1
    for c in KITTI.corruptions:
        assert _spread(Counter(p.level for p in picks if p.corruption == c), [1, 2, 3, 4, 5]) <= 1
    uses = Counter(p.source for p in picks)
    assert max(uses.values()) == -(-n // len(frames))
    if n <= len(frames):
        assert len(uses) == n
    assert len({(p.source, p.corruption, p.level) for p in picks}) == n
    assert len({p.id for p in picks}) == n
    assert all(len(p.id) == 10 and int(p.id, 16) >= 0 for p in picks)


def test_same_seed_same_draw_other_seed_other_draw():
    a = draw(200, FRAMES, KITTI.corruptions, [1, 2, 3], seed=3, dataset="kitti-c")
    assert a == draw(200, FRAMES, KITTI.corruptions, [1, 2, 3], seed=3, dataset="kitti-c")
    b = draw(200, FRAMES, KITTI.corruptions, [1, 2, 3], seed=4, dataset="kitti-c")
    assert [(p.source, p.corruption, p.level) for p in a] != [(p.source, p.corruption, p.level) for p in b]
    assert {p.id for p in a}.isdisjoint({p.id for p in b})


def test_the_order_is_not_the_key_order():
    picks = draw(500, FRAMES, KITTI.corruptions, [1, 2, 3, 4, 5], seed=0, dataset="kitti-c")
    by_corruption = [p.corruption for p in picks]
    # runs of one corruption as long as a shuffled list has, not 27 in a row
    longest, run = 1, 1
    for x, y in zip(by_corruption, by_corruption[1:]):
        run = run + 1 if x == y else 1
        longest = max(longest, run)
    assert longest < 6
    assert [p.id for p in picks] != sorted(p.id for p in picks)


def test_more_images_than_triples_is_refused():
    with pytest.raises(RobodepthError, match="distinct"):
        draw(7, ["a", "b"], ["fog"], [1, 2, 3], seed=0, dataset="kitti-c")
