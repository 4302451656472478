"""Load ``.npy`` files that hold pickled object arrays (DexGraspNet's format) without running code.

``numpy.load(path, allow_pickle=True)`` unpickles the payload with Python's full
unpickler, which calls whatever global the file names (``os.system`` included). Here the
``.npy`` header is parsed with numpy's public format helpers and, for object arrays, the
payload goes to an unpickler whose ``find_class`` admits only the handful of numpy
globals that numpy's own pickles of arrays, dtypes and scalars use. Plain containers
(dict, list, tuple), numbers, strings, bytes, bool and None are built by pickle opcodes
and need no global at all. Any other global is refused before it is imported or called,
with an error that names the file and the global. Arrays without objects are read by
numpy with pickling disabled.
"""

from __future__ import annotations

import os
import pickle
from pathlib import Path

import numpy as np
from numpy.lib import format as npy_format


class NpyReadError(ValueError):
    """A ``.npy`` file that is malformed or of an unsupported format."""


class RefusedPickleError(NpyReadError):
    """A pickle that names a global outside the admitted numpy set; nothing was executed."""

    def __init__(self, path: str | os.PathLike, global_name: str) -> None:
        self.path = str(path)
        self.global_name = global_name
        super().__init__(
            f"{path}: refused pickle global {global_name!r} (only containers, numbers, strings and "
            "numpy arrays/scalars are admitted); nothing was executed"
        )


def _numpy_multiarray():
    try:
        from numpy._core import multiarray  # numpy >= 2
    except ImportError:  # pragma: no cover - numpy 1.x
        from numpy.core import multiarray
    return multiarray


def admitted_globals() -> dict[tuple[str, str], object]:
    """The (module, name) pairs numpy's array/dtype/scalar pickles use, mapped to the objects.

    Pickles written by numpy 1.x name ``numpy.core.multiarray``, numpy 2.x names
    ``numpy._core.multiarray``; both resolve to the installed module without importing
    anything by name from the file.
    """
    multiarray = _numpy_multiarray()
    admitted: dict[tuple[str, str], object] = {("numpy", "ndarray"): np.ndarray, ("numpy", "dtype"): np.dtype}
    for module in ("numpy.core.multiarray", "numpy._core.multiarray"):
        admitted[(module, "_reconstruct")] = multiarray._reconstruct
        admitted[(module, "scalar")] = multiarray.scalar
    return admitted


class RestrictedUnpickler(pickle.Unpickler):
    """An unpickler that resolves only ``admitted_globals()`` and refuses persistent ids."""

    def __init__(self, file, source: str | os.PathLike) -> None:
        super().__init__(file, encoding="ASCII")
        self._source = source
        self._admitted = admitted_globals()

    def find_class(self, module: str, name: str):
        try:
            return self._admitted[(module, name)]
        except KeyError:
            raise RefusedPickleError(self._source, f"{module}.{name}") from None

    def persistent_load(self, pid):
        raise RefusedPickleError(self._source, f"persistent id {pid!r}")


def _read_header(fp, path: Path) -> tuple[tuple[int, ...], bool, np.dtype]:
    try:
        version = npy_format.read_magic(fp)
    except ValueError as exc:
        raise NpyReadError(f"{path}: not a .npy file ({exc})") from None
    readers = {(1, 0): npy_format.read_array_header_1_0, (2, 0): npy_format.read_array_header_2_0}
    if version not in readers:
        raise NpyReadError(f"{path}: unsupported .npy format version {version[0]}.{version[1]}")
    try:
        return readers[version](fp)
    except ValueError as exc:
        raise NpyReadError(f"{path}: malformed .npy header ({exc})") from None


def load_npy_restricted(path: str | os.PathLike) -> np.ndarray:
    """Read a ``.npy`` file; object arrays go through ``RestrictedUnpickler``.

    Raises ``RefusedPickleError`` for a pickle that names any other global and
    ``NpyReadError`` for a malformed file; nothing from the file is executed.
    """
    path = Path(path)
    with open(path, "rb") as fp:
        shape, _, dtype = _read_header(fp, path)
        if not dtype.hasobject:
            fp.seek(0)
            try:
                return npy_format.read_array(fp, allow_pickle=False)
            except ValueError as exc:
                raise NpyReadError(f"{path}: malformed array data ({exc})") from None
        try:
            value = RestrictedUnpickler(fp, path).load()
        except RefusedPickleError:
            raise
        except Exception as exc:  # truncated or inconsistent pickles raise many types
            raise NpyReadError(f"{path}: malformed pickle payload ({type(exc).__name__}: {exc})") from None
    if not isinstance(value, np.ndarray):
        raise NpyReadError(f"{path}: pickle payload is a {type(value).__name__}, not the array the header declares")
    if value.shape != tuple(shape):
        raise NpyReadError(f"{path}: pickled array has shape {value.shape}, header declares {tuple(shape)}")
    return value
