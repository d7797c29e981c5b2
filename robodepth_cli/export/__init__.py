"""``robodepth export``: a finished build as Hugging Face parquet or WebDataset tar shards,
``robodepth verify`` of such an export, and reading one back as a build is read.

Nothing here is imported by a build: pyarrow (parquet) is imported only where a parquet
shard is written or read; tar shards need only the standard library.
"""
