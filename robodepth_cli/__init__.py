"""robodepth: build the RoboDepth robustness benchmark datasets."""

__version__ = "0.1.0"
