"""Tests of robodepth_cli/sources/."""
