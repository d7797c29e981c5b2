"""Tests of robodepth_cli/styles/."""
