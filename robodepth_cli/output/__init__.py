"""What a build leaves in OUT: the names and the output-path rule (:mod:`.layout`), the
folder with its lock and journal (:mod:`.folder`), the manifest (:mod:`.manifest`), the
build record (:mod:`.record`) and ``robodepth verify`` (:mod:`.verify`)."""
