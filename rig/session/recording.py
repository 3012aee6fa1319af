"""Opening any recording the offline commands take: our own session ``.mcap``, a ROS 1 ``.bag``
(or the split files of one recording), a rosbag2 folder (sqlite3 or MCAP storage), a bare MCAP
file recorded by others, or a KITTI raw drive folder. They are read in place, never copied or
converted first."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from rig.errors import InputError
from rig.session.bag import BagRecording
from rig.session.bag_files import bag_format
from rig.session.kitti_raw import KittiRecording, is_kitti_drive
from rig.session.reader import SessionReader
from rig.session.source import Recording, TimeSpan
from rig.session.writer import SESSION_METADATA

EXPECTED = (
    "a session .mcap, a ROS 1 .bag (or its split files), a rosbag2 folder, an MCAP file "
    "or a KITTI raw drive folder"
)


def is_foreign_mcap(path: Path) -> bool:
    """Whether the MCAP file ``path`` was recorded by others: a message comes before any
    ``lidar_ts.session`` metadata (which our writer puts first). A file damaged before either
    counts as ours, so that its complete records are salvaged as a session's are."""
    from mcap.records import Message, Metadata

    for record in SessionReader(path).records():
        if isinstance(record, Metadata) and record.name == SESSION_METADATA:
            return False
        if isinstance(record, Message):
            return True
    return False


def open_recording(
    paths: str | Path | Sequence[str | Path],
    *,
    topic_map: dict[str, str] | None = None,
    span: TimeSpan | None = None,
    camera: int | None = None,
) -> Recording:
    """A reader of the recording at ``paths`` (one path, or the split files of one ROS 1 bag, or
    a folder holding only those): :class:`SessionReader` for our own sessions, else
    :class:`BagRecording`; a KITTI raw drive folder as :class:`KittiRecording` (``camera``: which
    of its cameras is the image, default the first colour one). A ``.db3``/``.mcap`` file inside a
    rosbag2 folder opens the folder. Raises :class:`InputError` naming the path when it is missing
    or not a recording."""
    given = [Path(paths)] if isinstance(paths, str | Path) else [Path(p) for p in paths]
    if not given:
        raise InputError(f"no recording given; expected {EXPECTED}")
    resolved: list[Path] = []
    for path in given:
        if not path.exists():
            raise InputError(f"no such session file or bag (expected {EXPECTED})", path=path)
        resolved += _resolved(path)
    if len(given) == 1 and is_kitti_drive(given[0]):
        return KittiRecording(given[0], span=span, topic_map=topic_map, camera=camera)
    if camera is not None:
        raise InputError(
            "only a KITTI raw drive has numbered cameras; choose a bag's image with --topics image=TOPIC",
            path=given[0],
            field="--camera",
        )
    formats = [bag_format(p) for p in resolved]
    for path, fmt in zip(resolved, formats, strict=True):
        if (
            fmt is None
            and path.is_dir()
            and (drives := sorted(d.name for d in path.iterdir() if is_kitti_drive(d)))
        ):
            raise InputError(
                f"a folder of KITTI raw drives; give one of them: {', '.join(drives)}", path=path
            )
        if fmt is None and path.suffix.lower() in (".pcap", ".pcapng"):
            raise InputError(
                "a packet capture, not a recording: rig record replays an Ouster pcap into a session "
                "(rig.yaml: a device of kind ouster with pcap: and meta:, its JSON metadata)",
                path=path,
            )
        if fmt is None:
            what = "a folder without metadata.yaml" if path.is_dir() else "bad magic bytes"
            raise InputError(f"not a recording: {what} (expected {EXPECTED})", path=path)
    if len(resolved) == 1 and formats[0] == "MCAP" and not is_foreign_mcap(resolved[0]):
        return SessionReader(resolved[0], span=span, topic_map=topic_map)
    if len(resolved) > 1 and set(formats) != {"ROS 1 bag"}:
        kinds = ", ".join(f"{p.name}: {f}" for p, f in zip(resolved, formats, strict=True))
        raise InputError(
            f"several recordings given ({kinds}); only the split files of one ROS 1 bag can be read together",
            path=resolved[0],
        )
    return BagRecording(resolved, formats[0], span=span, topic_map=topic_map)


def _resolved(path: Path) -> list[Path]:
    """The rosbag2 folder of a storage file in it; the ``.bag`` files of a folder of split bags."""
    if path.is_file() and path.suffix in (".db3", ".mcap") and (path.parent / "metadata.yaml").is_file():
        return [path.parent]
    if path.is_dir() and not (path / "metadata.yaml").is_file():
        return sorted(path.glob("*.bag")) or [path]
    return [path]


def as_recording(source: Recording | str | Path) -> Recording:
    """``source`` itself when it is an open recording, else the recording at that path."""
    return source if isinstance(source, Recording) else open_recording(source)
