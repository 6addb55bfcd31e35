"""The recorder (``[record]``): every bus message and raw device chunk to MCAP."""

from zarco_runtime.links.recorder.settings import Record

__all__ = ["Record"]
