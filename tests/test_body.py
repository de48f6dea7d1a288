"""Tests for mrlib.representation.body: the default body, the fast forward, chumpy-free SMPL loading."""

from __future__ import annotations

import os
import pickle
import sys
import types

import numpy as np
import pytest
import torch

from mrlib.errors import BodyModelError
from mrlib.representation.body import BodyModel, default_body_path, load_body_model
from mrlib.representation.motion import Motion
from mrlib.representation.rotations import axis_angle_to_matrix
from mrlib.representation.skeleton import JOINT_NAMES, PARENTS, SMPL_FOOT_VERTEX_IDS
from mrlib.representation.smpl_files import read_smpl_arrays

KEYS = ("v_template", "f", "shapedirs", "posedirs", "J_regressor", "kintree_table", "weights")


@pytest.fixture(scope="module")
def body() -> BodyModel:
    return load_body_model()


@pytest.fixture(scope="module")
def default_arrays() -> dict[str, np.ndarray]:
    with np.load(default_body_path(), allow_pickle=False) as z:
        return {k: z[k] for k in z.files}


def random_rotmats(*lead: int, scale: float = 0.4, seed: int = 0) -> torch.Tensor:
    g = torch.Generator().manual_seed(seed)
    return axis_angle_to_matrix(torch.randn(*lead, 24, 3, generator=g) * scale)


def smplx_reference(body: BodyModel, R, trans, betas):
    """Vertices and the first 24 joints from smplx.SMPL.forward itself."""
    lead = R.shape[:-3]
    N = int(np.prod(lead))
    RN = R.reshape(N, 24, 3, 3)
    b = torch.as_tensor(betas, dtype=torch.float32).expand(*lead, body.num_betas).reshape(N, -1)
    out = body.smpl(
        betas=b,
        global_orient=RN[:, :1],
        body_pose=RN[:, 1:],
        transl=trans.reshape(N, 3),
        pose2rot=False,
    )
    return out.vertices.reshape(*lead, -1, 3), out.joints[:, :24].reshape(*lead, 24, 3)


# -- the embedded default body ---------------------------------------------------------
def test_default_body_file_is_small_and_plain(default_arrays):
    assert default_body_path().stat().st_size < 1_000_000
    for k in (*KEYS, "vertex_ids", "joint_names", "license", "source"):
        assert k in default_arrays, k
    assert tuple(default_arrays["joint_names"]) == JOINT_NAMES
    assert "CC0" in str(default_arrays["license"])


def test_default_body_loads_with_sane_attributes(body):
    assert body.name == "default"
    assert 3000 < body.num_vertices < 20000
    assert body.faces.dtype == np.int64 and body.faces.shape[1] == 3
    assert body.faces.max() < body.num_vertices
    assert len(body.foot_vertex_ids) == 6
    assert body.parents == PARENTS and body.joint_names == JOINT_NAMES
    assert body.num_betas == 10
    assert "CC0" in body.license
    assert list(body.parameters()) == []  # no stray learnable smplx parameters


def test_default_body_rig_arrays_are_valid(body):
    W = body.smpl.lbs_weights
    assert torch.allclose(W.sum(1), torch.ones(body.num_vertices), atol=1e-5)
    assert (W >= 0).all()
    R = body.smpl.J_regressor
    assert (R >= 0).all()
    assert torch.allclose(R.sum(1), torch.ones(24), atol=1e-5)


def test_default_body_rest_pose_is_smpl_like_t_pose(body):
    J = body.rest_joints().numpy()
    v = body.rest_vertices().numpy()
    name = {n: i for i, n in enumerate(JOINT_NAMES)}
    stature = v[:, 1].max() - v[:, 1].min()
    assert 1.55 < stature < 1.85
    assert J[name["head"], 1] > J[name["pelvis"], 1] > J[name["left_knee"], 1]  # Y up
    assert J[name["left_hip"], 0] > 0 > J[name["right_hip"], 0]  # left is +X
    assert J[name["left_foot"], 2] > J[name["left_ankle"], 2]  # toes point +Z
    for side in ("left", "right"):  # arms horizontal, straight out along X
        arm = J[name[f"{side}_wrist"]] - J[name[f"{side}_shoulder"]]
        assert abs(arm[1]) < 0.02 * np.linalg.norm(arm) + 1e-3
        assert abs(arm[0]) > 0.95 * np.linalg.norm(arm)
    # the contact vertices are on the soles, toes ahead of heels
    feet = v[list(body.foot_vertex_ids)]
    assert (feet[:, 1] < v[:, 1].min() + 0.03).all()
    assert feet[0, 2] > feet[2, 2] and feet[3, 2] > feet[5, 2]
    assert (feet[:3, 0] > 0).all() and (feet[3:, 0] < 0).all()


def test_default_body_shape_directions_do_what_they_say(body):
    names = body.beta_names
    assert names is not None and len(names) == body.num_betas
    v0 = body.rest_vertices().numpy()
    for i, n in enumerate(names):
        b = np.zeros(body.num_betas, np.float32)
        b[i] = 1.0
        disp = np.abs(body.rest_vertices(b).numpy() - v0).max()
        assert disp > 0.005, n  # every direction changes the body visibly
    tall = np.eye(body.num_betas, dtype=np.float32)[names.index("height")]
    stature = lambda v: v[:, 1].max() - v[:, 1].min()
    assert stature(body.rest_vertices(2 * tall).numpy()) > stature(v0) + 0.1
    arm = np.eye(body.num_betas, dtype=np.float32)[names.index("upper_arm_length")]
    J0, J1 = body.rest_joints().numpy(), body.rest_joints(arm).numpy()
    bone = lambda J: np.linalg.norm(J[18] - J[16])
    assert bone(J1) > bone(J0) + 0.005


# -- the fast forward against smplx ---------------------------------------------------------
@pytest.mark.parametrize("per_item_betas", [False, True])
def test_forward_matches_smplx(body, per_item_betas):
    R = random_rotmats(2, 3)
    g = torch.Generator().manual_seed(1)
    trans = torch.randn(2, 3, 3, generator=g)
    betas = torch.randn(2, 3, 10, generator=g) if per_item_betas else torch.randn(10, generator=g)
    ref_v, ref_j = smplx_reference(body, R, trans, betas)
    out = body(R, trans, betas, vertex_ids="all")
    assert out.vertices.shape == (2, 3, body.num_vertices, 3)
    torch.testing.assert_close(out.vertices, ref_v, atol=1e-5, rtol=0)
    torch.testing.assert_close(out.joints, ref_j, atol=1e-5, rtol=0)
    ids = [5, 100, *body.foot_vertex_ids]
    sub = body(R, trans, betas, vertex_ids=ids)
    assert sub.vertices.shape == (2, 3, len(ids), 3)
    torch.testing.assert_close(sub.vertices, ref_v[..., ids, :], atol=1e-5, rtol=0)
    assert body(R, trans, betas).vertices is None


def test_forward_with_pose_blendshapes_matches_smplx(default_arrays, tmp_path):
    """A model with non-zero posedirs (like real SMPL) exercises the corrective path."""
    a = dict(default_arrays)
    rng = np.random.default_rng(0)
    a["posedirs"] = (rng.standard_normal(a["posedirs"].shape) * 1e-3).astype(np.float32)
    np.savez(tmp_path / "posed.npz", **a)
    model = load_body_model(tmp_path / "posed.npz")
    assert model.name == "smpl" and model.has_pose_blendshapes
    R = random_rotmats(4, seed=3)
    trans = torch.zeros(4, 3)
    ref_v, ref_j = smplx_reference(model, R, trans, torch.zeros(10))
    torch.testing.assert_close(model(R, trans, vertex_ids="all").vertices, ref_v, atol=1e-5, rtol=0)
    ids = list(model.foot_vertex_ids)
    torch.testing.assert_close(
        model(R, trans, vertex_ids=ids).vertices, ref_v[:, ids], atol=1e-5, rtol=0
    )


def test_rest_joints_equal_identity_pose_joints(body):
    b = torch.randn(10, generator=torch.Generator().manual_seed(2))
    eye = torch.eye(3).expand(24, 3, 3)
    torch.testing.assert_close(body(eye, None, b).joints, body.rest_joints(b))
    assert body.rest_joints(torch.zeros(5, 10)).shape == (5, 24, 3)


def test_forward_is_differentiable(body):
    R = random_rotmats(2, 4).requires_grad_(True)
    trans = torch.zeros(2, 4, 3, requires_grad=True)
    betas = torch.zeros(10, requires_grad=True)
    v = body(R, trans, betas, vertex_ids=body.foot_vertex_ids).vertices
    v.square().sum().backward()
    for t in (R, trans, betas):
        assert t.grad is not None and t.grad.abs().sum() > 0


@pytest.mark.parametrize("shared_rest", [True, False])
def test_rigid_transforms_match_smplx_and_their_gradients_too(body, shared_rest):
    """The depth-by-depth forward kinematics gives smplx's posed joints and skinning
    transforms, and the same gradients (float64, so rounding does not hide a slip)."""
    from smplx.lbs import batch_rigid_transform

    from mrlib.representation.chain import rigid_transforms

    g = torch.Generator().manual_seed(4)
    R = random_rotmats(6, seed=3).double().requires_grad_(True)
    rest = body.rest_joints(torch.randn(1 if shared_rest else 6, 10, generator=g)).double()
    w = torch.randn(6, 24, 3, 4, dtype=torch.float64, generator=g)  # a loss of everything

    joints, G, t = rigid_transforms(R, rest, PARENTS)
    (gr,) = torch.autograd.grad((torch.cat([G, t[..., None]], -1) * w).sum() + joints.sum(), R)
    ref_j, A = batch_rigid_transform(R, rest.expand(6, 24, 3), torch.tensor(PARENTS))
    (ref_gr,) = torch.autograd.grad((A[..., :3, :] * w).sum() + ref_j.sum(), R)
    torch.testing.assert_close(joints, ref_j)
    torch.testing.assert_close(torch.cat([G, t[..., None]], -1), A[..., :3, :])
    torch.testing.assert_close(gr, ref_gr)
    with pytest.raises(ValueError, match="parent"):
        rigid_transforms(R[:, :3], rest[:, :3], (-1, 2, 0))  # a child before its parent


def test_forward_in_float64(body):
    b64 = load_body_model().to(torch.float64)
    R = random_rotmats(3)
    out32 = body(R, vertex_ids="all").vertices
    out64 = b64(R.double(), vertex_ids="all").vertices
    assert out64.dtype == torch.float64
    torch.testing.assert_close(out64.float(), out32, atol=1e-5, rtol=0)


def test_forward_rejects_bad_shapes(body):
    with pytest.raises(BodyModelError, match="rotmat"):
        body(torch.zeros(5, 23, 3, 3))
    with pytest.raises(BodyModelError, match="betas"):
        body(random_rotmats(2), betas=torch.zeros(11))
    with pytest.raises(BodyModelError, match=r"betas\[:, None, :\]"):
        body(random_rotmats(2, 3), betas=torch.zeros(2, 10))  # (B, NB) against (B, T)
    assert body(random_rotmats(2, 3), betas=torch.zeros(2, 1, 10)).joints.shape == (2, 3, 24, 3)
    with pytest.raises(BodyModelError, match="vertex_ids"):
        body(random_rotmats(2), vertex_ids=[body.num_vertices])
    with pytest.raises(BodyModelError, match="vertex_ids"):
        body(random_rotmats(2), vertex_ids="some")


def test_motion_helpers(body):
    T = 6
    g = np.random.default_rng(0)
    motion = Motion(poses=g.normal(0, 0.2, (T, 24, 3)), trans=g.normal(0, 1, (T, 3)), fps=30)
    J = body.motion_joints(motion)
    assert J.shape == (T, 24, 3) and J.dtype == np.float32
    V = body.motion_vertices(motion, frames=[0, 5])
    assert V.shape == (2, body.num_vertices, 3)
    R = axis_angle_to_matrix(torch.from_numpy(motion.poses))
    full = body(R, torch.from_numpy(motion.trans), vertex_ids="all")
    np.testing.assert_allclose(V, full.vertices.numpy()[[0, 5]], atol=1e-5)
    np.testing.assert_allclose(J, full.joints.numpy(), atol=1e-5)


# -- model files: chumpy-free pickles, folders, errors -----------------------------------------
class _FakeCh:
    """Imitates chumpy.ch.Ch for pickling: the value lives in ``x``."""

    def __init__(self, x):
        self.x = x
        self._dirty_vars = set()


def install_fake_chumpy(monkeypatch) -> type:
    """Put a fake ``chumpy.ch`` module in sys.modules (for pickling) and return its Ch."""
    fake_chumpy = types.ModuleType("chumpy")
    fake_ch = types.ModuleType("chumpy.ch")
    fake_ch.Ch = type("Ch", (_FakeCh,), {"__module__": "chumpy.ch"})
    fake_chumpy.ch = fake_ch
    monkeypatch.setitem(sys.modules, "chumpy", fake_chumpy)
    monkeypatch.setitem(sys.modules, "chumpy.ch", fake_ch)
    return fake_ch.Ch


def remove_fake_chumpy(monkeypatch) -> None:
    monkeypatch.delitem(sys.modules, "chumpy")
    monkeypatch.delitem(sys.modules, "chumpy.ch")


def write_fake_smpl_pickle(path, arrays, monkeypatch, protocol):
    """Write ``arrays`` as an SMPL-style pickle: chumpy arrays for the dense buffers and a
    scipy CSC matrix for the joint regressor, like the official downloads."""
    import scipy.sparse

    cls = install_fake_chumpy(monkeypatch)
    data = {
        "v_template": cls(arrays["v_template"].astype(np.float64)),
        "shapedirs": cls(arrays["shapedirs"].astype(np.float64)),
        "posedirs": arrays["posedirs"].astype(np.float64),
        "weights": cls(arrays["weights"].astype(np.float64)),
        "J_regressor": scipy.sparse.csc_matrix(arrays["J_regressor"].astype(np.float64)),
        "kintree_table": np.concatenate([[[4294967295, *PARENTS[1:]]], [np.arange(24)]]).astype(
            np.int64
        ),
        "f": arrays["f"].astype(np.uint32),
        "bs_type": "lrotmin",
        "vertex_ids": arrays["vertex_ids"],
    }
    with open(path, "wb") as fh:
        pickle.dump(data, fh, protocol=protocol)
    remove_fake_chumpy(monkeypatch)


def test_chumpy_pickle_loads_without_chumpy(default_arrays, tmp_path, monkeypatch):
    path = tmp_path / "SMPL_NEUTRAL.pkl"
    write_fake_smpl_pickle(path, default_arrays, monkeypatch, protocol=2)  # as Python 2 wrote
    assert "chumpy" not in sys.modules
    arrays = read_smpl_arrays(path)
    assert "chumpy" not in sys.modules
    for k in ("v_template", "shapedirs", "weights", "J_regressor"):
        assert isinstance(arrays[k], np.ndarray), k
        np.testing.assert_allclose(arrays[k], default_arrays[k], rtol=0, atol=1e-7)
    model = load_body_model(tmp_path)  # a folder with SMPL_NEUTRAL.pkl
    assert model.name == "smpl" and model.num_vertices == default_arrays["v_template"].shape[0]
    assert "SMPL" in model.license
    torch.testing.assert_close(
        model.rest_joints(), load_body_model().rest_joints(), atol=1e-6, rtol=0
    )


def test_protocol0_chumpy_pickle(tmp_path, monkeypatch):
    """Protocol-0 pickles rebuild objects through copyreg._reconstructor."""
    import scipy.sparse

    small = {
        "v_template": np.arange(6.0).reshape(2, 3),
        "shapedirs": np.ones((2, 3, 1)),
        "weights": np.eye(2),
        "J_regressor": np.array([[0.5, 0.5], [0.0, 1.0]]),
        "vertex_ids": np.array([0, 1]),
    }
    Ch = install_fake_chumpy(monkeypatch)
    data = {
        "v_template": Ch(small["v_template"]),
        "shapedirs": Ch(small["shapedirs"]),
        "weights": small["weights"],
        "J_regressor": scipy.sparse.csr_matrix(small["J_regressor"]),
    }
    with open(tmp_path / "m.pkl", "wb") as fh:
        pickle.dump(data, fh, protocol=0)
    remove_fake_chumpy(monkeypatch)
    arrays = read_smpl_arrays(tmp_path / "m.pkl")
    for k in data:
        np.testing.assert_array_equal(arrays[k], small[k])


class _Evil:
    def __init__(self, cmd):
        self.cmd = cmd

    def __reduce__(self):
        return (os.system, (self.cmd,))


class _EvalEvil:
    def __reduce__(self):
        return (eval, ("1 + 1",))


@pytest.mark.parametrize("protocol", [0, 2, 5])
def test_malicious_pickle_is_refused(tmp_path, protocol):
    marker = tmp_path / "pwned"
    path = tmp_path / "SMPL_NEUTRAL.pkl"
    with open(path, "wb") as fh:
        pickle.dump(
            {"v_template": np.zeros((3, 3)), "f": _Evil(f"touch {marker}")}, fh, protocol=protocol
        )
    with pytest.raises(BodyModelError, match="refusing"):
        load_body_model(path)
    assert not marker.exists()
    with open(path, "wb") as fh:
        pickle.dump(_EvalEvil(), fh, protocol=protocol)
    with pytest.raises(BodyModelError, match="refusing.*eval"):
        read_smpl_arrays(path)


def test_smpl_topology_npz_uses_smpl_foot_vertices(tmp_path):
    """An .npz with SMPL's 6890 vertices and no vertex_ids gets SMPL's contact vertices."""
    rng = np.random.default_rng(0)
    V = 6890
    W = rng.random((V, 24))
    Jr = rng.random((24, V))
    arrays = dict(
        v_template=rng.normal(0, 0.3, (V, 3)),
        f=rng.integers(0, V, (100, 3)),
        shapedirs=rng.normal(0, 1e-3, (V, 3, 10)),
        posedirs=np.zeros((V, 3, 207)),
        J_regressor=Jr / Jr.sum(1, keepdims=True),
        kintree_table=np.stack([np.array(PARENTS), np.arange(24)]),
        weights=W / W.sum(1, keepdims=True),
    )
    (tmp_path / "smpl").mkdir()
    np.savez(tmp_path / "smpl" / "SMPL_FEMALE.npz", **arrays)
    model = load_body_model(tmp_path, gender="female")
    assert model.name == "smpl"
    assert model.foot_vertex_ids == SMPL_FOOT_VERTEX_IDS
    out = model(random_rotmats(2), vertex_ids=model.foot_vertex_ids)
    assert out.vertices.shape == (2, 6, 3)


def test_env_variable_is_used(tmp_path, monkeypatch, default_arrays):
    np.savez(tmp_path / "body.npz", **default_arrays)
    monkeypatch.setenv("MRLIB_SMPL_PATH", str(tmp_path / "body.npz"))
    assert load_body_model().path == tmp_path / "body.npz"
    monkeypatch.setenv("MRLIB_SMPL_PATH", str(tmp_path / "missing.pkl"))
    with pytest.raises(BodyModelError, match=r"missing\.pkl.*MRLIB_SMPL_PATH"):
        load_body_model()


def test_clear_errors_for_bad_paths_and_files(tmp_path, default_arrays):
    with pytest.raises(BodyModelError, match="no such file"):
        load_body_model(tmp_path / "nope.pkl")
    with pytest.raises(BodyModelError, match=r"SMPL_MALE\.pkl"):
        load_body_model(tmp_path, gender="male")
    with pytest.raises(BodyModelError, match="gender"):
        load_body_model(gender="robot")
    (tmp_path / "model.txt").write_text("hello")
    with pytest.raises(BodyModelError, match="unsupported"):
        load_body_model(tmp_path / "model.txt")
    (tmp_path / "garbage.pkl").write_bytes(b"\x00\x01 not a pickle")
    with pytest.raises(BodyModelError, match=r"garbage\.pkl"):
        load_body_model(tmp_path / "garbage.pkl")
    partial = {k: v for k, v in default_arrays.items() if k != "weights"}
    np.savez(tmp_path / "partial.npz", **partial)
    with pytest.raises(BodyModelError, match="missing weights"):
        load_body_model(tmp_path / "partial.npz")
    bad = dict(default_arrays, J_regressor=default_arrays["J_regressor"][:20])
    np.savez(tmp_path / "bad.npz", **bad)
    with pytest.raises(BodyModelError, match="J_regressor has shape"):
        load_body_model(tmp_path / "bad.npz")
    np.savez(tmp_path / "obj.npz", v_template=np.array([{"a": 1}], dtype=object))
    with pytest.raises(BodyModelError, match="without pickle"):
        load_body_model(tmp_path / "obj.npz")
