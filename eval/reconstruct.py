"""``lts reconstruct``: the whole offline pipeline on one session, resumable stage by stage.

Stages (each an ``lts`` command run as a child process, so its progress and errors are its own):

=========  =========================================  ==============================
stage      what                                       output in RUN_DIR
=========  =========================================  ==============================
calibrate  ``--calib`` copied, or ``lts calibrate``   ``calib.yaml``
           session with ``--init``
slam       ``lts slam import`` of ``--slam``, or the  ``slam/``
           fallback mapper ``lts slam run``
prepare    ``lts prepare`` (keyframes, depth, normals) ``scene/``
train      ``lts train`` (resumed from its checkpoint  ``train/``
           when an earlier attempt was cut short)
evaluate   ``lts eval train/ [--gt]`` + report         ``train/eval.json``, ``report.html``
=========  =========================================  ==============================

A stage is skipped when ``stages.json`` records it as finished with the same *fingerprint*: its
command line, the toolkit's version and the size and modification time of every input file.
Changing a training option therefore retrains without redoing calibration, mapping or keyframes;
a changed session or an upgraded toolkit redoes everything. A training folder made with other
options is kept, renamed ``train.previous-N``.
"""

from __future__ import annotations

import hashlib
import json
import shutil
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from rig.atomic_file import write_atomic
from rig.errors import InputError
from rig.version import package_version

STAGES = ("calibrate", "slam", "prepare", "train", "evaluate")
MANIFEST = "stages.json"


class StageFailedError(RuntimeError):
    """A stage's command failed; the stages before it are kept and a rerun starts here."""


@dataclass
class ReconstructOptions:
    """What ``lts reconstruct`` was asked for."""

    session: Path
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


@dataclass
class StageRecord:
    """One stage's outcome: ``ran`` (seconds) or ``skipped`` (up to date)."""

    name: str
    status: str
    seconds: float


@dataclass
class ReconstructResult:
    run_dir: Path
    stages: list[StageRecord] = field(default_factory=list)
    metrics: dict = field(default_factory=dict)


def _files_of(path: Path) -> list[Path]:
    if path.is_file():
        return [path]
    return sorted(p for p in path.rglob("*") if p.is_file()) if path.is_dir() else []


def fingerprint(command: list[str], inputs: list[Path]) -> str:
    """A digest of a stage's command line, the toolkit's version (an upgrade redoes the stages) and
    the size and mtime of every input file."""
    digest = hashlib.sha256(json.dumps([package_version(), *command]).encode())
    for path in inputs:
        for f in _files_of(path):
            stat = f.stat()
            digest.update(f"{f}:{stat.st_size}:{stat.st_mtime_ns}".encode())
    return digest.hexdigest()


def _lts() -> str:
    return str(Path(sys.executable).with_name("lts"))


class Pipeline:
    """Runs the stages of one reconstruction into ``options.out``."""

    def __init__(self, options: ReconstructOptions, log: Callable[[str], None]):
        self.o = options
        self.log = log
        self.run = options.out
        self.manifest_path = self.run / MANIFEST
        self.manifest: dict[str, str] = (
            json.loads(self.manifest_path.read_text()) if self.manifest_path.is_file() else {}
        )
        if not options.session.is_file():
            raise InputError("no such session file", path=options.session)
        if options.calib is None and options.init is None:
            raise InputError(
                "give --calib (a full calibration) or --init (a rough T_cam_lidar for lts calibrate to "
                "refine, with the time offset estimated from the session)",
                field="calib",
            )

    def _done(self, stage: str, print_: str, output: Path) -> bool:
        """Finished with these inputs, and its output is still there."""
        return self.manifest.get(stage) == print_ and output.exists()

    def _record(self, stage: str, print_: str) -> None:
        self.manifest[stage] = print_
        write_atomic(self.manifest_path, json.dumps(self.manifest, indent=1))

    def _forget_from(self, stage: str) -> None:
        for later in STAGES[STAGES.index(stage) :]:
            self.manifest.pop(later, None)

    def _stage(
        self,
        stage: str,
        command: list[str],
        inputs: list[Path],
        output: Path,
        before: Callable[[], None] | None = None,
        resume_flag: str | None = None,
        action: Callable[[], None] | None = None,
    ) -> StageRecord:
        """Run ``command`` unless the stage is up to date. ``resume_flag`` is appended (outside the
        fingerprint) when the stage's own files show an unfinished earlier attempt. ``action``, when
        given, does the stage's work in this process and ``command`` only names it."""
        print_ = fingerprint(command, inputs)
        if self._done(stage, print_, output):
            self.log(f"[{stage}] up to date, skipped")
            return StageRecord(stage, "skipped", 0.0)
        self._forget_from(stage)
        if before is not None:
            before()
        if resume_flag is not None:
            self.log(f"[{stage}] an earlier attempt stopped part-way: continuing from its checkpoint")
            command = [*command, resume_flag]
        shown = command if action is not None else command[1:]  # lts commands without the lts path
        self.log(f"[{stage}] {' '.join(shown)}")
        started = time.perf_counter()
        code = 0
        if action is not None:
            action()
        else:
            code = subprocess.run(command).returncode
        if code != 0:
            raise StageFailedError(
                f"stage {stage} failed (exit {code}); earlier stages are kept in {self.run} and a rerun of "
                "the same command continues from this stage"
            )
        self._record(stage, print_)
        return StageRecord(stage, "ran", round(time.perf_counter() - started, 2))

    def _set_aside_old_training(self, scene_changed: bool) -> None:
        """A training folder made with other options or on an older scene is renamed, never deleted."""
        train = self.run / "train"
        if not (train / "config.yaml").is_file():
            return
        from splat.config import load_config

        if not scene_changed and load_config(train / "config.yaml") == self._train_config():
            return
        n = 1
        while (self.run / f"train.previous-{n}").exists():
            n += 1
        train.rename(self.run / f"train.previous-{n}")
        self.log(f"[train] options or scene changed: the earlier run is kept as train.previous-{n}")

    def _train_config(self):
        from splat.config import config_from_options

        o = self.o
        return config_from_options(o.method, o.preset, seed=o.seed, device=o.device, iterations=o.iterations)

    def _train_command(self) -> list[str]:
        command = [_lts(), "train", str(self.run / "scene"), "--out", str(self.run / "train"),
                   "--method", self.o.method, "--preset", self.o.preset, "--seed", str(self.o.seed),
                   "--device", self.o.device]  # fmt: skip
        if self.o.iterations is not None:
            command += ["--iterations", str(self.o.iterations)]
        return command

    def execute(self) -> ReconstructResult:
        o, run = self.o, self.run
        run.mkdir(parents=True, exist_ok=True)
        result = ReconstructResult(run)
        calib = run / "calib.yaml"
        if o.calib is not None:
            from rig.calibration import load_calibration

            load_calibration(o.calib)  # a bad file stops here, with its own error

            def copy_calib() -> None:
                shutil.copyfile(o.calib, calib)

            command = ["copy", str(o.calib), str(calib)]
            result.stages.append(self._stage("calibrate", command, [o.calib], calib, action=copy_calib))
        else:
            command = [
                _lts(),
                "calibrate",
                "session",
                str(o.session),
                "--out",
                str(calib),
                "--init",
                str(o.init),
            ]
            result.stages.append(self._stage("calibrate", command, [o.session, o.init], calib))

        slam = run / "slam"
        if o.slam is not None:
            command = [_lts(), "slam", "import", str(o.slam), "--out", str(slam)]
            result.stages.append(self._stage("slam", command, [o.slam], slam / "mesh.ply"))
        else:
            command = [_lts(), "slam", "run", str(o.session), "--calib", str(calib), "--out", str(slam)]
            result.stages.append(self._stage("slam", command, [o.session, calib], slam / "mesh.ply"))

        scene = run / "scene"
        command = [
            _lts(),
            "prepare",
            str(o.session),
            "--calib",
            str(calib),
            "--slam",
            str(slam),
            "--out",
            str(scene),
        ]
        if o.method == "tsplus":
            command.append("--sparse-points")
        if o.keyframe_interval_s is not None:
            command += ["--keyframe-interval", str(o.keyframe_interval_s)]

        def clear_scene() -> None:
            shutil.rmtree(scene, ignore_errors=True)

        prepared = self._stage(
            "prepare", command, [o.session, calib, slam], scene / "scene.json", before=clear_scene
        )
        result.stages.append(prepared)

        train = run / "train"
        self._set_aside_old_training(scene_changed=prepared.status == "ran")
        resume = "--resume" if (train / "checkpoints" / "last.pt").is_file() else None
        command = self._train_command()
        result.stages.append(self._stage("train", command, [scene], train / "model.pt", resume_flag=resume))

        command = [_lts(), "eval", str(train), "--json"] + (["--gt", str(o.gt)] if o.gt is not None else [])
        started = time.perf_counter()
        self.log(f"[evaluate] {' '.join(command[1:])}")
        done = subprocess.run(command, stdout=subprocess.PIPE, text=True)
        if done.returncode != 0:
            raise StageFailedError(
                f"stage evaluate failed (exit {done.returncode}); training is kept in {train}"
            )
        result.metrics = json.loads(done.stdout.strip().splitlines()[-1])
        result.stages.append(StageRecord("evaluate", "ran", round(time.perf_counter() - started, 2)))
        return result


def reconstruct(options: ReconstructOptions, log: Callable[[str], None] = print) -> ReconstructResult:
    """Run (or resume) every stage of a reconstruction; see the module docstring."""
    return Pipeline(options, log).execute()
