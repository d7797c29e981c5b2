"""Tests of robodepth_cli/running/ and the end-to-end loops (robodepth run, make demo)."""
