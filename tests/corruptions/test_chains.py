"""Compound corruptions: chains such as ``fog:3+gaussian_noise:2.5`` (issue 23)."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from tests.helpers.paths import REFERENCE
from robodepth_cli import seeding
from robodepth_cli.corruptions import REGISTRY, corrupt, corrupt_chain
from robodepth_cli.corruptions.chains import MAX_STEPS, Chain, Step, looks_like_chain, parse_chain
from robodepth_cli.errors import RobodepthError
from robodepth_cli.errors import RobodepthError


def frame() -> np.ndarray:
    img = Image.open(REFERENCE / "kitti" / "kitti_like_md2__input.png").convert("RGB")
    return np.asarray(img)[:96, :200]


def test_a_chain_has_a_canonical_text_and_a_safe_directory_name():
    c = parse_chain(" fog : 3.0 + gaussian_noise:2.50")
    assert c == Chain((Step("fog", 3), Step("gaussian_noise", 2.5)))
    assert c.text == "fog:3+gaussian_noise:2.5"
    assert c.dirname == "fog-3+gaussian_noise-2.5"
    assert parse_chain(c.dirname) == c
    assert set(c.dirname) <= set("abcdefghijklmnopqrstuvwxyz_0123456789-+.")
    assert looks_like_chain(c.text) and looks_like_chain("fog+snow:1") and not looks_like_chain("fog")


def test_a_benchmark_range_limits_the_steps():
    assert parse_chain("dark:4+contrast:1.5", top=4).steps[0].level == 4
    with pytest.raises(RobodepthError, match=r"step 1 \(dark\): level 4.5 is out of range; valid levels: 1..4"):
        parse_chain("dark:4.5", top=4)


@pytest.mark.parametrize("text,message", [
    ("", "--compose: chain '': empty; write steps NAME:LEVEL joined by '+', e.g. 'fog:3+gaussian_noise:2.5'"),
    ("fog:3+", "--compose: chain 'fog:3+': step 2 is empty (a '+' with nothing on one side)"),
    ("+fog:3", "--compose: chain '+fog:3': step 1 is empty (a '+' with nothing on one side)"),
    ("fog:3++snow:1", "--compose: chain 'fog:3++snow:1': step 2 is empty (a '+' with nothing on one side)"),
    ("fog3+snow:1", "--compose: chain 'fog3+snow:1': step 1 'fog3' is not NAME:LEVEL (e.g. 'fog:3')"),
    ("fog:+snow:1", "--compose: chain 'fog:+snow:1': step 1 'fog:' is not NAME:LEVEL (e.g. 'fog:3')"),
    ("fog:3+snwo:1", "--compose: chain 'fog:3+snwo:1': step 2: unknown corruption 'snwo'; valid: brightness, "),
    ("fog:6", "--compose: chain 'fog:6': step 1 (fog): level 6 is out of range; valid levels: 1..5"),
    ("fog:0.5+snow:1", "--compose: chain 'fog:0.5+snow:1': step 1 (fog): level 0.5 is out of range; valid levels: 1..5"),
    ("fog:x", "--compose: chain 'fog:x': step 1 (fog): 'x' is not a number; levels are 1..5"),
    ("+".join(["fog:1"] * 9), "--compose: chain 'fog:1+fog:1+fog:1+fog:1+fog:1+fog:1+fog:1+fog:1+fog:1': "
                              "9 steps; a chain has at most 8"),
])
def test_bad_chains_are_one_line_refusals_naming_the_chain(text, message):
    with pytest.raises(RobodepthError) as info:
        parse_chain(text, where="--compose")
    assert str(info.value).startswith(message)
    assert "\n" not in str(info.value) and isinstance(info.value, RobodepthError)


def test_eight_steps_are_allowed():
    assert len(parse_chain("+".join(["contrast:1"] * MAX_STEPS)).steps) == 8


def test_deterministic_steps_compose_exactly():
    x = frame()
    chain = parse_chain("contrast:2.5+defocus_blur:1.5+jpeg_compression:3+pixelate:4.25+color_quant:2")
    assert all(REGISTRY[s.name].deterministic for s in chain.steps)
    by_hand = x
    for step in chain.steps:
        by_hand = corrupt(by_hand, step.name, step.level, np.random.default_rng(99))
    got = corrupt_chain(x, chain, seeding.chain_rngs(0, "image", chain, "frame.png"))
    assert np.array_equal(got, by_hand)


def test_random_steps_draw_from_their_own_streams():
    x = frame()
    chain = parse_chain("fog:3+gaussian_noise:2.5")
    got = corrupt_chain(x, chain, seeding.chain_rngs(4, "kitti-c", chain, "a/b.png"))
    # the same bytes from fresh generators (any process derives the same ones)
    assert np.array_equal(got, corrupt_chain(x, chain.text, seeding.chain_rngs(4, "kitti-c", chain, "a/b.png")))
    # step k is corrupt() of step k - 1's output with step k's generator
    r1, r2 = seeding.chain_rngs(4, "kitti-c", chain, "a/b.png")
    assert np.array_equal(got, corrupt(corrupt(x, "fog", 3, r1), "gaussian_noise", 2.5, r2))
    # a different key, seed or chain draws differently
    assert not np.array_equal(got, corrupt_chain(x, chain, seeding.chain_rngs(4, "kitti-c", chain, "a/c.png")))
    assert not np.array_equal(got, corrupt_chain(x, chain, seeding.chain_rngs(5, "kitti-c", chain, "a/b.png")))
    # the first step is not the single corruption of the same job: its stream is the chain's
    single = corrupt(x, "fog", 3, seeding.job_rng(4, "kitti-c", "fog", 3, "a/b.png"))
    assert not np.array_equal(corrupt(x, "fog", 3, seeding.chain_rngs(4, "kitti-c", chain, "a/b.png")[0]), single)


def test_a_repeated_step_draws_anew():
    chain = parse_chain("gaussian_noise:1+gaussian_noise:1")
    a, b = seeding.chain_rngs(0, "image", chain, "k")
    assert a.random() != b.random()


def test_wrong_number_of_generators_is_refused():
    with pytest.raises(ValueError, match="2 steps but 1 generators"):
        corrupt_chain(frame(), "fog:1+snow:1", [np.random.default_rng(0)])
