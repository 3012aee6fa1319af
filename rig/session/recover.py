"""``rig recover``: rewrite every complete record of a (truncated) MCAP file into a valid one."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from mcap.records import Attachment, Channel, Message, Metadata, Schema
from mcap.writer import CompressionType, Writer

from rig.errors import InputError
from rig.session.reader import CORRUPTION_ERRORS, mcap_records
from rig.version import package_version

RECOVERY_METADATA = "lidar_ts.recovery"


def recover(src: str | Path, dst: str | Path) -> dict[str, Any]:
    """Copy schemas, channels, messages, metadata and attachments of ``src`` to a finished ``dst``.

    Returns ``{"messages", "metadata", "attachments", "truncated", "reason"}``: what was salvaged and
    why the source ended. Messages keep their bytes, times and sequence numbers.
    """
    src, dst = Path(src), Path(dst)
    if not src.is_file():
        raise InputError("no such session file", path=src)
    if src.resolve() == dst.resolve():
        raise InputError("the output must be a different file from the input", path=dst)
    with src.open("rb") as f:
        if f.read(8) != b"\x89MCAP0\r\n":
            raise InputError("not an MCAP file (bad magic bytes)", path=src)
    counts = {"messages": 0, "metadata": 0, "attachments": 0}
    truncated, reason = False, ""
    schema_ids: dict[int, int] = {}
    channel_ids: dict[int, int] = {}
    with src.open("rb") as fin, dst.open("wb") as fout:
        writer = Writer(fout, compression=CompressionType.ZSTD)
        writer.start(profile="ros2", library=f"lidar-ts {package_version()} (recovered)")
        saw_footer = False
        try:
            for record in mcap_records(fin, src.stat().st_size):
                if isinstance(record, Schema) and record.id not in schema_ids:
                    schema_ids[record.id] = writer.register_schema(record.name, record.encoding, record.data)
                elif isinstance(record, Channel) and record.id not in channel_ids:
                    channel_ids[record.id] = writer.register_channel(
                        record.topic,
                        record.message_encoding,
                        schema_ids.get(record.schema_id, 0),
                        dict(record.metadata),
                    )
                elif isinstance(record, Message) and record.channel_id in channel_ids:
                    writer.add_message(
                        channel_ids[record.channel_id],
                        record.log_time,
                        record.data,
                        record.publish_time,
                        record.sequence,
                    )
                    counts["messages"] += 1
                elif isinstance(record, Metadata):
                    writer.add_metadata(record.name, dict(record.metadata))
                    counts["metadata"] += 1
                elif isinstance(record, Attachment):
                    writer.add_attachment(
                        record.create_time, record.log_time, record.name, record.media_type, record.data
                    )
                    counts["attachments"] += 1
                saw_footer = saw_footer or type(record).__name__ == "Footer"
        except CORRUPTION_ERRORS as exc:
            truncated, reason = True, f"{type(exc).__name__}: {exc}".strip()
        if not truncated and not saw_footer:
            truncated, reason = True, "no footer"
        result = {**counts, "truncated": truncated, "reason": reason}
        writer.add_metadata(
            RECOVERY_METADATA, {k: json.dumps(v) for k, v in {**result, "source": str(src)}.items()}
        )
        writer.finish()
    return result
