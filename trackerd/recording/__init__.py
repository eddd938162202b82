"""Recording synchronized camera pairs losslessly, and replaying them through the daemon's own pipeline.

docs/recording.md describes the commands and the format (version 1.0) byte by byte:

* ``format.py``     byte layouts, their packing and checking, the metadata model, the version;
* ``writer.py``     appending pairs crash-safely, the index, a full disk, closing;
* ``recorder.py``   the writer thread behind a bounded drop-oldest queue (`trackerd record`, the daemon);
* ``extension.py``  recording on demand from the running daemon (``[recording]``, SIGHUP);
* ``reader.py``     opening a recording, recovering pairs past the index, naming any damage;
* ``replay.py``     a recording as a PairSource: recorded pace or max speed, deterministic;
* ``check.py``, ``export.py``, ``importer.py``  `trackerd recording check|export|import`;
* ``annotate.py``   viewable frames with the detections drawn (export, snap);
* ``cameras.py``, ``progress.py``  the cameras record and snap open; the live progress line.
"""
