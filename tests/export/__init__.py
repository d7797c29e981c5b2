"""Tests of robodepth_cli/export/."""
