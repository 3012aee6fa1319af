"""Training: initialisation, densification bookkeeping, variance statistics, guards, resume."""

from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np
import pytest
import torch
import trimesh
from training_scene import CAMERA, camera_poses, corner_mesh, write_training_scene

from rig.errors import InputError
from splat.config import make_config
from splat.floor_cells import PlaneGrid
from splat.init_mesh import decouple_and_scale, ground_fill
from splat.model import TriangleModel, load_model
from splat.param_rows import make_optimizer, replace_rows
from splat.raster.extension import optional_cpu_extension
from splat.schedule import evaluation_due, final_phase_start
from splat.strategy import OpacityStrategy, VarianceStrategy
from splat.strategy.growth import cloned_rows, subdivided_rows
from splat.strategy.variance import color_error, composed_error_sums, depth_error, error_sums, shared_budget
from splat.trainer import Trainer, TrainingDivergedError, train
from splat.views import View, load_views


@pytest.fixture(scope="module")
def scene_dir(tmp_path_factory):
    return write_training_scene(tmp_path_factory.mktemp("scene"))


_TINY = dict(
    iterations=60, densify_every=20, densify_until=0.5, eval_every=20, checkpoint_every=20,
    init_max_triangles=500, ground_fill=False, drop_redundant_keyframes=False, growth_rate=0.2,
    coarse_min_side_px=1,  # the 64x48 views start at 32x24: the coarse start is exercised too
)  # fmt: skip


def _tiny_config(**overrides):
    return make_config("ours", "default", **{**_TINY, **overrides})


def _model(n: int = 6, seed: int = 0) -> TriangleModel:
    g = torch.Generator().manual_seed(seed)
    triangles = torch.rand(n, 3, 3, generator=g) + torch.tensor([0.0, 0.0, 3.0])
    return TriangleModel.from_triangles(triangles, torch.rand(n, 3, 3, generator=g) * 0.8 + 0.1, 0.6)


def test_decouple_and_scale_keeps_centroids_and_scales_areas():
    mesh = corner_mesh(4)
    triangles = decouple_and_scale(mesh.vertices, mesh.faces, 2.0)
    original = np.asarray(mesh.vertices)[np.asarray(mesh.faces)]
    np.testing.assert_allclose(triangles.mean(axis=1), original.mean(axis=1), atol=1e-12)
    area = lambda t: 0.5 * np.linalg.norm(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]), axis=1)  # noqa: E731
    np.testing.assert_allclose(area(triangles), 4.0 * area(original), rtol=1e-12)


def test_replace_rows_keeps_adam_state_with_its_rows():
    model = _model(5)
    optimizer = make_optimizer(model, {"vertices": 0.01, "colors": 0.01, "opacity": 0.01})
    for p in model.params.values():
        p.grad = torch.arange(p.numel(), dtype=p.dtype).view_as(p) + 1.0
    optimizer.step()
    before = {n: optimizer.state[p]["exp_avg"].clone() for n, p in model.params.items()}
    values = {n: p.detach().clone() for n, p in model.params.items()}
    keep = torch.tensor([True, False, True, True, False])
    added = {n: v[:2] * 0 + 7 for n, v in values.items()}
    replace_rows(model, optimizer, keep, added)
    assert model.n_triangles == 5
    for name, p in model.params.items():
        assert p.is_leaf and p.requires_grad
        assert (
            optimizer.param_groups[[g["name"] for g in optimizer.param_groups].index(name)]["params"][0] is p
        )
        state = optimizer.state[p]
        torch.testing.assert_close(p.detach()[:3], values[name][keep])
        torch.testing.assert_close(state["exp_avg"][:3], before[name][keep])
        assert not state["exp_avg"][3:].any() and not state["exp_avg_sq"][3:].any()
    optimizer.step()  # the optimiser still works on the new tensors


def _area(t: torch.Tensor) -> torch.Tensor:
    """Areas of triangles ``(..., 3, 3)``."""
    return 0.5 * torch.linalg.cross(t[..., 1, :] - t[..., 0, :], t[..., 2, :] - t[..., 0, :]).norm(dim=-1)


def test_clone_preserves_transmittance_and_subdivision_covers_the_parent():
    model = _model(4)
    rows = torch.tensor([1, 3])
    clones = cloned_rows(model, rows)
    o = torch.sigmoid(model.params["opacity"].detach()[rows])
    o_clone = torch.sigmoid(clones["opacity"][:2])
    torch.testing.assert_close(1 - (1 - o_clone) ** 2, o, rtol=1e-4, atol=1e-5)
    torch.testing.assert_close(clones["vertices"][:2], clones["vertices"][2:])

    children = subdivided_rows(model, rows)["vertices"].view(4, 2, 3, 3)  # child-major, then parent
    parents = model.params["vertices"].detach()[rows]
    torch.testing.assert_close(_area(children).sum(0), _area(parents), rtol=1e-5, atol=1e-7)
    torch.testing.assert_close(children.mean(dim=(0, 2)), parents.mean(dim=1), rtol=1e-5, atol=1e-6)


def _optimizer(model: TriangleModel) -> torch.optim.Adam:
    return make_optimizer(model, {"vertices": 0.01, "colors": 0.01, "opacity": 0.01})


def _variance_strategy(model: TriangleModel, **overrides) -> VarianceStrategy:
    strategy = VarianceStrategy(_tiny_config(**overrides), log=lambda *_: None)
    strategy.initialize(model)
    return strategy


def test_variance_statistics_match_a_direct_computation():
    model = _model(8, seed=2)
    g = torch.Generator().manual_seed(4)
    target = 3.0 + torch.rand(CAMERA.height, CAMERA.width, generator=g)
    target[torch.rand(target.shape, generator=g) < 0.3] = 0  # pixels without LiDAR
    out = model.render(CAMERA, torch.eye(4))
    view = View("v", torch.eye(4), torch.zeros(CAMERA.height, CAMERA.width, 3), depth=target, normal=None)
    strategy = _variance_strategy(model)
    strategy.gather(model, out, view)
    strategy.gather(model, out, view)  # accumulating a view twice leaves the variance unchanged
    dominant, depth = out.dominant.numpy(), out.accumulated_depth.detach().numpy()
    for face in range(model.n_triangles):
        mask = (dominant == face) & (target.numpy() > 0)
        expected = np.var(target.numpy()[mask] - depth[mask]) if mask.any() else 0.0
        assert int(strategy.depth_error.count[face]) == 2 * mask.sum()
        assert float(strategy.depth_error.variance()[face]) == pytest.approx(expected, rel=1e-3, abs=1e-6)
    assert torch.equal(depth_error(out, target)[1], target > 0)


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64], ids=["f32", "f64"])
def test_error_sums_of_the_cpu_kernel_match_their_composition_to_the_bit(dtype):
    model = _model(40, seed=3)
    model.params = {k: v.to(dtype) if v.is_floating_point() else v for k, v in model.params.items()}
    g = torch.Generator().manual_seed(6)
    shape = (CAMERA.height, CAMERA.width)
    image = torch.rand(*shape, 3, generator=g, dtype=dtype)
    depth = torch.where(torch.rand(shape, generator=g) < 0.5, 3.0 + torch.rand(shape, generator=g), 0.0)
    depth[0, :5] = float("inf")  # not a return
    normal = torch.nn.functional.normalize(torch.randn(*shape, 3, generator=g, dtype=dtype), dim=-1)
    normal[:10] = 0.0  # no prior
    normal[10, :3] = float("nan")
    moving = torch.rand(shape, generator=g) < 0.2
    out = model.render(CAMERA, torch.eye(4, dtype=dtype))
    assert optional_cpu_extension() is not None  # the kernel is what is compared, not the fallback
    views = [
        View("all", torch.eye(4, dtype=dtype), image, depth.to(dtype), normal, moving_mask=moving),
        View("bare", torch.eye(4, dtype=dtype), image, depth=None, normal=None),
    ]
    for view in views:
        fused, composed = error_sums(out, view), composed_error_sums(out, view)
        for ours, spec in zip(fused, composed, strict=True):
            assert (ours is None) == (spec is None)
            for name in () if ours is None else ("count", "sum", "sum_sq"):
                assert torch.equal(getattr(ours, name), getattr(spec, name)), (view.name, name)
        assert int(fused[2].count.sum()) > 0
    assert int(error_sums(out, views[0])[1].count.sum()) > 0


def test_densification_with_all_zero_weights_is_skipped_not_a_crash():
    model = _model(6)
    strategy = _variance_strategy(model)
    strategy.max_weight[:] = 1.0  # every triangle seen, no error at all
    report = strategy.densify(model, _optimizer(model), 20)
    assert report.skipped and "positive sampling weight" in report.skipped
    assert model.n_triangles == 6 and report.cloned == report.subdivided == 0


def test_variance_sampling_clones_depth_errors_and_subdivides_normal_errors():
    model = _model(4)
    strategy = _variance_strategy(model, growth_rate=2.0)
    strategy.max_weight[:] = 1.0
    strategy.depth_error.count[:] = 100
    strategy.depth_error.sum_sq[0] = 100 * 0.2**2  # triangle 0: 20 cm depth spread → clone
    strategy.normal_error.count[:] = 100
    strategy.normal_error.sum_sq[1] = 100 * 0.5**2  # triangle 1: normal spread → subdivide
    report = strategy.densify(model, _optimizer(model), 20)
    assert (report.cloned, report.subdivided) == (1, 1)
    assert model.n_triangles == 2 + 2 + 4
    assert strategy.max_weight.shape == (8,) and strategy.depth_error.count.shape == (8,)  # fresh statistics


def test_colour_statistics_count_only_opaque_static_pixels_without_lidar():
    model = _model(8, seed=2)
    g = torch.Generator().manual_seed(5)
    image = torch.rand(CAMERA.height, CAMERA.width, 3, generator=g)
    depth = torch.where(torch.rand(CAMERA.height, CAMERA.width, generator=g) < 0.5, 4.0, 0.0)
    moving = torch.zeros(CAMERA.height, CAMERA.width, dtype=torch.bool)
    moving[:, : CAMERA.width // 4] = True
    out = model.render(CAMERA, torch.eye(4))
    view = View("v", torch.eye(4), image, depth=depth, normal=None, moving_mask=moving)
    strategy = _variance_strategy(model)
    strategy.gather(model, out, view)
    counted = (depth == 0) & ~moving & (out.alpha.detach() >= 0.5)
    assert torch.equal(color_error(out, view)[1], counted) and counted.any()
    error = (image - out.rgb.detach()).mean(dim=-1).numpy()
    dominant = out.dominant.numpy()
    for face in range(model.n_triangles):
        mask = (dominant == face) & counted.numpy()
        assert int(strategy.color_error.count[face]) == mask.sum()
        expected = np.var(error[mask]) if mask.any() else 0.0
        assert float(strategy.color_error.variance()[face]) == pytest.approx(expected, rel=1e-3, abs=1e-6)


def test_colour_variance_subdivides_only_triangles_no_lidar_return_backs():
    model = _model(4)
    strategy = _variance_strategy(model, growth_rate=2.0)
    strategy.max_weight[:] = 1.0
    strategy.depth_error.count[:2] = 100  # triangles 0, 1: LiDAR within noise
    strategy.color_error.count[:] = 100
    strategy.color_error.sum_sq[1:3] = 100 * 0.2**2  # texture on 1 (LiDAR-backed) and 2 (not)
    weights, prefer_clone = strategy.sampling_weights(model)
    assert weights.tolist() == [0.0, 0.0, pytest.approx(0.2**2 / 0.03**2), 0.0]
    assert not prefer_clone[2]
    report = strategy.densify(model, _optimizer(model), 20)
    assert (report.cloned, report.subdivided) == (0, 1) and model.n_triangles == 3 + 4


def test_lidar_and_colour_candidates_share_the_budget_by_their_numbers():
    geometric = torch.tensor([4000.0, 2000.0, 6000.0, 0.0, 0.0])
    photometric = torch.tensor([0.0, 0.0, 0.0, 5.0, 15.0])
    shared = shared_budget(geometric, photometric)
    assert shared.tolist() == pytest.approx([1.0, 0.5, 1.5, 0.5, 1.5])
    assert torch.equal(shared_budget(geometric, torch.zeros(5)), geometric)  # one kind alone: as it is
    assert torch.equal(shared_budget(torch.zeros(5), photometric), photometric)


def test_a_strategy_densifies_on_schedule_and_moves_adam_state_with_the_rows():
    model = _model(5)
    with torch.no_grad():
        model.params["opacity"][4] = -10.0  # transparent: pruned
    optimizer = _optimizer(model)
    for p in model.params.values():
        p.grad = torch.arange(p.numel(), dtype=p.dtype).view_as(p) + 1.0
    optimizer.step()
    before = {name: optimizer.state[p]["exp_avg"].clone() for name, p in model.params.items()}
    vertices = model.params["vertices"].detach().clone()
    strategy = OpacityStrategy(_tiny_config(growth_rate=1.5), log=lambda *_: None)  # budget: 6 = 2 splits
    strategy.initialize(model)
    strategy.max_weight[:4] = 1.0  # triangles 0-3 seen
    assert strategy.after_step(model, optimizer, 18, None, None) is None  # densify_every = 20
    report = strategy.after_step(model, optimizer, 19, None, None)
    assert (report.iteration, report.pruned, report.cloned, report.subdivided) == (20, 1, 0, 2)
    assert model.n_triangles == 2 + 2 * 4
    # The two kept, unsampled rows come first, in order; the 8 children after them.
    kept = [next(i for i in range(4) if torch.equal(vertices[i], v)) for v in model.params["vertices"][:2]]
    assert kept == sorted(kept)
    for name, p in model.params.items():
        group = next(g for g in optimizer.param_groups if g["name"] == name)
        assert group["params"][0] is p and p.is_leaf and p.requires_grad
        state = optimizer.state[p]
        assert torch.equal(state["exp_avg"][:2], before[name][kept])
        assert not state["exp_avg"][2:].any() and not state["exp_avg_sq"][2:].any()
    optimizer.step()  # the optimiser still works on the new tensors


def test_the_detail_preset_adds_more_triangles_at_each_densification(scene_dir, tmp_path):
    added = {}
    for preset in ("default", "detail"):
        values = {**_TINY, "growth_rate": make_config("ours", preset).growth_rate}
        config = make_config("ours", preset, **values)
        assert config.max_triangles == {"default": 80_000, "detail": 200_000}[preset]
        result = train(scene_dir, tmp_path / preset, config, progress=False, log=lambda *_: None)
        added[preset] = [row["after"] - row["before"] + row["pruned"] for row in result.densification]
    assert len(added["detail"]) == len(added["default"]) > 0
    assert all(d > 2 * n for d, n in zip(added["detail"], added["default"], strict=True))


@pytest.mark.parametrize("keep_far_floor", [True, False])
def test_transparent_triangles_on_the_far_floor_are_kept(keep_far_floor):
    """A street's far road, a few pixels between the LiDAR's rings, turns transparent where the
    background explains it: the prunes keep what lies on the floor plane beyond 8 m of every camera
    (config keep_far_floor), and prune the floor nearer, and what lies off it."""
    on_plane = torch.tensor([[0.0, 0, 0], [2, 0, 0], [0, 2, 0.05]])  # within 10 cm of z = 0
    far, up = torch.tensor([20.0, 0, 0]), torch.tensor([0, 0, 0.5])
    triangles = torch.stack([on_plane + far, on_plane, on_plane + far + up, on_plane + up])
    model = TriangleModel.from_triangles(triangles, torch.full((4, 3, 3), 0.5), 0.6)
    with torch.no_grad():
        model.params["opacity"][:3] = -10.0  # transparent; the last one stays opaque
    optimizer = _optimizer(model)
    strategy = OpacityStrategy(_tiny_config(keep_far_floor=keep_far_floor), log=lambda *_: None)
    strategy.keep_far_floor(PlaneGrid(np.array([0.0, 0.0, 1.0, 0.0]), 1.0), np.array([[0.0, 0.0, 1.5]]))
    strategy.initialize(model)
    strategy.before_step(model, optimizer, strategy.config.iterations)  # the final prune
    kept = [0, 3] if keep_far_floor else [3]
    assert torch.equal(model.params["vertices"].detach(), triangles[kept])


def test_statistics_are_gathered_only_for_a_densification_still_to_come():
    # The default schedule: densify every 500 iterations while at most 55 % of 3000 are done.
    strategy = OpacityStrategy(make_config("ours", "default"), log=lambda *_: None)
    assert strategy.last_densification() == 1500
    assert [strategy.densifies_after(i) for i in (498, 499, 1499, 1649, 1999)] == [
        False, True, True, False, False,
    ]  # fmt: skip
    assert strategy.collects_at(1499) and not strategy.collects_at(1500)


def test_held_out_views_are_evaluated_often_enough_for_early_stopping_once_the_schedules_end():
    config = make_config("ours", "default")
    assert final_phase_start(config) == 2100  # the opacity floor has risen, sigma is annealed
    due = [i for i in range(1, config.iterations + 1) if evaluation_due(config, i)]
    assert due[:3] == [250, 500, 750] and 2125 not in due
    assert [i for i in due if i >= 1750] == [1750, 2000, *range(2100, 3001, 50)]
    # Patience 3: a run that gains nothing in its final phase stops 750 iterations early.
    assert final_phase_start(config) + config.patience * config.final_eval_every == 2250


def test_training_stops_early_when_the_held_out_views_gain_nothing_in_the_final_phase(scene_dir, tmp_path):
    run = tmp_path / "run"
    config = _tiny_config(iterations=120, final_eval_every=5, patience=2, min_improvement_db=100.0)
    result = train(scene_dir, run, config, progress=False, log=lambda *_: None)
    # The final phase starts at 84: evaluated at 85 (the best so far), 90 and 95, then stopped.
    lines = [json.loads(line) for line in (run / "metrics.jsonl").read_text().splitlines()]
    assert [line["iteration"] for line in lines] == [20, 40, 60, 80, 85, 90, 95]
    assert result.stopped_early
    assert any("stopped early at iteration 95" in s and "(25 iterations" in s for s in result.skips)
    assert json.loads((run / "summary.json").read_text())["stopped_early"]
    assert load_model(run / "model.pt").n_triangles == result.n_triangles


def test_ground_fill_covers_a_hole_in_the_floor():
    mesh = corner_mesh(12)
    centroids = mesh.triangles_center
    hole = (
        (centroids[:, 2] < 1e-6)
        & (np.abs(centroids[:, 0]) < 1.0)
        & (centroids[:, 1] > 0.3)
        & (centroids[:, 1] < 2.0)
    )
    holed = trimesh.Trimesh(mesh.vertices, mesh.faces[~hole], process=False)
    fill = ground_fill(holed, CAMERA, camera_poses(6), cell_m=0.2)
    assert fill.plane is not None
    np.testing.assert_allclose(fill.plane, [0, 0, 1, 0], atol=1e-6)
    assert len(fill.triangles) > 0
    assert np.abs(fill.triangles[..., 2]).max() < 1e-9
    centres = fill.triangles.mean(axis=1)
    on_mesh = (np.abs(centres[:, 0]) < 2.0) & (centres[:, 1] > -1.0) & (centres[:, 1] < 3.0)
    in_hole = (np.abs(centres[:, 0]) < 1.0 + 0.2) & (centres[:, 1] > 0.3 - 0.2) & (centres[:, 1] < 2.0 + 0.2)
    assert not (on_mesh & ~in_hole).any()  # no cell where the mesh already has floor
    hole_area = 2.0 * 1.7
    filled = 0.5 * np.linalg.norm(np.cross(fill.triangles[:, 1] - fill.triangles[:, 0],
                                           fill.triangles[:, 2] - fill.triangles[:, 0]), axis=1)  # fmt: skip
    assert filled[in_hole].sum() > 0.6 * hole_area  # the cameras see the hole but for its nearest strip
    whole = ground_fill(mesh, CAMERA, camera_poses(6), cell_m=0.2)
    centres = whole.triangles.mean(axis=1)  # only the floor beyond the mesh's edges is added
    assert not ((np.abs(centres[:, 0]) < 1.9) & (centres[:, 1] > -0.9) & (centres[:, 1] < 2.9)).any()


def test_training_improves_the_view_and_writes_the_run_folder(scene_dir, tmp_path):
    run = tmp_path / "run"
    result = train(scene_dir, run, _tiny_config(iterations=120), progress=False, log=lambda *_: None)
    for name in (
        "config.yaml",
        "run.json",
        "metrics.jsonl",
        "model.pt",
        "summary.json",
        "mesh.ply",
        "collision.ply",
    ):
        assert (run / name).is_file(), name
    lines = [json.loads(line) for line in (run / "metrics.jsonl").read_text().splitlines()]
    assert [line["iteration"] for line in lines] == [20, 40, 60, 80, 100, 120]
    # The LiDAR term pulls the 10 cm-coarse start onto the surfaces.
    assert lines[-1]["loss"]["depth"] < 0.5 * lines[0]["loss"]["depth"]
    assert result.test["test_depth_l1_m"] < 0.05
    assert load_model(run / "model.pt").n_triangles == result.n_triangles
    assert result.densification and result.rejected_steps == 0
    blur = result.camera_blur  # fitted on the training views; the test views are scored through it
    assert 0 <= blur["width_px"] <= 1.5 and blur["train_psnr"] >= blur["train_psnr_sharp"]
    assert blur["test_psnr_sharp"] == lines[-1]["test_psnr"]


def test_resume_after_a_kill_reaches_identical_parameters(scene_dir, tmp_path, monkeypatch):
    # Every camera-only triangle counts as far (splat.far_vertex_steps): the scales of its steps must
    # survive the kill.
    config = _tiny_config(vertex_step_range_m=0.5)
    whole = train(scene_dir, tmp_path / "whole", config, progress=False, log=lambda *_: None)

    class KilledError(Exception):
        pass

    original = Trainer._step
    kill_at = 47  # after the checkpoint at 40, mid-way between densifications

    def dying_step(self, it):
        if it == kill_at:
            raise KilledError
        return original(self, it)

    monkeypatch.setattr(Trainer, "_step", dying_step)
    with pytest.raises(KilledError):
        train(scene_dir, tmp_path / "killed", config, progress=False, log=lambda *_: None)
    monkeypatch.setattr(Trainer, "_step", original)
    resumed = train(scene_dir, tmp_path / "killed", config, resume=True, progress=False, log=lambda *_: None)
    a, b = load_model(tmp_path / "whole" / "model.pt"), load_model(tmp_path / "killed" / "model.pt")
    for name in a.params:
        assert torch.equal(a.params[name], b.params[name]), name
    assert torch.equal(a.background, b.background)
    assert resumed.test == whole.test
    lines = (tmp_path / "killed" / "metrics.jsonl").read_text().splitlines()
    # Every 20 iterations, and every 50 once the final phase starts (at 42).
    assert [json.loads(line)["iteration"] for line in lines] == [20, 40, 50, 60]


def test_resuming_with_other_settings_names_each_change(scene_dir, tmp_path):
    run = tmp_path / "run"
    train(scene_dir, run, _tiny_config(iterations=20), progress=False, log=lambda *_: None)
    with pytest.raises(InputError, match=r"other settings \(seed 0 -> 1, floor_rise_end 0.7 -> 0.8\)"):
        train(scene_dir, run, _tiny_config(iterations=20, seed=1, floor_rise_end=0.8), resume=True,
              progress=False, log=lambda *_: None)  # fmt: skip


def test_keeping_the_views_image_moments_changes_nothing_but_the_time(scene_dir, tmp_path, monkeypatch):
    import splat.trainer as trainer_module

    config = _tiny_config(iterations=40)
    kept = Trainer(scene_dir, tmp_path / "kept", config, log=lambda *_: None)
    kept.prepare(resume=False)
    kept.run(progress=False)
    assert all(view.image_moments is not None for view in kept.train_views)
    monkeypatch.setattr(trainer_module, "IMAGE_MOMENTS_BUDGET_BYTES", 0)
    recomputed = Trainer(scene_dir, tmp_path / "recomputed", config, log=lambda *_: None)
    recomputed.prepare(resume=False)
    recomputed.run(progress=False)
    assert all(view.image_moments is None for view in recomputed.train_views)
    for name in kept.model.params:
        assert torch.equal(kept.model.params[name], recomputed.model.params[name]), name


def test_non_finite_steps_are_rejected_and_persistent_ones_stop_training(scene_dir, tmp_path, monkeypatch):
    import splat.trainer as trainer_module

    real_loss = trainer_module.training_loss
    calls = {"n": 0}

    def sometimes_nan(*args, **kwargs):
        terms = real_loss(*args, **kwargs)
        calls["n"] += 1
        if calls["n"] in (3, 4):
            terms.total = terms.total * float("nan")
        return terms

    monkeypatch.setattr(trainer_module, "training_loss", sometimes_nan)
    result = train(
        scene_dir, tmp_path / "a", _tiny_config(iterations=10), progress=False, log=lambda *_: None
    )
    assert result.rejected_steps == 2

    def always_nan(*args, **kwargs):
        terms = real_loss(*args, **kwargs)
        terms.total = terms.total * float("nan")
        return terms

    monkeypatch.setattr(trainer_module, "training_loss", always_nan)
    with pytest.raises(TrainingDivergedError, match="non-finite"):
        train(scene_dir, tmp_path / "b", _tiny_config(iterations=40, max_rejected_steps=5), progress=False,
              log=lambda *_: None)  # fmt: skip


def test_lts_train_cli_summary_and_clear_errors(scene_dir, tmp_path, lts_cli):
    run = tmp_path / "run"
    args = ["train", scene_dir, "--out", run, "--preset", "fast", "--iterations", 20, "--no-progress"]
    code, out, err = lts_cli(*args, "--json")
    assert code == 0, err
    summary = json.loads(out.strip().splitlines()[-1])
    assert summary["iterations"] == 20 and summary["n_triangles"] > 0 and "test_psnr" in summary["test"]
    # 64x48 views: a half-size start (32x24) would be below coarse_min_side_px, so there is none.
    assert "half resolution" not in " ".join(summary["skips"])
    code, _, err = lts_cli(*args)
    assert code == 2 and "--resume" in err
    code, _, err = lts_cli(*args[:-3], "--iterations", 30, "--resume")
    assert code == 2 and "iterations" in err
    code, _, err = lts_cli("train", tmp_path, "--out", tmp_path / "x")
    assert code == 2 and "scene.json" in err
    code, _, err = lts_cli(
        *args[:3], tmp_path / "full", "--iterations", 20, "--half-resolution", 0, "--no-progress"
    )
    assert code == 0, err
    assert "coarse_until: 0.0" in (tmp_path / "full" / "config.yaml").read_text()
    code, _, err = lts_cli(*args[:3], tmp_path / "y", "--half-resolution", 2)
    assert code == 2 and "--half-resolution" in err
    code, _, err = lts_cli(*args[:3], tmp_path / "z", "--device", "gpu")  # was torch's RuntimeError
    assert code == 2 and "device: expected cpu, cuda or cuda:N, got 'gpu'" in err


def test_learning_rates_100x_too_high_never_leave_a_non_finite_model(scene_dir, tmp_path):
    config = _tiny_config(
        iterations=40, lr_vertices=0.03, lr_colors=2.0, lr_opacity=5.0, max_rejected_steps=5
    )
    try:
        result = train(scene_dir, tmp_path / "run", config, progress=False, log=lambda *_: None)
    except TrainingDivergedError:
        return  # stopped with a clear error: acceptable
    model = load_model(tmp_path / "run" / "model.pt")
    assert all(bool(torch.isfinite(p).all()) for p in model.params.values())
    assert np.isfinite(result.test["test_psnr"])


def test_a_full_disk_during_export_leaves_no_partial_file(scene_dir, tmp_path):
    import subprocess

    model = TriangleModel.from_triangles(
        torch.as_tensor(
            decouple_and_scale(corner_mesh(40).vertices, corner_mesh(40).faces, 2.0), dtype=torch.float32
        ),
        torch.full((2 * 2 * 40 * 40, 3, 3), 0.5),
        0.9,
    )
    disk = tmp_path / "tiny"
    disk.mkdir()
    mounted = subprocess.run(
        ["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", str(disk)], capture_output=True
    )
    if mounted.returncode != 0:
        pytest.skip(f"cannot mount a 64 KB tmpfs here ({mounted.stderr.decode().strip()}): not root?")
    try:
        from splat.export import export_mesh

        with pytest.raises(OSError):
            export_mesh(model, disk)
        assert not list(disk.glob("*.tmp"))  # the partial file was removed
    finally:
        subprocess.run(["umount", "-l", str(disk)], capture_output=True)


def test_masked_pixels_give_the_photometric_loss_no_gradient():
    from splat.losses import training_loss

    rendered = torch.rand(16, 24, 3, requires_grad=True)
    target = torch.rand(16, 24, 3)
    mask = torch.zeros(16, 24, dtype=torch.bool)
    mask[2:14, 2:22] = True
    out = SimpleNamespace(rgb=rendered, max_weight=torch.zeros(1), distortion=torch.zeros(1))
    config = make_config("ours", "default", w_opacity=0.0, w_distortion=0.0)
    terms = training_loss(out, target, None, None, torch.zeros(0), config, moving_mask=mask)
    terms.total.backward()
    assert float(terms.l1.detach()) == pytest.approx(float((rendered - target).detach().abs()[~mask].mean()))
    # D-SSIM's 11x11 window reaches 5 pixels into the mask: its centre gets no gradient at all.
    assert rendered.grad[7:9, 11:13].abs().max() == 0
    assert rendered.grad[~mask].abs().sum() > 0
    unmasked = training_loss(out, target, None, None, torch.zeros(0), config)
    assert float(unmasked.l1.detach()) == pytest.approx(float((rendered - target).detach().abs().mean()))


def test_a_keyframe_with_moving_points_has_a_mask_around_them(scene_dir, tmp_path):
    import shutil

    from slam_bridge.scene import MOVING_DIR, MOVING_TOP_DIR, load_scene

    root = tmp_path / "scene"
    shutil.copytree(scene_dir, root)
    scene = load_scene(root)
    first, second = scene.keyframes[:2]
    (root / MOVING_DIR).mkdir()
    centre = CAMERA.unproject(np.array([[CAMERA.width / 2, CAMERA.height / 2]]), 2.0).astype(np.float32)
    np.save(root / MOVING_DIR / f"{first.name}.npy", centre)
    mask = scene.moving_mask(first)
    assert mask.shape == (CAMERA.height, CAMERA.width) and mask[CAMERA.height // 2, CAMERA.width // 2]
    assert 0 < mask.sum() < 0.1 * mask.size
    assert scene.moving_mask(second) is None
    views = load_views(scene, scene.keyframes[:2])
    assert views[0].moving_mask is not None and views[1].moving_mask is None
    # Where the point is at the top of the LiDAR's field, the mask also reaches up its column.
    (root / MOVING_TOP_DIR).mkdir()
    np.save(root / MOVING_TOP_DIR / f"{first.name}.npy", centre)
    cut = scene.moving_mask(first)
    assert (cut >= mask).all() and cut[: CAMERA.height // 2, CAMERA.width // 2].all()


def test_far_returns_count_their_depth_error_relative_to_their_range():
    from splat.losses import accumulated_depth_l1

    lidar = torch.tensor([[4.0, 40.0, 0.0]])
    out = SimpleNamespace(accumulated_depth=torch.tensor([[4.1, 41.0, 7.0]]))  # no return: no error
    assert float(accumulated_depth_l1(out, lidar)) == pytest.approx((0.1 + 1.0) / 2)
    assert float(accumulated_depth_l1(out, lidar, reference_m=8.0)) == pytest.approx((0.1 + 1.0 / 5) / 2)


def test_a_mesh_of_many_times_the_faces_wanted_is_clustered_before_decimation():
    import splat.init_mesh as init_mesh

    mesh = corner_mesh(60)  # 14 400 faces: more than 20 times the 500 wanted
    small = init_mesh.simplify(mesh, 500)
    assert 0 < len(small.faces) <= 500
    assert abs(small.area - mesh.area) < 0.05 * mesh.area
