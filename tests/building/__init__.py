"""Tests of robodepth_cli/building/."""
