"""Helpers shared by the test suite (and bench/): tree builders, fake models, readers of what a
command wrote. Fixtures live in tests/conftest.py; no test module imports another."""
