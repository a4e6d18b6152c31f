"""The branch file: schema, atomic rewrite, readable with numpy alone, clear errors."""
import math
import os

import numpy as np
import pytest

from hertzpetsc.branchfile import POINT_FIELDS, BranchWriter, point_index, read_branch
from hertzpetsc.errors import BranchFileError


def write_small(path, npts=3, K=8):
    w = BranchWriter(path, dict(alpha=1.5, cells_per_pi=K, h=math.pi / K, M=10), np.arange(K + 1) * math.pi / K,
                     dict(note="test"))
    for i in range(npts):
        fields = {k: float(i) for k in POINT_FIELDS}
        fields["q"] = math.pi * (10 - i) / 10
        w.append(np.sin(np.arange(K + 1) * math.pi / K) * (i + 1), **fields)
    return w


def test_roundtrip_and_plain_numpy_access(tmp_path):
    path = str(tmp_path / "b.npz")
    write_small(path)
    b = read_branch(path)
    assert b["u"].shape == (3, 9) and b["alpha"] == 1.5 and b["meta"]["note"] == "test"
    assert point_index(b, 0.9 * math.pi) == 1
    with np.load(path) as z:                       # no hertzpetsc needed to read it
        assert set(POINT_FIELDS) <= set(z.files)
    assert not [f for f in os.listdir(tmp_path) if ".tmp-" in f]     # no temporary file left behind


def test_missing_point_is_a_clear_error(tmp_path):
    path = str(tmp_path / "b.npz")
    write_small(path)
    with pytest.raises(BranchFileError, match="no point at q = 0.5"):
        point_index(read_branch(path), 0.5)


def test_missing_file(tmp_path):
    with pytest.raises(BranchFileError, match="does not exist"):
        read_branch(str(tmp_path / "nothing.npz"))


@pytest.mark.parametrize("content", [b"", b"not a zip at all", b"PK\x03\x04garbage"])
def test_corrupt_file(tmp_path, content):
    path = tmp_path / "b.npz"
    path.write_bytes(content)
    with pytest.raises(BranchFileError, match="corrupt"):
        read_branch(str(path))


def test_truncated_file(tmp_path):
    path = str(tmp_path / "b.npz")
    write_small(path)
    data = open(path, "rb").read()
    open(path, "wb").write(data[: len(data) // 2])
    with pytest.raises(BranchFileError, match="corrupt"):
        read_branch(path)


def test_foreign_npz(tmp_path):
    path = str(tmp_path / "b.npz")
    np.savez(path, x=np.zeros(3))
    with pytest.raises(BranchFileError, match="not a hertzpetsc branch file"):
        read_branch(path)
