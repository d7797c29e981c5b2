"""``robodepth selftest``: the shipped fixtures built with every kind of variant and compared
with the reference recorded on the locked install (:mod:`.check`; ``make selftest-record``
writes the reference through :mod:`.__main__`). Imports nothing heavy: ``robodepth --help``
loads the package."""
