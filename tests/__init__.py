"""The test suite: its folders mirror the package (tests/building/ tests robodepth_cli/building/, ...);
shared helpers are in tests/helpers/, shared fixtures in tests/conftest.py."""
