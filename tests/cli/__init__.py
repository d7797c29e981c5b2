"""Tests of the command line across commands (robodepth_cli/cli.py, robodepth_cli/commands/): options, messages, refusals, interrupts."""
