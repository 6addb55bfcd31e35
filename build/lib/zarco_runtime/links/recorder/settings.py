"""Settings of the recorder (``[record]``)."""

from __future__ import annotations

from dataclasses import dataclass

from zarco_core.config import spec


@dataclass(slots=True)
class Record:
    """Where and how the recorder writes (MCAP, one file per run, rotated by size).

    ``zarco run`` records by default (``enabled`` is true unless the vessel file
    says otherwise); ``zarco sim`` only with ``--record FILE``.  A relative
    ``dir`` is taken from the configuration file's folder.  Batches of messages
    reach the writer process every ``flush_s`` and it writes a chunk at least
    that often, so a process killed outright loses at most about ``2 ×
    flush_s`` of messages; ``fsync_s`` bounds what a power cut loses.
    """

    enabled: bool = spec(False, "", "run the recorder (zarco run: true unless the file says "
                         "false; zarco sim: only with --record FILE)")
    dir: str = spec("recordings", "", "folder of the recordings (relative: to the "
                    "configuration file's folder); one file per run, never overwritten")
    file: str = spec("", "", "write this file instead of a new one in dir (zarco sim "
                     "--record FILE); its parts after a rotation get -002, -003, ...")
    max_file_mb: float = spec(256.0, "MB", "start a new part when a file reaches this size",
                              min=1.0, max=1e6)
    min_free_mb: float = spec(200.0, "MB", "stop recording (and raise a fault) when the "
                              "file system's free space falls below this", min=0.0, max=1e7)
    flush_s: float = spec(0.25, "s", "hand messages to the writer and write a chunk at "
                          "least this often", min=0.02, max=0.5)
    fsync_s: float = spec(1.0, "s", "force written chunks to the storage this often "
                          "(a power cut loses at most about this much)", min=0.0, max=60.0)
    raw: bool = spec(True, "", "record every raw chunk read from or written to a device")
    location_hz: float = spec(5.0, "Hz", "rate of the foxglove.LocationFix topics of the "
                              "vessel and the AUV (map panel)", min=0.1, max=100.0)
    queue_mb: float = spec(64.0, "MB", "messages waiting for a slow writer beyond this are "
                           "dropped, oldest first, and counted", min=1.0, max=4096.0)
