"""Tests of robodepth_cli/models/ (robodepth predict)."""
