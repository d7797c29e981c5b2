"""Tests of robodepth_cli/output/."""
