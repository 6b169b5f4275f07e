"""A damaged ``.npy`` header inside an ``.npz`` (an unclosed bracket: numpy's header tokenizer raises
``tokenize.TokenError``, which is neither a ValueError nor a SyntaxError) is one clear InputError."""

import io
import zipfile

import numpy as np
import pytest

from handmocap.core.errors import InputError
from handmocap.core.io.npz import load_npz
from handmocap.core.session.storage import check_npy


def _unclosed_header() -> bytes:
    buffer = io.BytesIO()
    np.lib.format.write_array(buffer, np.zeros(3))
    data = bytearray(buffer.getvalue())
    data[data.index(b"}")] = ord("(")
    return bytes(data)


def test_session_snapshot_member_with_an_unclosed_header():
    with pytest.raises(InputError, match="not an array"):
        check_npy(io.BytesIO(_unclosed_header()), 10**6, "review.npz")


def test_npz_file_with_an_unclosed_header(tmp_path):
    path = tmp_path / "model.npz"
    with zipfile.ZipFile(path, "w") as archive:
        archive.writestr("vertices.npy", _unclosed_header())
    with pytest.raises(InputError):
        load_npz(path, "a hand model file")
