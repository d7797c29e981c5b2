"""Tests of robodepth_cli/report/."""
