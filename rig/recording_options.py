"""The command-line options of every offline command that reads a recording: the recording's
paths, ``--topics``, ``--start`` and ``--duration``; one definition, so the commands agree."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import typer

from rig.calibration import Calibration, load_calibration
from rig.session.source import Recording, TimeSpan
from rig.session.topic_map import TOPICS_HELP

RECORDING_HELP = (
    "The recording: a session .mcap (rig record, lts sim), a ROS 1 .bag (several, or a folder of "
    "them: the split files of one recording, merged in time order), a rosbag2 folder (sqlite3 or "
    "mcap storage) or an MCAP file from others; bags are read in place. A bag message is timed by "
    "its header stamp; by the bag's receive time when it has no header or its stamps come from "
    "another clock (over 60 s from the receive times). A topic whose header stamps are zero or go "
    "backwards is refused. A KITTI raw drive folder (…_drive_NNNN_sync) is read in place too, its "
    "calibration files being the recording's own calibration."
)
RECORDING_ARGUMENT = typer.Argument(..., help=RECORDING_HELP, metavar="RECORDING")
TOPICS_OPTION = typer.Option("auto", "--topics", metavar="MAP", help=TOPICS_HELP)
START_OPTION = typer.Option(
    0.0, "--start", min=0.0, metavar="S", help="Read from S seconds after the recording's first message."
)
IMAGE_TOPIC_OPTION = typer.Option(None, "--image-topic", help="Image topic (overrides --topics image=...).")
POINTS_TOPIC_OPTION = typer.Option(
    None, "--points-topic", help="Point-cloud topic (overrides --topics points=...)."
)
CAMERA_OPTION = typer.Option(
    None,
    "--camera",
    min=0,
    max=3,
    metavar="N",
    help="KITTI raw drive: the camera whose images to use (image_0N; default the first colour camera, 2).",
)
DURATION_OPTION = typer.Option(
    None, "--duration", min=0.0, metavar="S", help="Read S seconds from --start (default: to the end)."
)


def time_span(start: float, duration: float | None) -> TimeSpan | None:
    """The span of ``--start``/``--duration`` (None: the whole recording)."""
    return None if start == 0 and duration is None else TimeSpan(start, duration)


def span_key(span: TimeSpan | None) -> list[str]:
    """``--start``/``--duration`` as a stage fingerprint's key (empty for the whole recording)."""
    return [] if span is None else span.describe().split()


def open_from_options(
    paths: Sequence[Path], topics: str, start: float, duration: float | None, camera: int | None = None
) -> Recording:
    """The recording the options name (errors as :class:`~rig.errors.InputError`)."""
    from rig.session import open_recording, parse_topic_map

    return open_recording(
        paths, topic_map=parse_topic_map(topics), span=time_span(start, duration), camera=camera
    )


#: ``--calib tf``: the recording's own calibration (:func:`rig.session.tf_static.recording_calibration`).
CALIB_FROM_RECORDING = "tf"
CALIB_TF_HELP = (
    f"or {CALIB_FROM_RECORDING}: the bag's own, its CameraInfo camera model and the /tf_static "
    "transform between the image's and the point cloud's header frames (time offset 0); a KITTI "
    "drive's calib_cam_to_cam.txt and calib_velo_to_cam.txt"
)


def calibration_option(calib: Path, recording: Recording, **topics: str | None) -> Calibration:
    """The calibration ``--calib`` names: a calib.yaml, or ``tf`` for the recording's own (its
    topics found as :func:`rig.session.find_topics` does, ``topics`` overriding roles)."""
    if str(calib) != CALIB_FROM_RECORDING:
        return load_calibration(calib, needs_extrinsic=True)
    from rig.session import find_topics
    from rig.session.tf_static import recording_calibration

    return recording_calibration(recording, find_topics(recording, **topics))
