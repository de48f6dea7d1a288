"""Reading SMPL model files: official ``.pkl`` pickles without chumpy, and ``.npz``.

Real SMPL pickles hold chumpy arrays and a scipy sparse ``J_regressor``; they load here
through a restricted unpickler that accepts numpy arrays, sparse matrices and chumpy
arrays (turned into numpy) and refuses any other object, so an untrusted file cannot
run code. ``.npz`` files are read with ``allow_pickle=False``. ``validate_smpl_arrays``
checks the shapes of a 24-joint SMPL model before ``mrlib.representation.body`` builds it.
"""

from __future__ import annotations

import codecs
import pickle
from pathlib import Path
from typing import Any

import numpy as np

try:
    from numpy._core import multiarray as _multiarray  # numpy >= 2
except ImportError:  # pragma: no cover - numpy 1.x
    from numpy.core import multiarray as _multiarray

from mrlib.errors import BodyModelError
from mrlib.representation.skeleton import NUM_JOINTS, PARENTS

__all__ = [
    "REQUIRED_KEYS",
    "OFFICIAL_NAMES",
    "read_smpl_arrays",
    "find_model_file",
    "validate_smpl_arrays",
]

NUM_POSE_BASIS = (NUM_JOINTS - 1) * 9  # 207: SMPL's pose-corrective basis size
REQUIRED_KEYS = (
    "v_template",
    "f",
    "shapedirs",
    "posedirs",
    "J_regressor",
    "kintree_table",
    "weights",
)
# File names the official SMPL downloads use, tried inside a folder.
OFFICIAL_NAMES = {
    "neutral": ("basicModel_neutral_lbs_10_207_0_v1.0.0.pkl",),
    "female": ("basicModel_f_lbs_10_207_0_v1.0.0.pkl",),
    "male": ("basicmodel_m_lbs_10_207_0_v1.0.0.pkl", "basicModel_m_lbs_10_207_0_v1.0.0.pkl"),
}


# -- reading model files without chumpy ------------------------------------------------
class _ChumpyArray:
    """Stands in for any chumpy object while unpickling; keeps only its numpy value.

    A pickled ``chumpy.Ch`` stores its value under ``"x"`` in its state dict. Pickles
    may create the object without calling ``__init__``, hence the class defaults."""

    value: np.ndarray | None = None
    state_keys: tuple[str, ...] = ()

    def __setstate__(self, state: Any) -> None:
        if isinstance(state, tuple) and len(state) == 2:  # (dict, slots) form
            state = state[0]
        if isinstance(state, dict):
            self.state_keys = tuple(sorted(map(str, state)))
            if "x" in state:
                self.value = np.asarray(_to_numpy(state["x"]))


class _SparseMatrix:
    """Stands in for a pickled scipy.sparse CSC/CSR/COO matrix; converted to dense."""

    kind = "csc"
    state: dict = {}

    def __setstate__(self, state: Any) -> None:
        self.state = state if isinstance(state, dict) else {}

    def to_dense(self) -> np.ndarray:
        s = self.state
        shape = tuple(s.get("_shape", s.get("shape", ())))
        fmt = s.get("format", self.kind)
        if len(shape) != 2:
            raise ValueError(f"sparse matrix without a 2-D shape (state keys {sorted(s)})")
        out = np.zeros(shape, dtype=np.float64)
        if fmt in ("csc", "csr"):
            data, indices, indptr = (np.asarray(s[k]) for k in ("data", "indices", "indptr"))
            for i in range(len(indptr) - 1):  # column (csc) or row (csr) i
                sl = slice(indptr[i], indptr[i + 1])
                if fmt == "csc":
                    out[indices[sl], i] += data[sl]
                else:
                    out[i, indices[sl]] += data[sl]
        elif fmt == "coo":
            row, col, data = (np.asarray(s[k]) for k in ("row", "col", "data"))
            np.add.at(out, (row, col), data)
        else:
            raise ValueError(f"unsupported sparse format {fmt!r}")
        return out


_SPARSE = {k: type(f"_{k}_matrix", (_SparseMatrix,), {"kind": k}) for k in ("csc", "csr", "coo")}


def _safe_reconstructor(cls: Any, base: Any, state: Any) -> Any:
    """``copyreg._reconstructor`` restricted to our stand-in classes (protocol-0/1
    pickles of new-style objects go through it)."""
    if not (isinstance(cls, type) and issubclass(cls, (_ChumpyArray, _SparseMatrix))):
        raise pickle.UnpicklingError(f"refusing to reconstruct {cls!r}")
    if base is not object:
        raise pickle.UnpicklingError(f"refusing reconstructor base {base!r}")
    return cls()


class _SMPLUnpickler(pickle.Unpickler):
    """Unpickler for SMPL model files that imports nothing but numpy's array
    reconstruction: chumpy objects and sparse matrices become stand-ins, and every
    other global (``os.system``, ``builtins.eval``, ...) is refused."""

    _NUMPY = {
        ("numpy.core.multiarray", "_reconstruct"),
        ("numpy._core.multiarray", "_reconstruct"),
        ("numpy.core.multiarray", "scalar"),
        ("numpy._core.multiarray", "scalar"),
        ("numpy", "ndarray"),
        ("numpy", "dtype"),
    }

    # plain containers that chumpy objects keep in their state
    _BUILTINS = {t.__name__: t for t in (object, set, frozenset, list, dict, tuple, complex, slice)}

    def find_class(self, module: str, name: str) -> Any:
        if (module, name) in self._NUMPY:
            return getattr(np, name) if module == "numpy" else _numpy_global(name)
        if module == "chumpy" or module.startswith("chumpy."):
            return _ChumpyArray
        if module.startswith("scipy.sparse") and name in ("csc_matrix", "csr_matrix", "coo_matrix"):
            return _SPARSE[name[:3]]
        if module in ("copy_reg", "copyreg") and name == "_reconstructor":
            return _safe_reconstructor
        if module in ("__builtin__", "builtins") and name in self._BUILTINS:
            return self._BUILTINS[name]
        if module == "_codecs" and name == "encode":  # bytes in protocol-0..2 pickles
            return codecs.encode
        raise pickle.UnpicklingError(
            f"refusing to load global {module}.{name}: not part of an SMPL model file"
        )


def _numpy_global(name: str) -> Any:
    return getattr(_multiarray, name)


def _to_numpy(value: Any) -> Any:
    if isinstance(value, _ChumpyArray):
        if value.value is None:
            raise ValueError(f"a chumpy object without a value (state keys {value.state_keys})")
        return value.value
    if isinstance(value, _SparseMatrix):
        return value.to_dense()
    return value


def read_smpl_arrays(path: str | Path) -> dict[str, np.ndarray]:
    """Arrays of an SMPL-format model file (``.pkl`` or ``.npz``), as numpy.

    Real SMPL pickles (with chumpy arrays and a scipy sparse ``J_regressor``) load
    without chumpy or scipy; any pickled object that is not an array is refused.

    Raises:
        BodyModelError: the file is missing, unreadable, or holds foreign objects.
    """
    path = Path(path)
    if not path.is_file():
        raise BodyModelError(f"{path}: no such file")
    suffix = path.suffix.lower()
    if suffix == ".npz":
        try:
            with np.load(path, allow_pickle=False) as z:
                return {k: z[k] for k in z.files}
        except ValueError as e:  # object arrays need pickle: refuse them
            raise BodyModelError(
                f"{path}: cannot read without pickle ({e}); save the model with plain "
                "numpy arrays (np.savez) or pass the original SMPL .pkl"
            ) from e
        except Exception as e:
            raise BodyModelError(f"{path}: not a readable .npz file ({e})") from e
    if suffix != ".pkl":
        raise BodyModelError(
            f"{path}: unsupported body model file type {suffix!r} (want .pkl or .npz)"
        )
    try:
        with open(path, "rb") as fh:
            data = _SMPLUnpickler(fh, encoding="latin1").load()
    except pickle.UnpicklingError as e:
        raise BodyModelError(f"{path}: {e}") from e
    except Exception as e:
        raise BodyModelError(f"{path}: not a readable SMPL pickle ({type(e).__name__}: {e})") from e
    if not isinstance(data, dict):
        raise BodyModelError(f"{path}: expected a dict of arrays, got {type(data).__name__}")
    out = {}
    for k, v in data.items():
        try:
            out[str(k)] = _to_numpy(v)
        except ValueError as e:
            raise BodyModelError(f"{path}: entry {k!r}: {e}") from e
    return out


def find_model_file(path: Path, gender: str) -> Path:
    """The model file for ``gender`` inside folder ``path`` (or its ``smpl/``)."""
    names = [f"SMPL_{gender.upper()}.pkl", f"SMPL_{gender.upper()}.npz", *OFFICIAL_NAMES[gender]]
    for folder in (path, path / "smpl"):
        for name in names:
            if (folder / name).is_file():
                return folder / name
    raise BodyModelError(
        f"{path}: folder has no SMPL model for gender {gender!r} (looked for "
        f"{', '.join(names)} here and in {path / 'smpl'}); download SMPL from "
        "https://smpl.is.tue.mpg.de and pass the .pkl file or its folder"
    )


def validate_smpl_arrays(arrays: dict[str, Any], path: Path) -> dict[str, np.ndarray]:
    """``arrays`` with the required keys as numpy arrays of a 24-joint SMPL model's
    shapes, finite, faces in range and SMPL's kinematic tree; else ``BodyModelError``
    naming ``path`` and what is wrong."""
    missing = [k for k in REQUIRED_KEYS if k not in arrays]
    if missing:
        raise BodyModelError(
            f"{path}: not an SMPL model: missing {', '.join(missing)} "
            f"(has {', '.join(sorted(arrays)) or 'nothing'})"
        )
    a = {k: np.asarray(arrays[k]) for k in REQUIRED_KEYS}
    V = a["v_template"].shape[0] if a["v_template"].ndim == 2 else -1
    expect = {
        "v_template": (V, 3),
        "shapedirs": (V, 3, None),
        "posedirs": (V, 3, NUM_POSE_BASIS),
        "J_regressor": (NUM_JOINTS, V),
        "weights": (V, NUM_JOINTS),
        "kintree_table": (2, NUM_JOINTS),
        "f": (None, 3),
    }
    for k, shape in expect.items():
        got = a[k].shape
        if len(got) != len(shape) or any(
            s is not None and s != g for s, g in zip(shape, got, strict=True)
        ):
            want = "(" + ", ".join("*" if s is None else str(s) for s in shape) + ")"
            raise BodyModelError(
                f"{path}: {k} has shape {got}, expected {want} for a 24-joint SMPL model"
            )
    for k in ("v_template", "shapedirs", "posedirs", "J_regressor", "weights"):
        if not np.isfinite(a[k]).all():
            raise BodyModelError(f"{path}: {k} has NaN or inf values")
    f = a["f"]
    if f.min() < 0 or f.max() >= V:
        raise BodyModelError(f"{path}: faces index vertices outside [0, {V})")
    parents = a["kintree_table"][0].astype(np.int64).copy()
    parents[0] = -1
    if tuple(parents.tolist()) != PARENTS:
        raise BodyModelError(f"{path}: kinematic tree {parents.tolist()} is not SMPL's")
    out = dict(arrays)
    out.update(a)
    return out
