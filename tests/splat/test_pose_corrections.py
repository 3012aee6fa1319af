"""Per-keyframe pose corrections learnt with the triangles: the correction, its gradient through the
rasteriser, and a training run that undoes known pose errors."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch
from scipy.spatial.transform import Rotation
from training_scene import CAMERA, corner_mesh, write_training_scene

from rig.errors import InputError
from rig.trajectory_io import read_tum
from rig.transforms import invert
from slam_bridge.scene import Keyframe
from splat.config import make_config
from splat.model import TriangleModel
from splat.pose_corrections import PoseCorrections
from splat.trainer import Trainer, train

QUIET = lambda *_: None  # noqa: E731


def _config(**overrides):
    values = dict(
        iterations=300, densify_every=100, densify_until=0.5, eval_every=100, checkpoint_every=100,
        init_max_triangles=500, ground_fill=False, drop_redundant_keyframes=False, coarse_min_side_px=1,
        learn_poses=True, lr_pose=1e-3,
    )  # fmt: skip
    values.update(overrides)
    return make_config("ours", "default", **values)


def _turn_and_move(deg: float, cm: float, seed: int) -> np.ndarray:
    """``(4, 4)`` a turn of ``deg`` about a random axis and a move of ``cm`` in a random direction."""
    axis, direction = np.random.default_rng(seed).normal(size=(2, 3))
    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec(np.radians(deg) * axis / np.linalg.norm(axis)).as_matrix()
    T[:3, 3] = cm / 100 * direction / np.linalg.norm(direction)
    return T


def _pose_errors(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(N,)`` rotation (degrees) and centre distance (metres) between camera poses ``(N, 4, 4)``."""
    R = np.einsum("nji,njk->nik", a[:, :3, :3], b[:, :3, :3])
    degrees = np.degrees(np.arccos(np.clip((np.trace(R, axis1=1, axis2=2) - 1) / 2, -1, 1)))
    return degrees, np.linalg.norm(a[:, :3, 3] - b[:, :3, 3], axis=1)


def _params(C: np.ndarray) -> np.ndarray:
    """``(6,)`` a rigid transform ``(4, 4)`` as a rotation vector and a translation."""
    return np.concatenate([Rotation.from_matrix(C[:3, :3]).as_rotvec(), C[:3, 3]])


def test_a_zero_correction_is_the_pose_and_a_correction_moves_the_camera_by_its_size():
    T_cam_world = torch.as_tensor(invert(_turn_and_move(20.0, 80.0, 1)), dtype=torch.float32)
    zero = PoseCorrections.zeros(T_cam_world.expand(3, 4, 4))
    assert torch.equal(zero.corrected(1), T_cam_world)
    assert float(zero.prior(0, 0.1).detach()) == 0.0

    C = _turn_and_move(0.7, 2.5, 2)
    params = torch.zeros(3, 6)
    params[2] = torch.as_tensor(_params(C))
    poses = PoseCorrections(params, T_cam_world.expand(3, 4, 4))
    expected = torch.as_tensor(C, dtype=torch.float32) @ T_cam_world
    torch.testing.assert_close(poses.corrected(2), expected)
    degrees, metres = poses.sizes()
    np.testing.assert_allclose(degrees, [0, 0, 0.7], atol=1e-3)  # float32 corrections
    np.testing.assert_allclose(metres, [0, 0, 0.025], atol=1e-7)
    keyframes = [Keyframe(f"k{i}", i, invert(T_cam_world.double().numpy()), "train") for i in range(3)]
    moved = poses.corrected_keyframes(keyframes)
    np.testing.assert_allclose(invert(moved[2].T_world_cam), C @ T_cam_world.double().numpy(), atol=1e-6)
    np.testing.assert_allclose(moved[0].T_world_cam, keyframes[0].T_world_cam, atol=1e-12)
    p = params[2]
    assert float(poses.prior(2, 0.1).detach()) == pytest.approx(
        float(p[:3].square().sum() + (p[3:] / 0.1).square().sum())
    )
    summary = poses.summary()
    assert summary["rotation_max_deg"] == pytest.approx(0.7, abs=1e-3)
    assert summary["translation_max_cm"] == pytest.approx(2.5, abs=1e-3)
    with pytest.raises(ValueError, match=r"\(V, 6\)"):
        PoseCorrections(torch.zeros(3, 7), torch.eye(4).expand(3, 4, 4))
    with pytest.raises(ValueError, match="3 poses"):
        PoseCorrections(torch.zeros(3, 6), torch.eye(4).expand(2, 4, 4))


def test_a_motion_common_to_every_view_is_taken_out_and_the_rest_kept():
    """Corrections that move every camera by one motion of the world (what moving the triangles
    with them would render alike) vanish; corrections that move the world on average by nothing
    stay as they are."""
    T = np.stack([invert(_turn_and_move(40.0, 400.0, 20 + i)) for i in range(6)])  # cameras ~4 m out
    G = _turn_and_move(0.3, 1.5, 3)
    common = np.stack([_params(T_i @ G @ invert(T_i)) for T_i in T])
    poses = PoseCorrections(torch.as_tensor(common), torch.as_tensor(T))
    poses.remove_common_motion()
    assert poses.params.detach().abs().max() < 1e-4  # second order in the 0.3 deg / 1.5 cm motion
    assert poses.params.requires_grad and poses.params.is_leaf

    own = np.stack([_params(_turn_and_move(0.4, 1.0, 40 + i)) for i in range(6)])
    poses = PoseCorrections(torch.as_tensor(common + own), torch.as_tensor(T))
    poses.remove_common_motion()
    again = poses.params.detach().clone()
    poses.remove_common_motion()
    torch.testing.assert_close(poses.params.detach(), again)  # nothing common is left
    degrees, metres = poses.sizes()
    assert 0.1 < degrees.mean() < 0.7 and 0.002 < metres.mean() < 0.03  # the views' own errors remain


def _pixel_shift(T_world_cam: np.ndarray, truth: np.ndarray, points: np.ndarray) -> float:
    """Mean image distance (pixels of :data:`CAMERA`) between ``points`` ``(N, 3)`` seen from
    ``T_world_cam`` and from ``truth`` ``(4, 4)``, over those the true view shows."""

    def pixels(T):
        T_cam_world = invert(T)
        p = points @ T_cam_world[:3, :3].T + T_cam_world[:3, 3]
        return np.column_stack([CAMERA.fx * p[:, 0] / p[:, 2] + CAMERA.cx,
                                CAMERA.fy * p[:, 1] / p[:, 2] + CAMERA.cy]), p[:, 2]  # fmt: skip

    seen, depth = pixels(truth)
    inside = (depth > 0.1) & (seen >= 0).all(axis=1) & (seen < [CAMERA.width, CAMERA.height]).all(axis=1)
    return float(np.linalg.norm(pixels(T_world_cam)[0] - seen, axis=1)[inside].mean())


def test_the_rasterisers_gradient_turns_a_wrong_pose_back_towards_the_true_one():
    """Triangles fixed, a view rendered from its true pose as the target; the same view from a pose
    0.8 deg and 3 cm off, its correction alone optimised: the image shift of the scene shrinks over
    ten times (a turn and a move along the wall trade against each other, so the pose itself is
    held to less: the turn halves, the move shrinks by a quarter)."""
    mesh = corner_mesh(8)
    triangles = torch.as_tensor(np.asarray(mesh.vertices)[np.asarray(mesh.faces)], dtype=torch.float32)
    g = torch.Generator().manual_seed(0)
    model = TriangleModel.from_triangles(triangles, torch.rand(len(triangles), 3, 3, generator=g), 0.9)
    model.sigma = 0.1
    truth = np.eye(4)
    truth[:3, :3] = Rotation.from_euler("x", -110, degrees=True).as_matrix()
    truth[:3, 3] = [0.2, -0.5, 1.2]
    T_true = torch.as_tensor(invert(truth), dtype=torch.float32)
    with torch.no_grad():
        target = model.render(CAMERA, T_true).rgb
    error = _turn_and_move(0.8, 3.0, 5)
    T_wrong = torch.as_tensor(error, dtype=torch.float32) @ T_true  # off in the camera frame
    poses = PoseCorrections.zeros(T_wrong[None])
    optimizer = torch.optim.Adam([poses.params], lr=1e-3)
    # Decayed as training decays it: at a constant rate Adam's steps keep ringing about the minimum
    # (0.01-0.10 px between steps 200 and 300), at the trainer's rate they settle (0.04 px).
    decay = torch.optim.lr_scheduler.ExponentialLR(optimizer, _config().lr_final_factor ** (1 / 300))
    for _ in range(300):
        loss = (model.render(CAMERA, poses.corrected(0)).rgb - target).abs().mean()
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
        decay.step()
    wrong = invert(T_wrong.double().numpy())
    recovered = invert(poses.corrected(0).detach().double().numpy())
    points = np.asarray(mesh.vertices)
    shift_before, shift_after = _pixel_shift(wrong, truth, points), _pixel_shift(recovered, truth, points)
    assert shift_after < shift_before / 10, (shift_before, shift_after)
    before, after = _pose_errors(wrong[None], truth[None]), _pose_errors(recovered[None], truth[None])
    assert after[0][0] < before[0][0] / 2 and after[1][0] < before[1][0] * 0.75, (before, after)


@pytest.fixture(scope="module")
def off_scene(tmp_path_factory):
    """The training corner with its training keyframes' poses 2 deg / 5 cm off (the LiDAR points,
    in the camera frame, move with them: a pose error of the whole rig)."""
    root = write_training_scene(tmp_path_factory.mktemp("off"))
    index = json.loads((root / "scene.json").read_text())
    for i, k in enumerate(index["keyframes"]):
        if k["split"] == "train":
            error = invert(_turn_and_move(2.0, 5.0, 10 + i))
            k["T_world_cam"] = (np.array(k["T_world_cam"]) @ error).tolist()
    (root / "scene.json").write_text(json.dumps(index))
    return root


def test_training_learns_corrections_without_a_common_motion_and_writes_the_corrected_keyframes(
    off_scene, tmp_path
):
    """The run's corrections move the keyframes (the corner's 64x48 views are too coarse to say by
    how much they get right: the rasteriser test above and docs/training.md measure that), keep no
    motion common to all views, and come out as the summary and ``keyframe_poses.tum``."""
    root = off_scene
    trainer = Trainer(root, tmp_path / "run", _config(iterations=60, eval_every=20), QUIET)
    trainer.prepare(resume=False)
    result = trainer.run(progress=False)
    poses = trainer.poses
    assert result.poses["rotation_max_deg"] > 0.01 and result.poses["translation_max_cm"] > 0.01
    assert json.loads((tmp_path / "run" / "summary.json").read_text())["poses"] == result.poses
    learnt = poses.params.detach().clone()
    poses.remove_common_motion()
    torch.testing.assert_close(poses.params.detach(), learnt, atol=1e-6, rtol=0)
    trajectory = read_tum(tmp_path / "run" / "keyframe_poses.tum")
    keyframes = sorted(poses.corrected_keyframes(trainer.train_keyframes), key=lambda k: k.t_ns)
    assert list(trajectory.t_ns) == [k.t_ns for k in keyframes]
    np.testing.assert_allclose(trajectory.rotations, [k.T_world_cam[:3, :3] for k in keyframes], atol=1e-6)
    np.testing.assert_allclose(trajectory.translations, [k.T_world_cam[:3, 3] for k in keyframes], atol=1e-6)
    plain = train(
        root, tmp_path / "plain", _config(iterations=20, learn_poses=False), progress=False, log=QUIET
    )
    assert plain.poses == {} and not (tmp_path / "plain" / "keyframe_poses.tum").exists()


def test_resume_keeps_the_corrections_and_a_run_without_them_names_the_file(off_scene, tmp_path, monkeypatch):
    root = off_scene
    config = _config(iterations=40, eval_every=20, checkpoint_every=20)
    whole = Trainer(root, tmp_path / "whole", config, QUIET)
    whole.prepare(resume=False)
    whole.run(progress=False)

    class KilledError(Exception):
        pass

    original = Trainer._step

    def dying_step(self, it):
        if it == 27:  # after the checkpoint at 20
            raise KilledError
        return original(self, it)

    monkeypatch.setattr(Trainer, "_step", dying_step)
    with pytest.raises(KilledError):
        train(root, tmp_path / "killed", config, progress=False, log=QUIET)
    monkeypatch.setattr(Trainer, "_step", original)
    resumed = Trainer(root, tmp_path / "killed", config, QUIET)
    resumed.prepare(resume=True)
    resumed.run(progress=False)
    assert torch.equal(whole.poses.params, resumed.poses.params)
    assert whole.poses.params.abs().max() > 0

    plain = _config(iterations=20, learn_poses=False)
    run = tmp_path / "plain"
    trainer = Trainer(root, run, plain, QUIET)
    trainer.prepare(resume=False)
    trainer.save_checkpoint()
    (run / "config.yaml").write_text(_config(iterations=20).to_yaml())  # as if it had learnt poses
    with pytest.raises(InputError, match="pose corrections of 5 training views") as error:
        Trainer(root, run, _config(iterations=20), QUIET).prepare(resume=True)
    assert "last.pt" in str(error.value)
