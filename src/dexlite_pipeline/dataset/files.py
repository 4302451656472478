"""Deterministic, atomic files of the dataset: the batches' .npz archives and the CSV tables.

Same inputs give the same bytes, so that git stores an unchanged file once and a diff shows
only what changed. ``numpy.savez_compressed`` stamps each member with the current time; here
every member gets a fixed date (1980-01-01, the earliest a zip can hold), fixed permissions and
a fixed compression level, and members are written in name order. Arrays are written with
``allow_pickle=False`` (strings as fixed-width unicode), so reading needs no pickle either.
Every file is written to a temporary sibling and renamed into place (``atomic.atomic_path``).
"""

from __future__ import annotations

import io
import math
import os
import zipfile
from pathlib import Path

import numpy as np
import pandas as pd

from dexlite_pipeline.atomic import atomic_path

FIXED_ZIP_DATE_TIME = (1980, 1, 1, 0, 0, 0)
ZIP_COMPRESSION_LEVEL = 6  # zlib's default: a fixed level keeps the bytes fixed (for one zlib version)
UNIX_FILE_MODE = 0o100644  # regular file, rw-r--r--
UNIX_CREATOR = 3  # zip "made by" Unix, whatever the writing platform


class DatasetFileError(ValueError):
    """A dataset file that cannot be read as the layout says."""


def write_npz_deterministic(path: str | os.PathLike, arrays: dict[str, np.ndarray]) -> None:
    """Write ``arrays`` as a compressed .npz at ``path``, byte-identical for identical arrays, atomically."""
    with atomic_path(path) as tmp:
        with zipfile.ZipFile(tmp, "w", compression=zipfile.ZIP_DEFLATED, compresslevel=ZIP_COMPRESSION_LEVEL) as archive:
            for name in sorted(arrays):
                buffer = io.BytesIO()
                np.lib.format.write_array(buffer, np.ascontiguousarray(arrays[name]), allow_pickle=False)
                member = zipfile.ZipInfo(f"{name}.npy", date_time=FIXED_ZIP_DATE_TIME)
                member.compress_type = zipfile.ZIP_DEFLATED
                member.create_system = UNIX_CREATOR
                member.external_attr = UNIX_FILE_MODE << 16
                archive.writestr(member, buffer.getvalue(), compresslevel=ZIP_COMPRESSION_LEVEL)


def read_npz(path: str | os.PathLike, names: tuple[str, ...] | None = None) -> dict[str, np.ndarray]:
    """The arrays of an .npz (only ``names`` when given; names the file lacks are left out), without pickle."""
    try:
        with np.load(path, allow_pickle=False) as archive:
            wanted = archive.files if names is None else [n for n in names if n in archive.files]
            return {name: archive[name] for name in wanted}
    except (OSError, ValueError, zipfile.BadZipFile) as exc:
        raise DatasetFileError(f"{path}: cannot read the grasp archive: {exc}") from None


def write_table(frame: pd.DataFrame, columns: tuple[str, ...], path: str | os.PathLike) -> None:
    """Write ``frame``'s ``columns`` as CSV (Unix line ends, NaN as an empty cell) atomically."""
    with atomic_path(path) as tmp:
        frame.loc[:, list(columns)].to_csv(tmp, index=False, lineterminator="\n")


def read_table(
    path: str | os.PathLike, columns: tuple[str, ...], float_columns: tuple[str, ...] = (), int_columns: tuple[str, ...] = ()
) -> pd.DataFrame:
    """A dataset table with exactly ``columns``: text as str ('' for an empty cell), the named columns as float64 / int64.

    A missing file is an empty table. A file with other columns is a ``DatasetFileError`` naming them.
    """
    if not Path(path).is_file():
        return empty_table(columns, float_columns, int_columns)
    frame = pd.read_csv(path, dtype=str, keep_default_na=False)
    if tuple(frame.columns) != tuple(columns):
        missing = [c for c in columns if c not in frame.columns]
        extra = [c for c in frame.columns if c not in columns]
        raise DatasetFileError(f"{path}: columns differ from the layout (missing: {', '.join(missing) or 'none'}; "
                               f"unexpected: {', '.join(extra) or 'none'}; or out of order)")  # fmt: skip
    frame = frame.astype(object)
    for column in float_columns:
        frame[column] = pd.to_numeric(frame[column].replace("", math.nan), errors="raise").astype(np.float64)
    for column in int_columns:
        frame[column] = pd.to_numeric(frame[column], errors="raise").astype(np.int64)
    return frame


def empty_table(columns: tuple[str, ...], float_columns: tuple[str, ...] = (), int_columns: tuple[str, ...] = ()) -> pd.DataFrame:
    """A table without rows whose columns have the dtypes ``read_table`` gives."""
    data = {c: pd.Series([], dtype=np.float64 if c in float_columns else np.int64 if c in int_columns else object) for c in columns}
    return pd.DataFrame(data, columns=list(columns))

