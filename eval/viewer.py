"""``lts view``: a training run in a browser through viser — the exported mesh (photo colours or
the distance to the ground truth), the raw triangles with their opacity, the ground truth, the
keyframe cameras with their images, the trajectory and one keyframe's LiDAR points; beside them
the model's render of the browser's viewpoint and the nearest captured image.

Viser's cameras follow OpenCV's axes (x right, y down, z forward), as the scene's ``T_world_cam``
do, so keyframe poses are used as they are.
"""

from __future__ import annotations

import math

import numpy as np
import viser
import viser.transforms as vtf

from eval.viewer_data import ViewerData
from eval.viewer_layers import (
    ERROR_SCALE,
    colorbar,
    colored_mesh,
    error_colors,
    lidar_points,
    mesh_colors,
    nearest_keyframe,
    scene_extent,
    thumbnail,
    trajectory_segments,
    triangle_soup,
)
from eval.viewer_render import ViewRenderer

FRUSTUM_THUMBNAIL_PX = 128
TRAIN_COLOR = (40, 110, 230)
TEST_COLOR = (240, 130, 20)
SELECTED_COLOR = (230, 30, 60)
GT_COLOR = (200, 200, 200)
MESH_PHOTO, MESH_ERROR, MESH_HIDDEN = "photo colours", "distance to ground truth", "hidden"


def _pose(T_world_cam: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(wxyz (4,), position (3,))`` of a camera-to-world pose ``(4, 4)``."""
    return vtf.SO3.from_matrix(T_world_cam[:3, :3]).wxyz, T_world_cam[:3, 3]


def _client_pose(camera: viser.CameraHandle) -> np.ndarray:
    """The ``(4, 4)`` camera-to-world pose of a browser's viewpoint."""
    T = np.eye(4)
    T[:3, :3] = vtf.SO3(np.asarray(camera.wxyz)).as_matrix()
    T[:3, 3] = camera.position
    return T


class Viewer:
    """The viser server of one run: scene layers, the shared controls and a render panel per
    browser. :meth:`stop` ends the server and the render thread."""

    def __init__(self, data: ViewerData, host: str, port: int, render_width: int = 320) -> None:
        self.data = data
        self.scene = data.scene
        self.keyframes = sorted(self.scene.keyframes, key=lambda k: k.t_ns)
        self.poses = np.stack([k.T_world_cam for k in self.keyframes])
        self.extent = scene_extent(self.scene, data.mesh)
        self.renderer = ViewRenderer(data.model, self.scene, render_width)
        self._images: dict[int, np.ndarray] = {}
        self.server = viser.ViserServer(host=host, port=port, verbose=False)
        self.server.scene.set_up_direction(data.up)
        self._set_initial_camera()
        self._add_meshes()
        self._add_cameras()
        self._add_keyframe_controls()
        self.server.on_client_connect(self._on_connect)
        self.server.on_client_disconnect(lambda client: self.renderer.forget(client.client_id))

    @property
    def port(self) -> int:
        """The port the server listens on (viser takes the next free one when the asked is busy)."""
        return self.server.get_port()

    def stop(self) -> None:
        """Stop the render thread and the server."""
        self.renderer.stop()
        self.server.stop()

    def _set_initial_camera(self) -> None:
        """Behind and above the first keyframe, looking where it looks, with its field of view."""
        first = self.poses[0]
        forward, up = first[:3, 2], self.data.up
        back = 0.15 * self.extent
        camera = self.server.initial_camera
        camera.position = first[:3, 3] - back * forward + 0.5 * back * up
        camera.look_at = first[:3, 3] + back * forward
        camera.up = up
        camera.fov = 2 * math.atan(self.scene.camera.height / (2 * self.scene.camera.fy))

    def _add_meshes(self) -> None:
        scene, gui, data = self.server.scene, self.server.gui, self.data
        truth = data.truth
        if truth is not None:
            self._add_error_legend()
        with gui.add_folder("Layers"):
            if data.mesh is not None:
                vertices, faces = np.asarray(data.mesh.vertices), np.asarray(data.mesh.faces)
                meshes = {MESH_PHOTO: colored_mesh(vertices, faces, mesh_colors(data.mesh))}
                if truth is not None:
                    colors = error_colors(truth.mesh_distance, truth.threshold_m)
                    meshes[MESH_ERROR] = colored_mesh(vertices, faces, colors)
                initial = MESH_ERROR if truth is not None else MESH_PHOTO
                handles = {
                    name: scene.add_mesh_trimesh(f"/mesh/{i}", mesh, visible=name == initial)
                    for i, (name, mesh) in enumerate(meshes.items())
                }
                choice = gui.add_dropdown("mesh.ply", [*meshes, MESH_HIDDEN], initial_value=initial)

                @choice.on_update
                def _(_) -> None:
                    for name, handle in handles.items():
                        handle.visible = name == choice.value

            soup = scene.add_mesh_trimesh("/triangles", triangle_soup(data.model), visible=data.mesh is None)
            self._toggle("raw triangles (opacity)", soup)
            if truth is not None:
                gt = scene.add_mesh_simple(
                    "/ground_truth",
                    np.asarray(truth.mesh.vertices),
                    np.asarray(truth.mesh.faces),
                    color=GT_COLOR,
                    opacity=0.35,
                    side="double",
                    visible=False,
                )
                self._toggle("ground truth", gt)

    def _add_error_legend(self) -> None:
        truth, gui = self.data.truth, self.server.gui
        assert truth is not None
        cm = 100 * truth.threshold_m
        how = "aligned by its camera trajectory" if truth.aligned else "taken as in the scene frame"
        with gui.add_folder("Ground truth"):
            gui.add_markdown(
                f"**F-score at {cm:g} cm: {truth.fscore:.3f}** (both meshes culled to the training "
                f"frusta, as `lts eval`)  \nground truth {how}"
            )
            gui.add_image(colorbar(), label="distance of mesh.ply to the ground truth", format="png")
            gui.add_markdown(f"0 cm → {cm:g} cm (middle) → ≥ {ERROR_SCALE * cm:g} cm")

    def _toggle(self, label: str, *handles: viser.SceneNodeHandle) -> None:
        """A checkbox that shows or hides ``handles`` (checked when the first is visible)."""
        box = self.server.gui.add_checkbox(label, handles[0].visible)

        @box.on_update
        def _(_) -> None:
            for handle in handles:
                handle.visible = box.value

    def _add_cameras(self) -> None:
        scene, camera = self.server.scene, self.scene.camera
        fov = 2 * math.atan(camera.height / (2 * camera.fy))
        scale = 0.012 * self.extent
        self.frustums = []
        for index, keyframe in enumerate(self.keyframes):
            wxyz, position = _pose(keyframe.T_world_cam)
            frustum = scene.add_camera_frustum(
                f"/keyframes/{keyframe.name}",
                fov,
                camera.width / camera.height,
                scale=scale,
                thickness=2.0,
                thickness_units="screen",
                color=TRAIN_COLOR if keyframe.split == "train" else TEST_COLOR,
                image=thumbnail(self.scene.image(keyframe), FRUSTUM_THUMBNAIL_PX),
                wxyz=wxyz,
                position=position,
            )
            frustum.on_click(lambda _, index=index: setattr(self.slider, "value", index))
            self.frustums.append(frustum)
        trajectory = scene.add_line_segments(
            "/trajectory",
            trajectory_segments(self.scene),
            colors=(250, 200, 0),
            thickness=3.0,
            thickness_units="screen",
        )
        self.lidar = scene.add_point_cloud(
            "/lidar", np.zeros((1, 3)), (0, 0, 0), point_size=0.0015 * self.extent, visible=False
        )
        with self.server.gui.add_folder("Cameras"):
            self._toggle("keyframes (blue train, orange test)", *self.frustums)
            self._toggle("trajectory", trajectory)

    def _add_keyframe_controls(self) -> None:
        gui = self.server.gui
        with gui.add_folder("Keyframe"):
            self.slider = gui.add_slider("keyframe", 0, len(self.keyframes) - 1, 1, 0)
            label = gui.add_markdown("")
            show_lidar = gui.add_checkbox("its LiDAR points", True)
            go = gui.add_button("view from this keyframe")

        def select(_=None) -> None:
            keyframe = self.keyframes[self.slider.value]
            label.content = f"`{keyframe.name}` ({keyframe.split})"
            points, colors = lidar_points(self.scene, keyframe)
            self.lidar.points, self.lidar.colors = points.astype(np.float32), colors
            self.lidar.visible = show_lidar.value and len(points) > 0
            for index, frustum in enumerate(self.frustums):
                selected = index == self.slider.value
                frustum.color = SELECTED_COLOR if selected else (
                    TRAIN_COLOR if self.keyframes[index].split == "train" else TEST_COLOR
                )  # fmt: skip

        @go.on_click
        def _(event: viser.GuiEvent) -> None:
            if event.client is None:
                return
            wxyz, position = _pose(self.poses[self.slider.value])
            with event.client.atomic():
                event.client.camera.position = position
                event.client.camera.wxyz = wxyz

        self.slider.on_update(select)
        show_lidar.on_update(select)
        select()

    def _captured(self, index: int) -> np.ndarray:
        """Keyframe ``index``'s image at the render size (read once)."""
        if index not in self._images:
            image = self.scene.image(self.keyframes[index])
            self._images[index] = thumbnail(image, self.renderer.camera.width)
        return self._images[index]

    def _on_connect(self, client: viser.ClientHandle) -> None:
        """The browser's render panel, refreshed whenever its camera moves."""
        blank = np.zeros((self.renderer.camera.height, self.renderer.camera.width, 3), dtype=np.uint8)
        with client.gui.add_folder("Current view", order=-1.0):  # above the shared controls
            render = client.gui.add_image(blank, label="model render (this viewpoint)")
            captured = client.gui.add_image(blank, label="nearest captured image")
            caption = client.gui.add_markdown("")

        def deliver(T_world_cam: np.ndarray, rgb: np.ndarray) -> None:
            index = nearest_keyframe(self.poses, T_world_cam)
            distance = np.linalg.norm(self.poses[index, :3, 3] - T_world_cam[:3, 3])
            with client.atomic():
                render.image = rgb
                captured.image = self._captured(index)
                caption.content = f"nearest keyframe `{self.keyframes[index].name}`, {distance:.2f} m away"

        @client.camera.on_update
        def _(camera: viser.CameraHandle) -> None:
            T = _client_pose(camera)
            self.renderer.request(client.client_id, T, lambda rgb: deliver(T, rgb))
