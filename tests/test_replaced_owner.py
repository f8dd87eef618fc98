"""A replaced output keeps its group (and, run as root, its owner), as it keeps its mode: the writer
stages a new file and renames it over the old one, a new inode that was the running user's, so a
show's shared group lost its write access to the override it shared."""

from __future__ import annotations

import os
import stat

import pytest

from .bad_common import SHIFT, rig, run_inprocess


def _other_group() -> int:
    """A group other than ours that we may give a file: any as root, else one we belong to."""
    mine = os.getegid()
    if os.geteuid() == 0:
        return 65534 if mine != 65534 else 65533
    others = [g for g in os.getgroups() if g != mine]
    if not others:
        pytest.skip("no second group to give the file")
    return others[0]


@pytest.mark.parametrize("suffix", [".usdc", ".usda"])
def test_a_replaced_output_keeps_its_group_and_mode(tmp_path, suffix):
    src = rig(tmp_path, "in.usda").path
    out = tmp_path / f"gaze{suffix}"
    argv = ["apply", str(src), *SHIFT, "--out", out.name]
    assert run_inprocess(argv, tmp_path)[0] == 0
    group = _other_group()
    owner = 65534 if os.geteuid() == 0 else -1  # root may keep another user's file theirs too
    os.chown(out, owner, group)
    os.chmod(out, 0o664)
    before = out.stat()
    argv[3] = "0.5s:-30:0"
    code, _, err = run_inprocess(argv, tmp_path)
    assert code == 0, err
    after = out.stat()
    assert after.st_ino != before.st_ino  # replaced, not written in place
    assert (after.st_gid, stat.S_IMODE(after.st_mode)) == (group, 0o664)
    assert after.st_uid == (owner if owner != -1 else before.st_uid)
