"""Tests of robodepth_cli/corruptions/."""
