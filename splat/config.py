"""Training configuration: one validated model, presets, and the method/ablation switches.

A run is fully described by its :class:`TrainConfig` (written to ``RUN_DIR/config.yaml``), so a
resumed run can check that it continues the same experiment.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any, Literal

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from rig.data_file import load_data_file
from rig.errors import InputError

Method = Literal["ours", "tsplus", "mesh-init", "lidar-init", "no-clone", "no-subdiv"]
Preset = Literal["fast", "default", "detail", "paper"]
METHODS: tuple[str, ...] = Method.__args__  # type: ignore[attr-defined]
PRESETS: tuple[str, ...] = Preset.__args__  # type: ignore[attr-defined]


class TrainConfig(BaseModel):
    """Every knob of a training run. Fractions are of ``iterations``."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    method: Method = "ours"
    preset: Preset = "default"
    iterations: int = Field(3000, ge=1)
    seed: int = Field(0, ge=0)
    device: str = "cpu"

    # Initialisation.
    init: Literal["mesh", "delaunay-sfm", "delaunay-lidar"] = "mesh"
    init_scale: float = Field(2.0, gt=0, description="decoupled faces are scaled about their centroid")
    init_color: Literal["grey", "project"] = "project"
    init_opacity: float = Field(0.7, gt=0, lt=1)
    init_max_triangles: int = Field(30_000, ge=100, description="warm-start mesh is simplified to this")
    init_noise_m: float = Field(0.0, ge=0, description="Gaussian noise on warm-start vertices (robustness)")
    snap_to_lidar: bool = Field(True, description="warm-start vertices snapped onto their local LiDAR planes")
    ground_fill: bool = True
    ground_cell_m: float = Field(0.15, gt=0)
    complete_hidden_floor: bool = Field(
        True, description="with ground_fill: also the floor no camera sees where the room encloses it"
    )
    camera_only_seeds: bool = Field(
        True,
        description="one triangle at each of the scene's sparse points no LiDAR return explains (what "
        "the camera sees beyond the LiDAR's field or range; splat.camera_only); needs sparse points",
    )
    lidar_fill: bool = Field(
        True,
        description="one triangle per 0.25 m voxel of the LiDAR returns no warm-start face lies near "
        "(holes of the mapper's mesh; splat.lidar_fill)",
    )
    upward_extension: bool = Field(
        True,
        description="upright surfaces at the topmost LiDAR returns continued up to the image top as "
        "camera-only cells (facades and poles above the LiDAR's field; splat.upward_extension)",
    )
    plane_sweep: bool = Field(
        True,
        description="camera-only cells where plane-sweep stereo between keyframes finds a surface above "
        "the LiDAR's reach that the upward extension does not cover (an overpass, tree crowns; "
        "splat.plane_sweep)",
    )
    lidar_init_points: int = Field(2_000, ge=4, description="as many as the SfM points TS+ starts from")

    # Loss weights (Eq. 3): (1-λ) L1 + λ D-SSIM + β1 opacity + β2 normal + β3 depth + β4 distortion.
    lambda_dssim: float = Field(0.2, ge=0, le=1)
    w_opacity: float = Field(0.0005, ge=0)
    w_normal: float = Field(0.05, ge=0)
    w_depth: float = Field(0.2, ge=0)
    depth_reference_m: float = Field(
        8.0, gt=0, description="LiDAR returns beyond this count their depth error relative to their range"
    )
    w_distortion: float = Field(0.01, ge=0)
    exposure: Literal["auto", "on", "off"] = Field(
        "auto",
        description="learn a colour matrix per training view (auto-exposure, white balance; splat.exposure), "
        "pulled towards the identity by w_exposure; auto: when the images' gains, measured on the LiDAR "
        "points neighbouring images share, spread by more than 5 %",
    )
    w_exposure: float = Field(0.01, ge=0, description="weight of the colour maps' prior towards the identity")
    learn_poses: bool = Field(
        False,
        description="learn a rigid correction of each training keyframe's pose with the triangles "
        "(splat.pose_corrections), pulled towards the LiDAR pose by w_pose",
    )
    w_pose: float = Field(0.1, ge=0, description="weight of the pose corrections' prior")
    pose_prior_translation_m: float = Field(
        0.1,
        gt=0,
        description="in the pose prior, a move of this many metres costs as much as a turn of 1 rad",
    )

    # Learning rates (Adam) and their schedule.
    # At 3e-4 the street's training views were fitted to only 27.1 dB (static pixels below the LiDAR's
    # top; 28.0 at 6e-4). 6e-4 gave test PSNR +0.3 dB on the room, +0.5 on the office and the
    # street; 1.2e-3 no more on the street and less on the room (docs/training.md, "Schedules").
    lr_vertices: float = Field(6e-4, ge=0, description="metres per step, about")
    lr_colors: float = Field(0.02, ge=0)
    lr_opacity: float = Field(0.05, ge=0)
    lr_background: float = Field(0.05, ge=0)
    lr_exposure: float = Field(0.01, ge=0)
    lr_pose: float = Field(1e-4, ge=0, description="radians and metres per step, about")
    vertex_step_range_m: float = Field(
        8.0,
        ge=0,
        description="beyond this distance from the nearest training camera a camera-only triangle's vertex "
        "steps grow with its distance (splat.far_vertex_steps: far geometry the LiDAR does not back moves "
        "as fast, in angle, as at this distance); 0: every vertex at lr_vertices",
    )
    vertex_lr_delay: float = Field(0.05, ge=0, le=1, description="vertex lr is 0 for this fraction")
    lr_final_factor: float = Field(0.1, gt=0, le=1)

    # TS+ schedules: sigma anneals, the opacity floor rises to 1 (opaque).
    sigma_start: float = Field(1.0, gt=0)
    sigma_end: float = Field(0.05, gt=0)
    sigma_anneal_end: float = Field(0.7, gt=0, le=1)
    floor_rise_start: float = Field(0.55, ge=0, le=1)
    floor_rise_end: float = Field(
        0.7,
        ge=0,
        le=1,
        description="the floor has risen by here, with sigma's anneal; the opaque, sharp phase that "
        "follows hardly gains (docs/training.md, Schedules), so early stopping can end it",
    )

    # Background: what the camera sees beyond the triangles (sky, structure above the LiDAR's field).
    # On the 8 s street the map took the test PSNR above the LiDAR's field 21.5 -> 22.4 dB
    # (docs/outdoor.md, "A map of the sky").
    background: Literal["map", "sh", "none"] = Field(
        "map",
        description="a trained colour per viewing direction (splat.background) composited where the "
        "triangles' accumulated opacity is below 1, never exported. sh: spherical harmonics alone; "
        "map: plus an equirectangular map down to 0.7° (a sky between roofs, far structure); none: black",
    )
    background_sh_degree: int = Field(2, ge=0, le=3, description="degree of the background's harmonics")
    background_where: Literal["above-lidar", "everywhere"] = Field(
        "above-lidar",
        description="where training composites it: where the LiDAR reached nothing, above each image "
        "column's topmost return and in 2° windows without a return between returns (elsewhere a gap "
        "between triangles stays black, so it is still filled), or everywhere",
    )

    # Densification.
    densify: Literal["variance", "opacity", "none"] = Field(
        "variance", description="the splat.strategy: variance (ours), opacity (TS+), none (final prune only)"
    )
    clone: bool = True
    subdivide: bool = True
    densify_every: int = Field(500, ge=1)
    densify_until: float = Field(0.55, ge=0, le=1)
    growth_rate: float = Field(0.15, ge=0, description="new triangles per densification / current count")
    max_triangles: int = Field(80_000, ge=1)
    lidar_noise_m: float = Field(0.015, gt=0, description="depth-error std treated as noise")
    normal_noise: float = Field(0.02, gt=0, description="std of 1 - n·n_prior treated as noise")
    color_noise: float = Field(
        0.03,
        gt=0,
        description="std of a pixel's colour error treated as noise where no LiDAR backs a triangle",
    )
    prune_opacity: float = Field(0.05, ge=0, lt=1)
    final_prune_opacity: float = Field(
        0.2, ge=0, lt=1, description="before the opacity floor rises, triangles below this are removed"
    )
    prune_unseen: bool = Field(
        False,
        description="prune triangles no training view sees: yes for Delaunay starts (arbitrary tetrahedron "
        "faces), no for the mesh warm start (what no camera sees is still the LiDAR's geometry)",
    )
    keep_far_floor: bool = Field(
        True,
        description="never prune the triangles on the floor plane farther than 8 m from every camera for "
        "their transparency: a street's road there, a few pixels high between a spinning LiDAR's rings, "
        "turns transparent where the background explains those pixels, and the mesh loses it",
    )

    # Skipping work and bookkeeping.
    coarse_until: float = Field(
        0.25,
        ge=0,
        le=1,
        description="this fraction of the iterations renders the training views at half resolution "
        "(splat.coarse_views: a quarter of the pixels while the triangles are still soft); 0: never",
    )
    coarse_min_side_px: int = Field(
        120,
        ge=1,
        description="no coarse start when the half-size images would be smaller than this on their "
        "shorter side (the quick demo's 160x120 views, trained at 80x60 for a quarter of the run, "
        "lost 1.1 dB of test PSNR; the room's 320x240 at 160x120 lost nothing)",
    )
    eval_every: int = Field(250, ge=1)
    final_eval_every: int = Field(
        50,
        ge=1,
        description="once every schedule has reached its end (opaque, sharp triangles), the held-out "
        "views are evaluated this often, so that early stopping can end a run that no longer gains "
        "(with eval_every alone, a final phase shorter than patience evaluations could never stop)",
    )
    patience: int = Field(3, ge=1, description="evaluations without improvement before stopping")
    min_improvement_db: float = Field(0.05, ge=0)
    drop_redundant_keyframes: bool = True
    redundant_motion_m: float = Field(0.05, ge=0)
    redundant_turn_deg: float = Field(2.0, ge=0)
    checkpoint_every: int = Field(500, ge=1)
    max_rejected_steps: int = Field(20, ge=1, description="consecutive non-finite steps before giving up")

    @field_validator("device")
    @classmethod
    def _device(cls, device: str) -> str:
        if not re.fullmatch(r"cpu|cuda(:\d+)?", device):
            raise ValueError(f"expected cpu, cuda or cuda:N, got {device!r}")
        return device

    @model_validator(mode="after")
    def _ordered(self) -> TrainConfig:
        if self.floor_rise_end < self.floor_rise_start:
            raise ValueError("floor_rise_end must not come before floor_rise_start")
        return self

    def to_yaml(self) -> str:
        return yaml.safe_dump(self.model_dump(), sort_keys=False)


#: What each method changes relative to ``ours`` (the method itself).
METHOD_OVERRIDES: dict[str, dict[str, Any]] = {
    "ours": {},
    # The photometric-only Triangle Splatting+ baseline: Delaunay of SfM points, TS+ densification.
    "tsplus": {
        "init": "delaunay-sfm", "w_depth": 0.0, "w_normal": 0.0, "densify": "opacity", "clone": False,
        "ground_fill": False, "prune_unseen": True,
    },
    # Ablations.
    "mesh-init": {"densify": "opacity", "clone": False},
    "lidar-init": {"init": "delaunay-lidar", "ground_fill": False, "prune_unseen": True},
    "no-clone": {"clone": False},
    "no-subdiv": {"subdivide": False},
}  # fmt: skip

PRESET_OVERRIDES: dict[str, dict[str, Any]] = {
    "fast": {"iterations": 1200, "densify_every": 300, "eval_every": 200, "init_max_triangles": 15_000},
    "default": {},
    # More triangles sooner: the opaque end of a training runs short of them on textured surfaces
    # (docs/outdoor.md). 0.04-0.23 dB more PSNR for 1.1-1.6x the training time on the room, the
    # office and the streets, so not the default.
    "detail": {"growth_rate": 0.5, "max_triangles": 200_000},
    # TS+-like schedules over a longer run.
    "paper": {
        "iterations": 10_000, "densify_every": 500, "init_max_triangles": 60_000, "max_triangles": 200_000,
        "vertex_lr_delay": 0.1, "eval_every": 500,
    },
}  # fmt: skip

#: What each preset is for, in a line (the command lines' help).
PRESET_HELP = (
    "fast (1200 iterations, a smaller warm start), default (3000), detail (3000, more triangles "
    "sooner, up to 200 000: a little sharper, 1.1-1.6x slower), paper (10 000, TS+-like schedules)"
)


def make_config(method: str = "ours", preset: str = "default", **overrides: Any) -> TrainConfig:
    """The config of ``method`` at ``preset``, then ``overrides`` (field → value) on top."""
    if method not in METHOD_OVERRIDES:
        raise InputError(f"unknown method {method!r}; expected one of {', '.join(METHODS)}", field="method")
    if preset not in PRESET_OVERRIDES:
        raise InputError(f"unknown preset {preset!r}; expected one of {', '.join(PRESETS)}", field="preset")
    values = {
        "method": method,
        "preset": preset,
        **PRESET_OVERRIDES[preset],
        **METHOD_OVERRIDES[method],
        **overrides,
    }
    return validated(values)


def config_from_options(
    method: str,
    preset: str,
    *,
    seed: int = 0,
    device: str = "cpu",
    init_noise_m: float = 0.0,
    iterations: int | None = None,
    max_triangles: int | None = None,
    coarse_until: float | None = None,
    exposure: str = "auto",
    learn_poses: bool = False,
) -> TrainConfig:
    """The config ``lts train`` builds from its options (None: the preset's value), so that
    ``lts reconstruct`` can tell whether an existing run was made with the same ones."""
    overrides: dict[str, Any] = {
        "seed": seed, "device": device, "init_noise_m": init_noise_m, "exposure": exposure,
        "learn_poses": learn_poses,
    }  # fmt: skip
    if iterations is not None:
        overrides["iterations"] = iterations
    if max_triangles is not None:
        overrides["max_triangles"] = max_triangles
    if coarse_until is not None:
        overrides["coarse_until"] = coarse_until
    return make_config(method, preset, **overrides)


def validated(values: dict[str, Any], path: Path | None = None) -> TrainConfig:
    """A :class:`TrainConfig` from plain values; errors name the file and the offending field."""
    try:
        return TrainConfig(**values)
    except ValidationError as exc:
        first = exc.errors()[0]
        field = ".".join(str(p) for p in first["loc"]) or None
        # A validator's own ValueError comes back as "Value error, <its message>".
        raise InputError(first["msg"].removeprefix("Value error, "), path=path, field=field) from None


def load_config(path: str | Path) -> TrainConfig:
    """Read ``config.yaml`` written by a run."""
    path = Path(path)
    if not path.is_file():
        raise InputError("no such config file", path=path)
    values = load_data_file(path, "YAML", "config")
    if not isinstance(values, dict):
        raise InputError("expected a mapping of config fields", path=path)
    return validated(values, path)
