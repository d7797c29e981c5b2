"""Tests of ground truth: making it (robodepth gt), writing it with a build, reading it back."""
