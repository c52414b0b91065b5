"""Sensor data: the :class:`Recording` type, its files, and readers."""

from quadest.data.recording import TRUTH_FIELDS, Recording
from quadest.data.recording_files import load_recording, save_recording
from quadest.data.summary import format_summary, summarize
from quadest.data.tables import write_blocks, write_table

__all__ = [
    "TRUTH_FIELDS",
    "Recording",
    "load_recording",
    "save_recording",
    "summarize",
    "format_summary",
    "write_blocks",
    "write_table",
]
