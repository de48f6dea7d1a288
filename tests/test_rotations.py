import pytest
import roma
import torch

from mrlib.representation.rotations import (
    axis_angle_to_6d,
    axis_angle_to_matrix,
    geodesic_distance,
    matrix_to_6d,
    matrix_to_axis_angle,
    sixd_to_axis_angle,
    sixd_to_matrix,
)

torch.manual_seed(0)


def test_6d_is_first_two_columns():
    R = roma.random_rotmat(5)
    x = matrix_to_6d(R)
    assert torch.allclose(x[:, :3], R[:, :, 0]) and torch.allclose(x[:, 3:], R[:, :, 1])


def test_round_trips_batched():
    aa = roma.random_rotvec((7, 24)).double()  # any leading batch dims
    R = axis_angle_to_matrix(aa)
    assert R.shape == (7, 24, 3, 3)
    assert geodesic_distance(sixd_to_matrix(matrix_to_6d(R)), R).max() < 1e-10
    assert (
        geodesic_distance(axis_angle_to_matrix(sixd_to_axis_angle(axis_angle_to_6d(aa))), R).max()
        < 1e-10
    )
    assert geodesic_distance(axis_angle_to_matrix(matrix_to_axis_angle(R)), R).max() < 1e-10


def test_any_6d_vector_maps_to_a_rotation():
    R = sixd_to_matrix(torch.randn(100, 6))
    eye = torch.eye(3).expand(100, 3, 3)
    assert torch.allclose(R.transpose(-1, -2) @ R, eye, atol=1e-5)
    assert torch.allclose(torch.linalg.det(R), torch.ones(100), atol=1e-5)


def test_gradients_flow_through_6d():
    x = torch.randn(4, 6, requires_grad=True)
    sixd_to_axis_angle(x).sum().backward()
    assert torch.isfinite(x.grad).all()


def test_device_follows_input():
    aa = torch.zeros(2, 3)
    assert axis_angle_to_6d(aa).device == aa.device


@pytest.mark.parametrize("dtype, tol", [(torch.float64, 1e-12), (torch.float32, 2e-6)])
def test_matrix_to_axis_angle_closed_form_agrees_with_roma_everywhere(dtype, tol):
    """The closed form (angles up to 3 rad) and roma's route (near a half turn) meet."""
    import roma

    from mrlib.representation.rotations import matrix_to_axis_angle

    g = torch.Generator().manual_seed(0)
    axis = torch.nn.functional.normalize(torch.randn(6000, 3, generator=g, dtype=dtype), dim=-1)
    angle = torch.cat(
        [
            torch.rand(3000, generator=g, dtype=dtype) * torch.pi,  # anywhere
            torch.pi - torch.rand(1000, generator=g, dtype=dtype) * 0.3,  # about the switch
            torch.full((1000,), 3.0, dtype=dtype),  # at it
            torch.rand(1000, generator=g, dtype=dtype) * 1e-7,  # tiny
        ]
    )
    aa = axis * angle[:, None]
    R = roma.rotvec_to_rotmat(aa)
    ours = matrix_to_axis_angle(R)
    assert (roma.rotvec_to_rotmat(ours) - R).abs().max() < tol
    assert (ours - roma.rotmat_to_rotvec(R)).abs().max() < tol
    assert torch.equal(matrix_to_axis_angle(torch.eye(3, dtype=dtype)), torch.zeros(3, dtype=dtype))
