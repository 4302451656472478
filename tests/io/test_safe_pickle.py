"""The restricted .npy/pickle loader: admits numpy's own pickles, refuses and never runs anything else."""

import io
import os
import pickle

import numpy as np
import pytest
from numpy.lib import format as npy_format

from dexlite_pipeline.io.safe_pickle import NpyReadError, RefusedPickleError, load_npy_restricted


def _write_object_npy(path, payload_bytes, shape=(1,)):
    """A .npy file whose header declares an object array and whose payload is the given pickle."""
    with open(path, "wb") as fp:
        npy_format.write_array_header_1_0(fp, {"descr": "|O", "fortran_order": False, "shape": shape})
        fp.write(payload_bytes)
    return path


class _RunsCommand:
    def __init__(self, command):
        self.command = command

    def __reduce__(self):
        return (os.system, (self.command,))


class _WritesFile:
    def __init__(self, marker):
        self.marker = marker

    def __reduce__(self):
        return (eval, (f"open({str(self.marker)!r}, 'w').write('pwned')",))


def test_numpy_object_array_of_dicts_loads(tmp_path):
    grasps = np.array(
        [
            {"qpos": {"WRJTx": 0.1, "robot0:FFJ3": -0.2}, "scale": np.float64(0.06)},
            {"qpos": {"WRJTx": 0.3}, "scale": np.float32(0.1), "extra": [1, (2, "a"), None, True, b"x", np.arange(3)]},
        ],
        dtype=object,
    )
    np.save(tmp_path / "g.npy", grasps, allow_pickle=True)
    back = load_npy_restricted(tmp_path / "g.npy")
    assert back.shape == (2,) and back.dtype == object
    assert back[0]["qpos"] == {"WRJTx": 0.1, "robot0:FFJ3": -0.2}
    assert isinstance(back[0]["scale"], np.float64) and back[0]["scale"] == 0.06
    assert back[1]["scale"].dtype == np.float32
    np.testing.assert_array_equal(back[1]["extra"][5], np.arange(3))
    assert back[1]["extra"][:5] == [1, (2, "a"), None, True, b"x"]


def test_plain_numeric_array_loads_without_pickle(tmp_path):
    data = np.arange(12, dtype=np.float32).reshape(3, 4)
    np.save(tmp_path / "a.npy", data)
    np.testing.assert_array_equal(load_npy_restricted(tmp_path / "a.npy"), data)


def test_os_system_is_refused_and_not_run(tmp_path):
    marker = tmp_path / "marker"
    path = _write_object_npy(tmp_path / "evil.npy", pickle.dumps([_RunsCommand(f"touch {marker}")]))
    with pytest.raises(RefusedPickleError) as info:
        load_npy_restricted(path)
    assert not marker.exists()
    message = str(info.value)
    assert "evil.npy" in message and "system" in message
    assert info.value.global_name in {"posix.system", "os.system", "nt.system"}


def test_malicious_object_nested_inside_valid_grasps_is_refused(tmp_path):
    marker = tmp_path / "marker"
    grasps = np.array([{"qpos": {"WRJTx": 0.0}, "scale": 0.1}, {"qpos": {"WRJTx": _WritesFile(marker)}, "scale": 0.1}], dtype=object)
    buffer = io.BytesIO()
    np.save(buffer, grasps, allow_pickle=True)  # pickles _WritesFile's reduce (builtins.eval) inside the array
    (tmp_path / "nested.npy").write_bytes(buffer.getvalue())
    with pytest.raises(RefusedPickleError, match=r"builtins\.eval"):
        load_npy_restricted(tmp_path / "nested.npy")
    assert not marker.exists()


@pytest.mark.parametrize(
    "module, name",
    [("numpy", "load"), ("builtins", "getattr"), ("subprocess", "Popen"), ("numpy", "core.multiarray._reconstruct")],
)
def test_other_globals_are_refused_by_name(tmp_path, module, name):
    payload = b"\x80\x02c" + f"{module}\n{name}\n".encode() + b")R."  # GLOBAL, empty tuple, REDUCE
    path = _write_object_npy(tmp_path / "g.npy", payload)
    with pytest.raises(RefusedPickleError, match=f"{module}.{name}".replace(".", r"\.")):
        load_npy_restricted(path)


def test_persistent_ids_are_refused(tmp_path):
    path = _write_object_npy(tmp_path / "p.npy", b"\x80\x02X\x03\x00\x00\x00abcQ.")  # BINPERSID
    with pytest.raises(RefusedPickleError, match="persistent id"):
        load_npy_restricted(path)


def test_payload_that_is_not_the_declared_array_is_an_error(tmp_path):
    path = _write_object_npy(tmp_path / "d.npy", pickle.dumps({"qpos": {}}))
    with pytest.raises(NpyReadError, match="dict, not the array"):
        load_npy_restricted(path)


def test_truncated_and_non_npy_files_are_errors(tmp_path):
    np.save(tmp_path / "ok.npy", np.array([{"a": 1.0}], dtype=object), allow_pickle=True)
    data = (tmp_path / "ok.npy").read_bytes()
    (tmp_path / "cut.npy").write_bytes(data[:-10])
    with pytest.raises(NpyReadError, match="cut.npy: malformed pickle"):
        load_npy_restricted(tmp_path / "cut.npy")
    (tmp_path / "text.npy").write_text("not numpy")
    with pytest.raises(NpyReadError, match="text.npy: not a .npy file"):
        load_npy_restricted(tmp_path / "text.npy")


@pytest.mark.real_sample
def test_real_dexgraspnet_files_load(dexgraspnet_sample):
    for path in sorted((dexgraspnet_sample / "dataset").glob("*.npy")):
        grasps = load_npy_restricted(path)
        assert grasps.dtype == object and len(grasps) > 200
        assert set(grasps[0]) == {"qpos", "scale"} and len(grasps[0]["qpos"]) == 28
