"""``lts reconstruct``: the whole offline job on one recording, resumable stage by stage.

=========  ==============================================  ==============================
stage      what                                            output in RUN_DIR
=========  ==============================================  ==============================
calibrate  ``--calib`` copied (``tf``: the bag's own       ``calib.yaml``
           CameraInfo and ``/tf_static``), or the
           recording calibrated from the rough ``--init``
           or ``/tf_static`` (time offset, extrinsic;
           only ``ok`` results are applied)
slam       ``--slam`` imported, or the fallback mapper     ``slam/``
prepare    keyframes, LiDAR points, normal priors          ``scene/``
train      triangle splatting (resumed from its            ``train/``
           checkpoint when an earlier attempt stopped)
evaluate   metrics against ``--gt`` and the report         ``train/eval.json``, ``report.html``
=========  ==============================================  ==============================

The recording (a session, or a bag read in place) is opened once, with its topic map and time
span, and handed to every stage; a bag is fingerprinted by the size and modification time of its
files, never read for it. Each stage calls its package's entry point in this process, through one
:class:`~lts.stages.StageRunner`, except the fallback mapper: it needs no calibration and runs
beside the recording's calibration in a process of its own (:mod:`lts.mapper_beside`). A stage
whose inputs and options are unchanged since it finished is skipped, so a crash or Ctrl-C resumes
at the stage that stopped. A training folder made with other options or on an older scene is
kept as ``train.previous-N``, never deleted.
"""

from __future__ import annotations

import json
import shutil
from collections.abc import Callable, Sequence
from contextlib import nullcontext
from dataclasses import dataclass, field
from functools import cache, partial
from pathlib import Path
from typing import TYPE_CHECKING

from lts.mapper_beside import MapperBeside
from lts.stages import StageRecord, StageRunner
from rig.errors import InputError
from rig.recording_options import CALIB_FROM_RECORDING, span_key
from rig.session import Recording, TimeSpan, open_recording, parse_topic_map
from slam_bridge.prepare_config import DEFAULT_MAX_SIZE, DEFAULT_MAX_TRAVEL_M
from slam_bridge.scene import FORMAT_VERSION, Scene, load_scene

if TYPE_CHECKING:
    from slam_bridge.prepare_config import PrepareConfig
    from splat.config import TrainConfig

STAGES = ("calibrate", "slam", "prepare", "train", "evaluate")


@dataclass
class ReconstructOptions:
    """What ``lts reconstruct`` was asked for (``session``: one path, or the split files of one
    ROS 1 bag; ``calib`` may be ``tf``: the recording's own calibration)."""

    session: Path | Sequence[Path]
    out: Path
    calib: Path | None = None
    init: Path | None = None
    slam: Path | None = None
    gt: Path | None = None
    method: str = "ours"
    preset: str = "default"
    iterations: int | None = None
    device: str = "cpu"
    seed: int = 0
    keyframe_interval_s: float | None = None
    keyframe_max_travel_m: float = DEFAULT_MAX_TRAVEL_M
    max_size: int = DEFAULT_MAX_SIZE
    downscale: int = 1
    topics: str = "auto"
    span: TimeSpan | None = None
    camera: int | None = None
    exposure: str = "auto"
    learn_poses: bool = False
    blocks: str | None = None
    ray_address: str | None = None

    @property
    def paths(self) -> list[Path]:
        return [self.session] if isinstance(self.session, Path) else list(self.session)

    def recording_key(self) -> list[str]:
        """The recording as the stages' fingerprints name it: its paths, topic map and span."""
        topics = [] if self.topics == "auto" else ["--topics", self.topics]
        camera = [] if self.camera is None else ["--camera", str(self.camera)]
        return [*map(str, self.paths), *topics, *camera, *span_key(self.span)]


@dataclass
class ReconstructResult:
    run_dir: Path
    stages: list[StageRecord] = field(default_factory=list)
    metrics: dict = field(default_factory=dict)


def reconstruct(o: ReconstructOptions, log: Callable[[str], None] = print) -> ReconstructResult:
    """Run (or resume) every stage of a reconstruction into ``o.out``; see the module docstring."""
    recording = check_options(o)
    stages = StageRunner(o.out, STAGES, log)
    calib, slam, scene, train = o.out / "calib.yaml", o.out / "slam", o.out / "scene", o.out / "train"
    source, paths = o.recording_key(), recording.input_files()

    if o.calib is not None and str(o.calib) == CALIB_FROM_RECORDING:
        key, inputs = ["recording calibration (CameraInfo, /tf_static)", *source], paths
        work = partial(recording_calibration, recording, calib, log)
    elif o.calib is not None:
        key, inputs = ["copy", str(o.calib)], [o.calib]
        work = partial(copy_calibration, o.calib, calib)
    else:
        key = ["lts calibrate session", *source, "--init", str(o.init)]
        inputs = [*paths, *([o.init] if o.init is not None else [])]
        work = partial(calibrate, recording, o.init, calib, log)
    # Only calibrating the recording takes long enough for the mapper to pay for a process beside it.
    beside = o.calib is None and o.slam is None and not stages.up_to_date("calibrate", key, inputs, calib)
    with MapperBeside(recording, slam) if beside else nullcontext() as mapper:
        stages.run("calibrate", key, inputs, calib, work)
        if o.slam is not None:
            key, inputs = ["lts slam import", str(o.slam)], [o.slam]
            stages.run("slam", key, inputs, slam / "mesh.ply", lambda: import_slam(o.slam, slam, log))
        else:
            mapped = partial(joined, mapper, log) if mapper else partial(map_session, recording, slam, log)
            stages.run("slam", ["lts slam run", *source], paths, slam / "mesh.ply", mapped)

    keyframes = prepare_config(o)
    key, inputs = ["lts prepare", *source, *prepare_key(keyframes)], [*paths, calib, slam]
    prepared = stages.run(
        "prepare", key, inputs, scene / "scene.json",
        lambda: build_scene(recording, calib, slam, scene, keyframes, log),
    )  # fmt: skip

    loaded_scene = cache(lambda: load_scene(scene))  # training and evaluation read its files once
    if not loaded_scene().split("test"):
        raise InputError(
            f"the scene has {len(loaded_scene().keyframes)} keyframes and none held out for testing, which "
            "the evaluate stage needs; take keyframes more often (--keyframe-interval S)",
            path=scene / "scene.json",
            field="split",
        )
    config = train_config(o)
    stages.run(
        "train", ["lts train", *train_key(o)], [scene], train / "model.pt",
        lambda: train_run(loaded_scene(), train, config, o, scene_changed=prepared.status == "ran", log=log),
    )  # fmt: skip

    key = ["lts eval", *(["--gt", str(o.gt)] if o.gt is not None else [])]
    inputs = [scene, *(train / name for name in EVALUATED_FILES), *([o.gt] if o.gt is not None else [])]
    stages.run(
        "evaluate", key, inputs, train / "eval.json", lambda: evaluate(train, loaded_scene(), o.gt, log)
    )  # fmt: skip
    return ReconstructResult(o.out, stages.records, json.loads((train / "eval.json").read_text()))


#: The files of a training run that ``lts eval`` reads (a change to any of them re-evaluates).
EVALUATED_FILES = ("model.pt", "mesh.ply", "collision.obj", "summary.json")


def check_options(o: ReconstructOptions) -> Recording:
    """Refuse a missing or unreadable recording, a bad topic map, calibration or training option
    before any stage starts; the recording, opened."""
    train_config(o)  # a bad method, preset or --exposure stops here, not after mapping
    if o.ray_address is not None and o.blocks is None:
        raise InputError("only with --blocks, which was not given: --ray-address", field="blocks")
    if o.blocks is not None:
        from splat.blocks.options import parse_block_count, refuse_learnt_poses
        from splat.blocks.ray_tasks import import_ray

        parse_block_count(o.blocks)
        refuse_learnt_poses(o.learn_poses)

        import_ray()  # without the blocks extra, say so before the calibration and the mapper run
    recording = open_recording(o.paths, topic_map=parse_topic_map(o.topics), span=o.span, camera=o.camera)
    if o.calib is None and o.init is None:
        from rig.session import find_topics
        from rig.session.tf_static import tf_extrinsic

        if tf_extrinsic(recording, find_topics(recording)) is None:
            raise InputError(
                "give --calib (a full calibration) or --init (a rough T_cam_lidar for lts calibrate to "
                "refine, with the time offset estimated from the session); the recording has no "
                "/tf_static transform between its image and point cloud frames to start from",
                field="calib",
            )
    from rig.calibration import load_calibration

    # A bad file stops here, with its own error, before any stage. A calibration used as it is
    # needs an extrinsic; a starting one may hold the camera alone (the extrinsic is then found).
    if o.calib is not None and str(o.calib) != CALIB_FROM_RECORDING:
        load_calibration(o.calib, needs_extrinsic=True)
    if o.init is not None:
        load_calibration(o.init)
    return recording


def copy_calibration(source: Path, out: Path) -> None:
    """The calibrate stage given a finished calibration: ``source`` copied to ``out``."""
    out.parent.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(source, out)


def recording_calibration(recording: Recording, out: Path, log: Callable[[str], None]) -> None:
    """The calibrate stage with ``--calib tf``: the recording's CameraInfo and /tf_static extrinsic."""
    from rig.calibration import save_calibration
    from rig.session import find_topics
    from rig.session.tf_static import recording_calibration as own_calibration

    calibration = own_calibration(recording, find_topics(recording))
    out.parent.mkdir(parents=True, exist_ok=True)
    save_calibration(calibration, out)
    log(f"  {calibration.quality['source']}")


def calibrate(recording: Recording, init: Path | None, out: Path, log: Callable[[str], None]) -> None:
    """The calibrate stage: the recording's time offset and extrinsic refined from ``init`` (or
    from the recording's /tf_static extrinsic)."""
    from calib.session_calib import calibrate_session, report_lines
    from rig.calibration import load_calibration, save_calibration

    calibration, report = calibrate_session(
        recording,
        load_calibration(init) if init is not None else None,
        progress=lambda step: log(f"  {step}"),
        search_straight=False,  # only an ok extrinsic is applied, and a straight drive's never is
    )
    for line in report_lines(report):
        log(f"  {line}")
    if not calibration.has_extrinsic:  # nothing to place the LiDAR in the images with
        raise InputError(
            "no LiDAR-to-camera extrinsic: " + "; ".join(report["extrinsic"]["reasons"]), field="--init"
        )
    out.parent.mkdir(parents=True, exist_ok=True)
    save_calibration(calibration, out)


def import_slam(source: Path, out: Path, log: Callable[[str], None]) -> None:
    """The slam stage given a mapper's output: imported into the SLAM folder ``out``."""
    from slam_bridge.slam_import import import_slam_output, import_summary

    for line in import_summary(import_slam_output(source, out), out):
        log(f"  {line}")


def map_session(session: Recording, out: Path, log: Callable[[str], None]) -> None:
    """The slam stage without a mapper's output: the fallback mapper on the recording's sweeps."""
    from slam_bridge.map_session import map_session as run_fallback_mapper

    for line in run_fallback_mapper(session, out).describe():
        log(f"  {line}")


def joined(mapper: MapperBeside, log: Callable[[str], None]) -> None:
    """The slam stage when the fallback mapper ran beside the calibration: its end awaited."""
    summary, seconds = mapper.join()
    for line in summary.describe():
        log(f"  {line}")
    log(f"  mapped in {seconds:.1f} s, beside the calibration in a process of its own")


def prepare_config(o: ReconstructOptions) -> PrepareConfig:
    """The keyframe options of ``o``, with SfM points when the method's initialisation reads them
    (the TS+ baseline starts from them; ours seeds camera-only triangles at them)."""
    from slam_bridge.prepare_config import PrepareConfig

    init = train_config(o)
    interval = {} if o.keyframe_interval_s is None else {"keyframe_interval_s": o.keyframe_interval_s}
    sparse = init.init == "delaunay-sfm" or (init.init == "mesh" and init.camera_only_seeds)
    return PrepareConfig(
        keyframe_max_travel_m=o.keyframe_max_travel_m,
        sparse_points=sparse,
        max_size=o.max_size,
        downscale=o.downscale,
        **interval,
    )


def prepare_key(config: PrepareConfig) -> list[str]:
    """The options of ``config`` that the app layer sets, as ``lts prepare`` takes them, and the
    scene folder's format (a folder of an older format is made again)."""
    interval = config.keyframe_interval_s
    key = [f"scene format {FORMAT_VERSION}"]
    key += [] if interval is None else ["--keyframe-interval", str(interval)]
    key += ["--keyframe-distance", str(config.keyframe_max_travel_m)]
    key += ["--max-size", str(config.max_size), "--downscale", str(config.downscale)]
    return key + (["--sparse-points"] if config.sparse_points else [])


def build_scene(
    session: Recording, calib: Path, slam: Path, out: Path, config: PrepareConfig, log: Callable[[str], None]
) -> None:
    """The prepare stage: a fresh scene folder ``out`` (an older one is removed first)."""
    from rig.calibration import load_calibration
    from slam_bridge.scene_builder import build_scene as build

    shutil.rmtree(out, ignore_errors=True)
    built = build(session, load_calibration(calib), slam, out, config)
    log(f"  {len(built.keyframes)} keyframes, {built.spacing}")
    if built.matching_summary() is not None:
        log(f"  {built.matching_summary()}")


def train_key(o: ReconstructOptions) -> list[str]:
    """The training options as ``lts train`` takes them."""
    key = ["--method", o.method, "--preset", o.preset, "--seed", str(o.seed), "--device", o.device]
    key += [] if o.exposure == "auto" else ["--exposure", o.exposure]
    key += ["--learn-poses"] if o.learn_poses else []
    key += [] if o.blocks is None else ["--blocks", o.blocks]
    return key + (["--iterations", str(o.iterations)] if o.iterations is not None else [])


def train_config(o: ReconstructOptions) -> TrainConfig:
    """The :class:`~splat.config.TrainConfig` that ``lts train`` builds from ``o``'s options."""
    from splat.config import config_from_options

    return config_from_options(
        o.method, o.preset, seed=o.seed, device=o.device, iterations=o.iterations, exposure=o.exposure,
        learn_poses=o.learn_poses,
    )  # fmt: skip


def train_run(
    scene: Scene,
    run_dir: Path,
    config: TrainConfig,
    o: ReconstructOptions,
    scene_changed: bool,
    log: Callable[[str], None],
) -> None:
    """The train stage (in blocks on Ray with ``o.blocks``, auto or N): continues an interrupted run made with
    the same options on the same scene; a run made otherwise is set aside as ``train.previous-N``
    and training starts afresh."""
    from splat.blocks.block_run import train_in_blocks
    from splat.blocks.options import BlockOptions
    from splat.blocks.partition import PARTITION_FILE
    from splat.config import load_config
    from splat.run_dir import checkpoint_path, config_path
    from splat.trainer import train

    resume = False
    in_blocks = (run_dir / PARTITION_FILE).is_file()
    if config_path(run_dir).is_file():
        changed = in_blocks != (o.blocks is not None) or load_config(config_path(run_dir)) != config
        if scene_changed or changed:
            n = 1
            while (run_dir.parent / f"{run_dir.name}.previous-{n}").exists():
                n += 1
            run_dir.rename(run_dir.parent / f"{run_dir.name}.previous-{n}")
            log(f"[train] options or scene changed: the earlier run is kept as {run_dir.name}.previous-{n}")
        elif checkpoint_path(run_dir).is_file() or in_blocks:
            log("[train] an earlier attempt stopped part-way: continuing from its checkpoint")
            resume = True
    if o.blocks is not None:
        options = BlockOptions(count=o.blocks, ray_address=o.ray_address)
        train_in_blocks(scene.root, run_dir, config, options, resume=resume)
    else:
        train(scene, run_dir, config, resume=resume)


def evaluate(run_dir: Path, scene: Scene, gt: Path | None, log: Callable[[str], None]) -> None:
    """The evaluate stage: ``eval.json`` and ``report.html`` in the training run of ``scene``."""
    from eval.report import write_report
    from eval.run_eval import evaluate_run, write_eval_json

    evaluation = evaluate_run(run_dir, gt, log=lambda message: log(f"  {message}"), scene=scene)
    write_eval_json(evaluation)
    write_report(evaluation)
