"""What a file is, from its first bytes: the formats' magic numbers."""

from __future__ import annotations

from pathlib import Path

MAGIC = (
    (b"ULog\x01\x12\x35", "ulog"),            # PX4 ULog
    (b"\xa3\x95", "dataflash"),               # ArduPilot DataFlash (binary)
    (b"\x89MCAP", "mcap"),                    # MCAP (rosbag2 MCAP storage, plain .mcap)
    (b"SQLite format 3\x00", "sqlite"),       # rosbag2 sqlite3 storage (.db3)
    (b"#ROSBAG V2.0", "ros1"),                # ROS 1 bag
    (b"# gyrotherm-run:", "run"),             # gyrotherm run file (CSV version 1)
)
"""``(first bytes, kind)``, tried in order."""
HEAD_BYTES = 16


def content_kind(path: Path, head: bytes | None = None) -> str:
    """The kind of :data:`MAGIC` whose bytes ``path`` starts with (``head``: its first
    bytes when already read), "" for none or for a directory."""
    if head is None:
        if not path.is_file():
            return ""
        with path.open("rb") as fh:
            head = fh.read(HEAD_BYTES)
    return next((kind for magic, kind in MAGIC if head.startswith(magic)), "")


__all__ = ["HEAD_BYTES", "MAGIC", "content_kind"]
