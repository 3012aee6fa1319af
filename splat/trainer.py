"""The training loop: LiDAR-guided fine stage, densification, checkpoints, resume, guards.

``RUN_DIR`` (see :mod:`splat.run_dir`) receives ``config.yaml``, ``run.json``, ``metrics.jsonl``
(one line per evaluation), ``checkpoints/last.pt``, the final ``model.pt``, test renders and the
exported meshes.
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np
import torch

from rig.atomic_file import atomic_path
from rig.camera import CameraModel
from rig.cli_support import console
from rig.errors import InputError
from rig.transforms import invert
from slam_bridge.scene import Keyframe, Scene, load_scene
from splat import run_dir as layout
from splat.camera_blur import FIT_VIEWS, fit_blur
from splat.coarse_views import coarse_iterations, half_camera, half_view
from splat.config import TrainConfig, load_config
from splat.exposure import (
    GAIN_SPREAD_LIMIT,
    ViewExposures,
    gain_spread,
    grey,
    held_out_maps,
    log_gain,
    neighbour_gains,
)
from splat.far_vertex_steps import FarVertexSteps
from splat.finite import all_finite
from splat.floor_cells import PlaneGrid, on_floor
from splat.held_out_views import evaluate_views, load_held_out_views, mark_background, write_renders
from splat.initialise import build_model, initial_triangles
from splat.lidar_points import keyframe_lidar_points, lidar_points
from splat.losses import image_moments, training_loss
from splat.model import TriangleModel, save_model
from splat.param_rows import make_optimizer
from splat.pose_corrections import PoseCorrections
from splat.raster import RenderOutput
from splat.schedule import evaluation_due, final_phase_start, schedule_at
from splat.strategy import DensifyReport, strategy_for
from splat.views import View, load_views, redundant_keyframes


class TrainingDivergedError(RuntimeError):
    """Too many consecutive steps had a non-finite loss or gradient."""


class TrainingInterruptedError(RuntimeError):
    """Ctrl-C/SIGTERM: a checkpoint was written and ``--resume`` continues from it."""


@dataclass
class TrainResult:
    """What a finished run reports (also written to ``RUN_DIR/summary.json``)."""

    run_dir: str
    method: str
    preset: str
    device: str
    iterations: int
    train_seconds: float
    n_triangles: int
    stopped_early: bool
    rejected_steps: int
    test: dict[str, float]
    skips: list[str] = field(default_factory=list)
    densification: list[dict] = field(default_factory=list)
    export: dict = field(default_factory=dict)
    exposure: dict = field(default_factory=dict)
    blocks: list[dict] = field(default_factory=list)
    poses: dict = field(default_factory=dict)
    camera_blur: dict = field(default_factory=dict)


@dataclass
class _State:
    """Everything a checkpoint holds besides the model, the optimiser and the strategy."""

    iteration: int = 0
    elapsed_s: float = 0.0
    rejected_total: int = 0
    rejected_in_a_row: int = 0
    best_psnr: float = -math.inf
    evals_without_gain: int = 0
    stopped_early: bool = False
    last_test: dict[str, float] = field(default_factory=dict)
    skips: list[str] = field(default_factory=list)
    densification: list[dict] = field(default_factory=list)


def _learning_rates(config: TrainConfig) -> dict[str, float]:
    return {
        "vertices": config.lr_vertices,
        "colors": config.lr_colors,
        "opacity": config.lr_opacity,
        "background": config.lr_background,
        "exposure": config.lr_exposure,
        "pose": config.lr_pose,
    }


def _apply_schedule(
    model: TriangleModel, optimizer: torch.optim.Optimizer, config: TrainConfig, it: int
) -> None:
    s = schedule_at(config, it)
    model.sigma, model.opacity_floor = s.sigma, s.opacity_floor
    base = _learning_rates(config)
    for group in optimizer.param_groups:
        factor = s.vertex_lr_factor if group["name"] == "vertices" else s.lr_factor
        group["lr"] = base[group["name"]] * factor


#: Memory for D-SSIM's target moments (:func:`splat.losses.image_moments`, float32), kept for the
#: first training views this holds, with their half-size twins of the coarse start: 2.2 MB a
#: 320x240 view, 13 MB a 1242x375 one (38 views of this budget).
IMAGE_MOMENTS_BUDGET_BYTES = 512 * 2**20


def _view_order(seed: int, epoch: int, n: int) -> np.ndarray:
    """The order of training views in ``epoch`` (a pure function of seed and epoch, so a resumed
    run visits the same views)."""
    return np.random.default_rng([seed, epoch]).permutation(n)


def _finite_step(loss: torch.Tensor, params: list[torch.Tensor]) -> bool:
    if not bool(torch.isfinite(loss)):
        return False
    return all(p.grad is None or all_finite(p.grad) for p in params)


class Trainer:
    """One training run of ``config`` on a scene folder into ``run_dir``."""

    def __init__(
        self,
        scene: str | Path | Scene,
        run_dir: str | Path,
        config: TrainConfig,
        log: Callable = console.print,
    ):
        self.scene: Scene = scene if isinstance(scene, Scene) else load_scene(scene)
        self.run_dir = Path(run_dir)
        self.config = config
        self.log = log
        self.state = _State()
        self.exposures: ViewExposures | None = None
        self._test_gains: tuple[np.ndarray, np.ndarray] | None = None
        self.poses: PoseCorrections | None = None
        # The coarse start (splat.coarse_views): how many iterations, the camera and the views of it.
        self._coarse_iterations = coarse_iterations(self.scene.camera, config)
        self._half_camera = half_camera(self.scene.camera)
        self._half_views: dict[int, View] = {}
        view_bytes = int(6 * 4 * 1.25 * self.scene.camera.width * self.scene.camera.height)
        self._views_with_moments = IMAGE_MOMENTS_BUDGET_BYTES // view_bytes
        self.strategy = strategy_for(config, log)
        if config.device.startswith("cuda") and not torch.cuda.is_available():
            raise InputError(
                "CUDA was asked for but torch sees no GPU here; use --device cpu", field="device"
            )

    # -- set-up ---------------------------------------------------------------------------------
    def _select_keyframes(self) -> None:
        train = self.scene.split("train")
        if not train:
            raise InputError("the scene has no training keyframes", path=self.scene.root / "scene.json")
        c = self.config
        if c.drop_redundant_keyframes:
            drop = set(redundant_keyframes(train, c.redundant_motion_m, c.redundant_turn_deg))
            if drop:
                self.state.skips.append(
                    f"{len(drop)} of {len(train)} training keyframes dropped: within "
                    f"{c.redundant_motion_m:g} m and {c.redundant_turn_deg:g}° of a kept one (saves loading "
                    "them and "
                    f"{len(drop) / len(train):.0%} of the renders of an epoch)"
                )
                train = [k for i, k in enumerate(train) if i not in drop]
        self.train_keyframes = train
        self.test_keyframes = self.scene.split("test")

    def _far_vertex_steps(self, lidar: np.ndarray) -> FarVertexSteps | None:
        """The scaling of far camera-only triangles' steps (:mod:`splat.far_vertex_steps`; camera-only:
        no return of the training keyframes' ``lidar`` ``(N, 3)`` near them), or None when
        ``vertex_step_range_m`` is 0."""
        if self.config.vertex_step_range_m <= 0:
            return None
        centres = torch.stack([torch.linalg.inv(v.T_cam_world)[:3, 3] for v in self.train_views])
        keyframes = self.train_keyframes
        return FarVertexSteps(
            centres,
            self.config.vertex_step_range_m,
            lambda triangles: torch.as_tensor(camera_only_triangles(triangles, lidar, keyframes)),
        )

    def _load_views(self) -> None:
        device = self.config.device
        self.train_views: list[View] = load_views(self.scene, self.train_keyframes, device=device)
        self.test_views: list[View] = load_held_out_views(self.scene, self.test_keyframes, self.config)
        if self.config.background != "none" and self.config.background_where == "above-lidar":
            mark_background(self.train_views, self.scene.camera)
        masked = [float(v.moving_mask.float().mean()) for v in self.train_views if v.moving_mask is not None]
        if masked:
            fraction = sum(masked) / len(self.train_views)
            self.state.skips.append(
                f"moving objects masked out of the photometric loss: {fraction:.1%} of the training pixels "
                f"({len(masked)} of {len(self.train_views)} views)"
            )
        if self.config.w_normal > 0 and all(v.normal is None for v in self.train_views):
            self.state.skips.append("no normal prior in any training view: normal loss skipped")
        if self.config.w_depth > 0 and all(v.depth is None for v in self.train_views):
            self.state.skips.append("no LiDAR depth in any training view: depth loss skipped")

    def _fresh_start(self, returns: list[np.ndarray]) -> None:
        """Initialise the model and the optimiser from the warm start; ``returns``: the world points
        ``(N_k, 3)`` of each training keyframe's LiDAR returns."""
        floor = None if self.floor is None else self.floor.plane
        init = initial_triangles(self.scene, self.train_keyframes, self.config, returns, floor)
        for note in init.notes:
            self.log(f"init: {note}")
        self.model = build_model(
            init, self.config, self.train_views, self.scene.camera, lambda m: self.log(f"init: {m}")
        )
        if self._learns_exposure():
            self.exposures = ViewExposures.identity(len(self.train_views), device=self.config.device)
        if self.config.learn_poses:
            self.poses = PoseCorrections.zeros(self._train_poses())
        self.optimizer = make_optimizer(self.model, _learning_rates(self.config), self._view_params())
        self.strategy.initialize(self.model)
        layout.metrics_path(self.run_dir).write_text("")
        if self._coarse_iterations > 0:
            half = self._half_camera
            self.state.skips.append(
                f"the first {self._coarse_iterations} of {self.config.iterations} iterations rendered at "
                f"half resolution ({half.width}x{half.height}: a quarter of the pixels)"
            )

    def _learns_exposure(self) -> bool:
        """Whether the run learns colour maps: ``exposure: on``, or ``auto`` and the training images'
        gains spread by more than :data:`GAIN_SPREAD_LIMIT` (:func:`neighbour_gains`); logged."""
        if self.config.exposure != "auto":
            return self.config.exposure == "on"
        ordered = sorted(range(len(self.train_keyframes)), key=lambda i: self.train_keyframes[i].t_ns)
        ratios = neighbour_gains(
            [self.train_views[i].image.cpu().numpy() for i in ordered],
            [self.scene.lidar(self.train_keyframes[i]).points.astype(np.float64) for i in ordered],
            np.stack([self.train_keyframes[i].T_world_cam for i in ordered]),
            self.scene.camera,
        )
        spread = gain_spread(ratios)
        learns = spread > GAIN_SPREAD_LIMIT
        self.state.skips.append(
            f"the training images' gains spread by {math.expm1(spread):.1%} (the LiDAR points neighbouring "
            f"images share): {'a colour map per image is learnt' if learns else 'no colour maps learnt'} "
            f"(exposure: auto, limit {math.expm1(GAIN_SPREAD_LIMIT):.0%})"
        )
        self.log(self.state.skips[-1])
        return learns

    def prepare(self, resume: bool) -> None:
        """Select keyframes, load views, then initialise or restore from the last checkpoint."""
        self.run_dir.mkdir(parents=True, exist_ok=True)
        checkpoint = layout.checkpoint_path(self.run_dir)
        config_path = layout.config_path(self.run_dir)
        if resume:
            if not checkpoint.is_file():
                raise InputError("no checkpoint to resume from (start without --resume)", path=checkpoint)
            previous = load_config(config_path).model_dump(exclude={"device"})
            changed = [f"{k} {v} -> {getattr(self.config, k)}" for k, v in previous.items()
                       if getattr(self.config, k) != v]  # fmt: skip
            if changed:
                raise InputError(
                    f"the run was started with other settings ({', '.join(changed)}); resume with the same "
                    "options, or train into a new --out where a default changed since",
                    path=config_path,
                )
        elif checkpoint.is_file():
            raise InputError("already holds a training run; pass --resume to continue it or pick a new --out",
                             path=self.run_dir)  # fmt: skip
        self._select_keyframes()
        self._load_views()
        returns = keyframe_lidar_points(self.scene, self.train_keyframes)
        self.lidar = np.concatenate(returns)  # (N, 3), kept for the export's camera-only flags
        self._far_steps = self._far_vertex_steps(self.lidar)
        self.floor = scene_floor(self.scene, self.train_keyframes, self.lidar)
        self.strategy.keep_far_floor(
            self.floor, np.stack([k.T_world_cam[:3, 3] for k in self.train_keyframes])
        )
        if resume:
            self._restore(checkpoint)
        else:
            config_path.write_text(self.config.to_yaml())
            layout.run_info_path(self.run_dir).write_text(
                json.dumps({"scene": str(self.scene.root.resolve()), "config": layout.CONFIG}, indent=1)
            )
            self._fresh_start(returns)

    # -- checkpoints ----------------------------------------------------------------------------
    def save_checkpoint(self) -> None:
        path = layout.checkpoint_path(self.run_dir)
        path.parent.mkdir(parents=True, exist_ok=True)
        state = {
            "model": self.model.to_state(),
            "optimizer": self.optimizer.state_dict(),
            "strategy": self.strategy.state_dict(),
            "state": asdict(self.state),
            "exposure": None if self.exposures is None else self.exposures.offsets.detach().cpu().clone(),
            "pose": None if self.poses is None else self.poses.params.detach().cpu().clone(),
            "far_vertex_steps": None if self._far_steps is None else self._far_steps.state_dict(),
        }
        with atomic_path(path) as tmp:
            torch.save(state, tmp)

    def _restore(self, path: Path) -> None:
        try:
            ckpt = torch.load(path, map_location="cpu", weights_only=False)
        except Exception as exc:  # a truncated or foreign file
            raise InputError(f"cannot read checkpoint ({type(exc).__name__}: {exc})", path=path) from None
        if "strategy" not in ckpt:
            raise InputError(
                "checkpoint written by an older lidar-ts (no densification strategy state); train into a "
                "new --out",
                path=path,
            )
        self.model = TriangleModel.from_state(ckpt["model"], self.config.device, path)
        if self.config.background != "none" and self.model.background is None:
            self.log("the checkpoint predates trained backgrounds: the run continues without one")
        if self.config.exposure == "on" or ckpt.get("exposure") is not None:
            self.exposures = _exposures_from_checkpoint(ckpt, len(self.train_views), self.config.device, path)
        if self.config.learn_poses:
            self.poses = _poses_from_checkpoint(ckpt, self._train_poses(), path)
        self.optimizer = make_optimizer(self.model, _learning_rates(self.config), self._view_params())
        self.optimizer.load_state_dict(ckpt["optimizer"])
        self.strategy.load_state_dict(ckpt["strategy"])
        if self._far_steps is not None:
            self._far_steps.load_state_dict(ckpt.get("far_vertex_steps"), self.model.params["vertices"])
        self.state = _State(**ckpt["state"])
        # Keep only the evaluations the checkpoint had already made.
        kept = [row for row in layout.read_metrics(self.run_dir) if row["iteration"] <= self.state.iteration]
        layout.metrics_path(self.run_dir).write_text("".join(json.dumps(row) + "\n" for row in kept))
        self.log(f"resumed at iteration {self.state.iteration} with {self.model.n_triangles} triangles")

    # -- the loop -------------------------------------------------------------------------------
    def _step(self, it: int) -> dict[str, float] | None:
        """Iteration ``it``: the strategy's work before the render, the schedule, one training view's
        render and loss, the optimiser step (rejected when not finite), then the strategy's
        densification. Returns the loss terms, or None for a rejected step."""
        self.strategy.before_step(self.model, self.optimizer, it)
        _apply_schedule(self.model, self.optimizer, self.config, it)
        index, view, camera = self._training_view(it)
        out, priors = self._render_training_view(index, view, camera)
        opacity = self.model.triangle_opacity()
        terms = training_loss(
            out, view.image, view.depth, view.normal, opacity, self.config,
            moving_mask=view.moving_mask, target_moments=view.image_moments, **priors,
        )  # fmt: skip
        terms.total.backward()
        accepted = self._optimizer_step(terms.total, it)
        report = self.strategy.after_step(self.model, self.optimizer, it, out if accepted else None, view)
        self._record(report)
        return terms.as_floats() if accepted else None

    def _training_view(self, it: int) -> tuple[int, View, CameraModel]:
        """Iteration ``it``'s training view (its index in the training views, the view) and the
        camera to render it with: at half resolution in the coarse start
        (:func:`splat.coarse_views.coarse_iterations`; made on first use, dropped after)."""
        n = len(self.train_views)
        index = int(_view_order(self.config.seed, it // n, n)[it % n])
        if it >= self._coarse_iterations:
            self._half_views.clear()
            view, camera = self.train_views[index], self.scene.camera
        else:
            if index not in self._half_views:
                self._half_views[index] = half_view(self.train_views[index])
            view, camera = self._half_views[index], self._half_camera
        if view.image_moments is None and index < self._views_with_moments and self.config.lambda_dssim > 0:
            view.image_moments = image_moments(view.image)
        return index, view, camera

    def _render_training_view(
        self, index: int, view: View, camera: CameraModel
    ) -> tuple[RenderOutput, dict[str, torch.Tensor]]:
        """The render of training view ``index`` (from its corrected pose and its colours mapped by
        the view's exposure, when the run learns them) and the priors of what the view learns
        (keyword arguments of :func:`splat.losses.training_loss`: ``exposure_prior``,
        ``pose_prior``; empty when it learns neither)."""
        priors: dict[str, torch.Tensor] = {}
        T_cam_world = view.T_cam_world
        if self.poses is not None:
            T_cam_world = self.poses.corrected(index)
            priors["pose_prior"] = self.poses.prior(index, self.config.pose_prior_translation_m)
        out = self.model.render(camera, T_cam_world, background_mask=view.background_mask)
        if self.exposures is not None:
            out = replace(out, rgb=self.exposures.apply(out.rgb, index))
            priors["exposure_prior"] = self.exposures.prior(index)
        return out, priors

    def _train_poses(self) -> torch.Tensor:
        """``(V, 4, 4)`` the training views' world-to-camera transforms."""
        return torch.stack([view.T_cam_world for view in self.train_views])

    def _view_params(self) -> dict[str, torch.Tensor]:
        """What the run learns per training view besides the triangles: name → leaf."""
        params = {}
        if self.exposures is not None:
            params["exposure"] = self.exposures.offsets
        if self.poses is not None:
            params["pose"] = self.poses.params
        return params

    def _optimizer_step(self, loss: torch.Tensor, it: int) -> bool:
        """Step the optimiser if ``loss`` and every gradient are finite, else count a rejected step
        (too many in a row: :class:`TrainingDivergedError`); the gradients are cleared either way."""
        params = self.model.trainable() + list(self._view_params().values())
        finite = _finite_step(loss, params)
        if finite:
            if self._far_steps is None:
                self.optimizer.step()
            else:
                self._far_steps.step(self.model.params["vertices"], self.optimizer.step)
            if self.poses is not None:
                self.poses.remove_common_motion()
        self.optimizer.zero_grad(set_to_none=True)
        self.state.rejected_total += not finite
        self.state.rejected_in_a_row = 0 if finite else self.state.rejected_in_a_row + 1
        if self.state.rejected_in_a_row >= self.config.max_rejected_steps:
            raise TrainingDivergedError(
                f"{self.state.rejected_in_a_row} steps in a row had a non-finite loss or gradient (last "
                f"at iteration {it}); the learning rates are probably too high for this scene"
            )
        return finite

    def _record(self, report: DensifyReport | None) -> None:
        if report is not None:
            self.state.densification.append(asdict(report))
            if note := report.note():
                self.state.skips.append(note)

    def _set_held_out_maps(self) -> str | None:
        """Give the test views their colour maps from the training views' (:func:`held_out_maps`);
        returns how they were chosen (None without maps or test views)."""
        if self.exposures is None or not self.test_views:
            return None
        train_times, test_times = _seconds(self.train_keyframes), _seconds(self.test_keyframes)
        if self._test_gains is None:
            self._test_gains = self._measured_test_gains(train_times, test_times)
        maps, rule = held_out_maps(self.exposures, train_times, test_times, self._test_gains)
        for view, matrix in zip(self.test_views, maps, strict=True):
            view.color_map = matrix.to(self.config.device)
        return rule

    def _measured_test_gains(
        self, train_times: np.ndarray, test_times: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Per test view (at ``test_times`` ``(Q,)`` s) the index of the training view nearest in
        time (``train_times`` ``(V,)``) and the log of its image's gain against that view's,
        measured on that view's LiDAR points (:func:`log_gain`; NaN where it cannot be)."""
        nearest = np.abs(test_times[:, None] - train_times[None, :]).argmin(axis=1)
        gains = []
        for view, keyframe, j in zip(self.test_views, self.test_keyframes, nearest, strict=True):
            train = self.train_keyframes[j]
            gain = log_gain(
                grey(self.train_views[j].image.cpu().numpy()),
                grey(view.image.cpu().numpy()),
                self.scene.lidar(train).points.astype(np.float64),
                self.scene.camera,
                train.T_world_cam,
                keyframe.T_world_cam,
            )
            gains.append(np.nan if gain is None else gain)
        return nearest, np.array(gains)

    def _write_color_maps(self) -> dict:
        """``RUN_DIR/exposure.json``: every keyframe's colour map and how the test views' were chosen;
        returns the maps' summary for ``summary.json`` (empty without maps)."""
        if self.exposures is None:
            return {}
        rule = self._set_held_out_maps()
        train = torch.eye(3) + self.exposures.offsets.detach().cpu()
        maps = {k.name: m.tolist() for k, m in zip(self.train_keyframes, train, strict=True)}
        maps |= {v.name: v.color_map.cpu().tolist() for v in self.test_views}
        record = {"test_views": rule, "maps": maps}
        layout.exposure_path(self.run_dir).write_text(json.dumps(record, indent=1))
        return {**self.exposures.summary(), "test_views": rule}

    def _fit_camera_blur(self) -> dict:
        """Fit the camera's blur on training views (:data:`~splat.camera_blur.FIT_VIEWS` of them, evenly
        spread; :func:`~splat.camera_blur.fit_blur`) and score the test views through it; returns its
        summary for ``summary.json``."""
        n = len(self.train_views)
        chosen = np.unique(np.linspace(0, n - 1, min(n, FIT_VIEWS)).round().astype(int))
        views = [self.train_views[i] for i in chosen]
        with torch.no_grad():
            renders = [
                self._render_training_view(i, view, self.scene.camera)[0].rgb
                for i, view in zip(chosen, views, strict=True)
            ]
        width, sharp, fitted = fit_blur(
            (r, v.image, v.moving_mask) for r, v in zip(renders, views, strict=True)
        )
        for view in self.test_views:
            view.blur_px = width
        self.log(f"the camera's blur: {width:.2f} px (training views {sharp:.2f} -> {fitted:.2f} dB)")
        return {"width_px": width, "train_psnr_sharp": round(sharp, 3), "train_psnr": round(fitted, 3)}

    def _evaluate(self, it: int, losses: dict[str, float]) -> None:
        self._set_held_out_maps()
        test = evaluate_views(self.model, self.test_views, self.scene.camera) if self.test_views else {}
        line = {
            "iteration": it,
            "elapsed_s": round(self.state.elapsed_s, 3),
            "n_triangles": self.model.n_triangles,
            "sigma": self.model.sigma,
            "opacity_floor": self.model.opacity_floor,
            "loss": losses,
            **test,
        }
        with layout.metrics_path(self.run_dir).open("a") as f:
            f.write(json.dumps(line) + "\n")
        self.state.last_test = test
        if "test_psnr" not in test or it < final_phase_start(self.config):
            return
        if test["test_psnr"] > self.state.best_psnr + self.config.min_improvement_db:
            self.state.best_psnr, self.state.evals_without_gain = test["test_psnr"], 0
        else:
            self.state.evals_without_gain += 1

    def run(self, progress: bool = True, on_iteration: Callable[[int], None] | None = None) -> TrainResult:
        """Train from the current state to the end (or an early stop); SIGINT saves a checkpoint.
        ``on_iteration`` is called with the number of iterations done after each one."""
        from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

        config = self.config
        columns = [TextColumn("train"), BarColumn(), MofNCompleteColumn(), TextColumn("{task.fields[info]}"),
                   TimeRemainingColumn()]  # fmt: skip
        losses: dict[str, float] = {}
        with Progress(*columns, console=console, disable=not progress, transient=True) as bar:
            task = bar.add_task("train", total=config.iterations, completed=self.state.iteration, info="")
            try:
                while self.state.iteration < config.iterations and not self.state.stopped_early:
                    it = self.state.iteration
                    started = time.perf_counter()
                    losses = self._step(it) or losses
                    self.state.iteration = it + 1
                    self.state.elapsed_s += time.perf_counter() - started
                    done = self.state.iteration
                    if evaluation_due(config, done):
                        self._evaluate(done, losses)
                        self._maybe_stop_early()
                    if done % config.checkpoint_every == 0:
                        self.save_checkpoint()
                    if on_iteration is not None:
                        on_iteration(done)
                    rate = self.state.iteration / max(self.state.elapsed_s, 1e-9)
                    bar.update(
                        task, completed=done, info=_progress_text(losses, self.model.n_triangles, rate)
                    )
            except KeyboardInterrupt:
                self.save_checkpoint()
                raise TrainingInterruptedError(
                    f"interrupted at iteration {self.state.iteration}; checkpoint saved in "
                    f"{layout.checkpoint_path(self.run_dir)} — rerun with --resume to continue"
                ) from None
        self.save_checkpoint()
        return self._finish()

    def _maybe_stop_early(self) -> None:
        if self.state.evals_without_gain < self.config.patience:
            return
        saved = self.config.iterations - self.state.iteration
        self.state.stopped_early = True
        self.state.skips.append(
            f"stopped early at iteration {self.state.iteration}: test PSNR gained less than "
            f"{self.config.min_improvement_db} dB over {self.config.patience} evaluations "
            f"({saved} iterations, {saved / self.config.iterations:.0%} of the budget, saved)"
        )
        self.log(self.state.skips[-1])

    def _finish(self) -> TrainResult:
        save_model(self.model, layout.model_path(self.run_dir))
        exposure = self._write_color_maps()
        blur = self._fit_camera_blur()
        test = evaluate_views(self.model, self.test_views, self.scene.camera) if self.test_views else {}
        if "test_psnr" in test:
            blur["test_psnr_sharp"] = self.state.last_test.get("test_psnr")  # the loop's last evaluation
        write_renders(self.model, self.test_views, self.scene.camera, layout.renders_dir(self.run_dir))
        keyframes, poses, lidar = self.train_keyframes, {}, self.lidar
        if self.poses is not None:
            keyframes = self.poses.corrected_keyframes(keyframes)
            write_keyframe_poses(keyframes, layout.keyframe_poses_path(self.run_dir))
            poses = self.poses.summary()
            lidar = lidar_points(self.scene, keyframes)  # the returns where the corrected poses put them
        export = export_run(self.model, self.scene, keyframes, self.run_dir, self.floor, lidar)
        c, s = self.config, self.state
        result = TrainResult(
            str(self.run_dir), c.method, c.preset, c.device, s.iteration, round(s.elapsed_s, 3),
            self.model.n_triangles, s.stopped_early, s.rejected_total, test, s.skips, s.densification, export,
            exposure, poses=poses, camera_blur=blur,
        )  # fmt: skip
        layout.summary_path(self.run_dir).write_text(json.dumps(asdict(result), indent=1))
        return result


def _seconds(keyframes: list[Keyframe]) -> np.ndarray:
    """``(K,)`` the keyframes' stamps in seconds."""
    return np.array([k.t_ns * 1e-9 for k in keyframes])


def _per_view_tensor(ckpt: dict, field: str, shape: tuple[int, ...], what: str, path: Path) -> torch.Tensor:
    """The checkpoint's ``field``, what the run learnt per training view (``what``, shape ``shape``
    with the views first); an error naming the file when it has none (a run started without them)
    or one of another shape (other keyframes)."""
    value = ckpt.get(field)
    if not isinstance(value, torch.Tensor) or tuple(value.shape) != shape:
        got = "none" if value is None else tuple(getattr(value, "shape", ()))
        raise InputError(
            f"expected the {what} of {shape[0]} training views (shape {shape}), got {got}; the run was "
            f"started without {what} or on other keyframes: train into a new --out",
            path=path,
            field=field,
        )
    return value


def _exposures_from_checkpoint(ckpt: dict, n_views: int, device: str, path: Path) -> ViewExposures:
    """The checkpoint's colour maps of ``n_views`` training views (:func:`_per_view_tensor`)."""
    return ViewExposures(_per_view_tensor(ckpt, "exposure", (n_views, 3, 3), "colour maps", path).to(device))


def _poses_from_checkpoint(ckpt: dict, T_cam_world: torch.Tensor, path: Path) -> PoseCorrections:
    """The checkpoint's pose corrections of the training views at ``T_cam_world`` ``(V, 4, 4)``
    (:func:`_per_view_tensor`)."""
    params = _per_view_tensor(ckpt, "pose", (len(T_cam_world), 6), "pose corrections", path)
    return PoseCorrections(params.to(T_cam_world), T_cam_world)


def write_keyframe_poses(keyframes: list[Keyframe], path: Path) -> None:
    """The keyframes' camera poses ``T_world_cam`` as a TUM trajectory at their stamps (what
    ``lts trajectory compare`` reads)."""
    from rig.trajectory import Trajectory
    from rig.trajectory_io import write_tum

    ordered = sorted(keyframes, key=lambda k: k.t_ns)
    poses = np.stack([k.T_world_cam for k in ordered])
    write_tum(Trajectory.from_poses(np.array([k.t_ns for k in ordered]), poses), path)


def _progress_text(losses: dict[str, float], n_triangles: int, rate: float) -> str:
    terms = " ".join(f"{k} {losses[k]:.4f}" for k in ("total", "l1", "depth", "normal") if k in losses)
    return f"{terms} {n_triangles} tri {rate:.1f} it/s"


@torch.no_grad()
def seen_triangles(model: TriangleModel, keyframes: list[Keyframe], camera: CameraModel) -> torch.Tensor:
    """``(F,)`` bool: the triangle dominates at least one pixel of some keyframe's view."""
    seen = torch.zeros(model.n_triangles, dtype=torch.bool)
    for k in keyframes:
        T_cam_world = torch.as_tensor(invert(k.T_world_cam), dtype=torch.float32, device=model.device)
        dominant = model.render(camera, T_cam_world).dominant
        seen[dominant[dominant >= 0].cpu()] = True
    return seen


def camera_only_triangles(
    triangles: torch.Tensor, lidar: np.ndarray, keyframes: list[Keyframe]
) -> np.ndarray:
    """``(F,)`` bool: the ``triangles`` ``(F, 3, 3)`` whose centroid no LiDAR return ``lidar`` ``(N, 3)``
    of ``keyframes`` explains (:func:`splat.camera_only.unexplained_points`): geometry from the
    images alone."""
    from splat.camera_only import unexplained_points

    centroids = triangles.detach().mean(dim=1).cpu().double().numpy()
    centres = np.stack([k.T_world_cam[:3, 3] for k in keyframes])
    return unexplained_points(centroids, lidar, centres)


def scene_floor(scene: Scene, keyframes: list[Keyframe], lidar: np.ndarray) -> PlaneGrid | None:
    """The floor plane of the scene's warm-start mesh and the LiDAR returns ``lidar`` ``(N, 3)``
    seen from ``keyframes`` (:func:`splat.init_mesh.fit_floor_plane`, as the ground fill finds it),
    or None without a floor."""
    from rig.mesh_io import load_mesh
    from splat.init_mesh import fit_floor_plane

    poses = np.stack([k.T_world_cam for k in keyframes])
    plane = fit_floor_plane(load_mesh(scene.mesh_path), poses, lidar)
    return None if plane is None else PlaneGrid(plane, 1.0)


def export_run(
    model: TriangleModel,
    scene: Scene,
    keyframes: list[Keyframe],
    run_dir: Path,
    floor: PlaneGrid | None,
    lidar: np.ndarray,
) -> dict:
    """Export ``model``'s meshes into ``run_dir`` (:func:`splat.export.export_mesh`): the collision
    mesh keeps the triangles seen from ``keyframes`` and the floor no camera sees (the triangles on
    ``floor``, :func:`scene_floor`: the ground fill's completion under furniture and round the
    path's ends, which never trains: without it a physics probe falls through there); the render
    mesh flags those no return of the keyframes' LiDAR ``lidar`` ``(N, 3)`` (world points,
    :func:`~splat.lidar_points.lidar_points`) explains; returns the export's summary for
    ``summary.json``."""
    from splat.export import export_mesh

    seen = seen_triangles(model, keyframes, scene.camera)
    triangles = model.params["vertices"].detach().cpu().double().numpy()
    camera_only = camera_only_triangles(model.params["vertices"], lidar, keyframes)
    result = export_mesh(model, run_dir, seen=seen, floor=on_floor(floor, triangles), camera_only=camera_only)
    return json.loads(json.dumps(asdict(result), default=str))


def train(
    scene: str | Path | Scene,
    run_dir: str | Path,
    config: TrainConfig,
    *,
    resume: bool = False,
    progress: bool = True,
    log: Callable = console.print,
    on_iteration: Callable[[int], None] | None = None,
) -> TrainResult:
    """Train ``config`` on ``scene`` (a scene folder, or a :class:`Scene` already loaded from one,
    whose files are then not read again) into ``run_dir`` (``resume``: continue from ``run_dir``'s
    last checkpoint, bit for bit on the CPU); ``on_iteration`` is told each iteration done."""
    trainer = Trainer(scene, run_dir, config, log)
    trainer.prepare(resume)
    return trainer.run(progress, on_iteration)
