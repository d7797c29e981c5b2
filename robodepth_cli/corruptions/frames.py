"""Which draws of a corruption belong to the scene or the camera and which to the sensor, so
that the neighbour frames of a test frame (``build kitti-c --frames -1,1``) are corrupted
consistently with it (docs/video.md): a neighbour's generator is seeded from the test
frame's key when the corruption's draws describe the scene or camera, from its own key when
they are sensor noise. No corruption mixes the two, so the rule is one choice per corruption."""

from __future__ import annotations

from ..benchmark_facts import CORRUPTIONS, DEPTH_AWARE

# What each corruption's draws stand for across frames (docs/video.md shows this table).
SHARED = "scene/camera: same draws in every frame"
PER_FRAME = "sensor noise: drawn anew per frame"
NO_DRAWS = "no draws: the same function on every frame"

DRAWS: dict[str, tuple[str, str]] = {
    "brightness": (NO_DRAWS, ""),
    "dark": (NO_DRAWS, ""),
    "fog": (SHARED, "the fog field"),
    "frost": (SHARED, "the frost texture and its crop"),
    "snow": (SHARED, "the snow layer and its fall angle"),
    "contrast": (NO_DRAWS, ""),
    "defocus_blur": (NO_DRAWS, ""),
    "glass_blur": (SHARED, "the pixel shuffle of the glass in front of the lens"),
    "motion_blur": (SHARED, "the blur angle (the camera's motion)"),
    "zoom_blur": (NO_DRAWS, ""),
    "elastic_transform": (SHARED, "the displacement field (the lens)"),
    "color_quant": (NO_DRAWS, ""),
    "gaussian_noise": (PER_FRAME, "the noise"),
    "impulse_noise": (PER_FRAME, "the salt-and-pepper pixels"),
    "shot_noise": (PER_FRAME, "the photon noise"),
    "iso_noise": (PER_FRAME, "the photon and read noise"),
    "pixelate": (NO_DRAWS, ""),
    "jpeg_compression": (NO_DRAWS, ""),
    # The depth-aware ones but rain draw nothing: each frame's own depth makes its fog,
    # focus or motion. Rain's drops fall about half a metre between two 10 Hz frames.
    **{name: (NO_DRAWS, "") if name != "rain_3d" else (PER_FRAME, "the rain drops (they fall between frames)")
       for name in DEPTH_AWARE},
}
assert tuple(DRAWS) == CORRUPTIONS + tuple(DEPTH_AWARE)  # every corruption says what its draws are


def draw_key(name: str, key: str, anchor: str | None) -> str:
    """The key that seeds corruption ``name`` on the frame ``key`` when it is a neighbour of
    the test frame ``anchor`` (None or "": ``key`` is a test frame)."""
    # A corruption this table does not list yet is taken as the scene's (one draw for the
    # sequence): a frame-to-frame jump in a fog or a blur would be the worse surprise.
    if not anchor or DRAWS.get(name, (SHARED,))[0] == PER_FRAME:
        return key
    return anchor
