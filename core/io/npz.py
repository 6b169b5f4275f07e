"""Reading ``.npz`` files (templates, priors, results, truth) with every array's size checked before loading.

``np.load`` trusts the header of each ``.npy`` member: a 300-byte file whose header claims a shape of
10^12 elements makes it allocate terabytes before it reads a byte. Here each header is read first and
the bytes it claims are compared with the bytes the member holds (as stored in the zip directory), and
that size with the most a zip member can expand to (deflate: at most 1032 bytes out per byte in). So
loading needs at most about 1032 times the file's size, and for a sound file no more than its arrays.
"""

import math
import tokenize
import zipfile
import zlib
from os import PathLike
from pathlib import Path

import numpy as np

from handmocap.core.errors import InputError

#: deflate writes at least one bit per 258-byte match, so no member expands more than this from its stored size
_DEFLATE_MAX_RATIO = 1032
_MAX_HEADER_BYTES = 10_000  # numpy's own limit for a .npy header (np.lib.format, max_header_size)


def load_npz(path: str | PathLike[str], what: str) -> dict[str, np.ndarray]:
    """Every array of the ``.npz`` file at ``path``, by member name without ``.npy``; never unpickles.

    Raises :class:`InputError` ``"<file name>: not <what> (<reason>)"`` (``what`` such as "a hand model file")
    when the file is not a zip of ``.npy`` arrays, a header is malformed or claims more data than its member
    holds, or a member is damaged.
    """
    name = Path(path).name
    try:
        with zipfile.ZipFile(path) as archive:
            arrays = {}
            for member in archive.infolist():
                if not member.filename.endswith(".npy"):
                    continue
                _check_member(archive, member)
                with archive.open(member) as stream:
                    arrays[member.filename[:-4]] = np.lib.format.read_array(stream, allow_pickle=False)
    except (OSError, EOFError, ValueError, TypeError, zipfile.BadZipFile, zlib.error, NotImplementedError,
            RuntimeError, SyntaxError, tokenize.TokenError) as error:  # numpy tokenizes and parses the header
        problem = " ".join(str(error).split())[:200]
        raise InputError(f"{name}: not {what} ({problem})") from None
    return arrays


def _check_member(archive: zipfile.ZipFile, member: zipfile.ZipInfo) -> None:
    """Raise ValueError unless the member's header describes a plain array of the size the member holds."""
    if member.compress_type == zipfile.ZIP_STORED:
        largest = member.compress_size
    else:
        largest = member.compress_size * _DEFLATE_MAX_RATIO
    if member.file_size > largest:
        raise ValueError(f"{member.filename} claims {member.file_size} bytes from {member.compress_size} stored")
    with archive.open(member) as stream:
        major, minor = np.lib.format.read_magic(stream)
        if (major, minor) == (1, 0):
            shape, fortran_order, dtype = np.lib.format.read_array_header_1_0(stream, _MAX_HEADER_BYTES)
        elif (major, minor) in ((2, 0), (3, 0)):
            shape, fortran_order, dtype = np.lib.format.read_array_header_2_0(stream, _MAX_HEADER_BYTES)
        else:
            raise ValueError(f"{member.filename}: unsupported .npy version {major}.{minor}")
        header_bytes = stream.tell()
    if dtype.hasobject:
        raise ValueError(f"{member.filename} holds Python objects")
    if any(size < 0 for size in shape):
        raise ValueError(f"{member.filename}: negative dimension in shape {shape}")
    count = math.prod(shape)
    claimed = count * dtype.itemsize
    too_many = count > member.file_size or dtype.itemsize > member.file_size  # an element takes >= 1 byte
    if too_many or claimed > member.file_size - header_bytes:
        raise ValueError(f"{member.filename}: its header claims {claimed} bytes, the member holds "
                         f"{member.file_size - header_bytes}")

