"""KITTI-S: the style names and the user's style images (:mod:`.inputs`, torch-free) and the
AdaIN engine that renders them (:mod:`.adain`, the only module here that imports torch)."""
