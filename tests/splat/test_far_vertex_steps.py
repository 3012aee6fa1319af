import torch

from splat.far_vertex_steps import FarVertexSteps, distance_scale


def _triangle_at(distance_m: float) -> torch.Tensor:
    """``(3, 3)``: a small triangle centred ``distance_m`` along x."""
    return torch.tensor([[distance_m, 0.0, 0.1], [distance_m, 0.1, -0.1], [distance_m, -0.1, -0.1]])


def _all(triangles: torch.Tensor) -> torch.Tensor:
    return torch.ones(len(triangles), dtype=torch.bool)


def test_distance_scale_grows_beyond_the_range_only():
    triangles = torch.stack([_triangle_at(2.0), _triangle_at(8.0), _triangle_at(24.0), _triangle_at(-40.0)])
    cameras = torch.tensor([[0.0, 0.0, 0.0], [-10.0, 0.0, 0.0]])
    scale = distance_scale(triangles, cameras, range_m=8.0)
    # The nearest camera counts: the triangle at -40 m lies 30 m from the second one.
    torch.testing.assert_close(scale, torch.tensor([1.0, 1.0, 3.0, 3.75]))


def test_step_scales_each_triangles_move_and_follows_a_replaced_tensor():
    cameras = torch.zeros(1, 3)
    vertices = torch.stack([_triangle_at(4.0), _triangle_at(16.0)]).requires_grad_(True)
    start = vertices.detach().clone()
    steps = FarVertexSteps(cameras, range_m=8.0, camera_only=_all)

    def add(tensor: torch.Tensor) -> None:
        with torch.no_grad():
            tensor.add_(0.01)

    steps.step(vertices, lambda: add(vertices))
    # The near triangle's step is the optimiser's, to the bit; the far one's twice as long.
    assert torch.equal(vertices.detach()[0], start[0] + 0.01)
    torch.testing.assert_close(vertices.detach()[1] - start[1], torch.full((3, 3), 0.02))

    # Densification replaces the parameter: its rows get their own scale.
    replaced = torch.stack([_triangle_at(32.0)]).requires_grad_(True)
    steps.step(replaced, lambda: add(replaced))
    torch.testing.assert_close(replaced.detach()[0, 0, 0], torch.tensor(32.04))


def test_triangles_a_lidar_return_backs_keep_the_optimisers_step():
    vertices = torch.stack([_triangle_at(24.0), _triangle_at(24.0)]).requires_grad_(True)
    start = vertices.detach().clone()
    steps = FarVertexSteps(torch.zeros(1, 3), range_m=8.0, camera_only=lambda _: torch.tensor([True, False]))

    def add() -> None:
        with torch.no_grad():
            vertices.add_(0.01)

    steps.step(vertices, add)
    torch.testing.assert_close(vertices.detach()[0] - start[0], torch.full((3, 3), 0.03))
    assert torch.equal(vertices.detach()[1], start[1] + 0.01)
