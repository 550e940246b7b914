"""The twin playing real devices over their real protocols: a GeoCOM total station on a
pseudo-terminal, Pioneer bases speaking ARCOS on pseudo-terminals or localhost TCP ports,
cameras serving MJPEG over HTTP on localhost. The drivers of :mod:`twin.drivers` and the
whole campaign run against them unchanged (:mod:`.emulation` starts them all and writes
the rig file that points at them)."""
