"""Tests of robodepth_cli/evaluation/."""
