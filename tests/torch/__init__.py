"""Tests of robodepth_cli.torch (transforms, batches, the dataset wrapper)."""
