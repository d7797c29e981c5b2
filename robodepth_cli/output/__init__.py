"""What a build leaves in OUT: the names and the output-path rule (:mod:`.layout`), the
manifest (:mod:`.manifest`), the build record (:mod:`.record`) and ``robodepth verify``
(:mod:`.verify`)."""
