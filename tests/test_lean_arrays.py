"""Memory-lean forms give the same numbers: constant joint columns as broadcasts, angles in steps."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from usdgaze.core import rotations as rot
from usdgaze.usd import skelio
from usdgaze.usd.stage import open_stage

CMU = Path(__file__).resolve().parents[1] / "sample_stages" / "cmu" / "cmu_131_02.usdc"
SHARED_MAP = Path(__file__).resolve().parents[1] / "sample_stages" / "shared_map" / "gaze_map.usda"


def _clip():
    stage = open_stage(str(CMU))
    root = stage.GetPrimAtPath("/root/Body")
    return skelio.read_clip(stage, stage.GetPrimAtPath("/root/Body/BodySkel"), root, str(CMU))


def test_local_trs_values_are_the_samples_bit_for_bit():
    clip = _clip()
    broadcasts = 0
    for j in range(len(clip.joints)):
        t, q, s = clip.local_trs(j)
        hits = np.flatnonzero(clip.anim_to_skel == j)
        if not len(hits):
            continue
        a = hits[0]
        for got, column in ((t, clip.translations[:, a]), (q, clip.rotations[:, a]), (s, clip.scales[:, a])):
            want = column.astype(float)
            assert got.shape == want.shape and np.array_equal(got.view(np.uint64), want.view(np.uint64))
        broadcasts += s.strides[0] == 0
    assert broadcasts == len(clip.joints)  # CMU's scales are constant: one row each, not F copies


def test_a_column_with_signed_zeros_is_not_taken_for_constant():
    clip = _clip()
    a = 1
    clip.translations = clip.translations.copy()
    clip.translations[:, a] = 0.0
    clip.translations[7, a, 0] = -0.0  # equal to 0.0, other bits: must come back as it is
    t, _, _ = clip.local_trs(int(clip.anim_to_skel[a]))
    assert t.strides[0] != 0 and np.signbit(t[7, 0]) and not np.signbit(t[6, 0])


def test_angle_in_steps_equals_the_whole_array_computation():
    q = np.random.default_rng(4).normal(size=(rot._ROWS + 123, 5, 4))
    assert np.array_equal(rot.angle(q), np.linalg.norm(rot.to_rotvec(q), axis=-1))
    assert rot.angle(q[0, 0]).shape == ()


def test_normalize_and_to_rotvec_match_their_masked_forms_bit_for_bit():
    rng = np.random.default_rng(5)
    q = rng.normal(size=(5000, 4))
    q[:500] = [0.0, 0.0, 0.0, 1.0]  # identities: the small-angle branch
    q[500:510, :3] = 1e-14
    for batch in (q, np.concatenate([q, np.zeros((3, 4))])):  # with and without zero-length rows
        n = np.sqrt(np.einsum("...i,...i->...", batch, batch))[..., None]
        unit = np.divide(batch, n, out=np.zeros_like(batch), where=n > 0)
        assert np.array_equal(rot.normalize(batch).view(np.uint64), unit.view(np.uint64))
        u = np.where(unit[:, 3:] < 0.0, -unit, unit)
        s = np.linalg.norm(u[:, :3], axis=-1, keepdims=True)
        angle = 2.0 * np.arctan2(s, u[:, 3:])
        want = u[:, :3] * np.divide(angle, s, out=np.full_like(s, 2.0), where=s > 1e-12)
        assert np.array_equal(rot.to_rotvec(batch).view(np.uint64), want.view(np.uint64))


_FAULTS = """
import resource, sys
import numpy as np
if sys.argv[1] == "tuned":
    from usdgaze.process import tune_allocator
    assert tune_allocator() and tune_allocator()
def faults():
    return resource.getrusage(resource.RUSAGE_SELF).ru_minflt
np.ones(6_250_000).sum()  # 50 MB, freed at once
before = faults()
for _ in range(4):
    np.ones(6_250_000).sum()  # the same size again: fresh pages, or the freed ones reused
print(faults() - before)
"""


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's allocator only")
def test_tuned_allocator_reuses_freed_memory_instead_of_faulting_in_fresh_pages():
    def faults(mode):
        return int(subprocess.run([sys.executable, "-c", _FAULTS, mode], capture_output=True, text=True,
                                  check=True).stdout.split()[-1])
    plain, tuned = faults("plain"), faults("tuned")
    assert plain >= 100  # glibc maps each large array afresh (huge pages make fewer, larger faults)
    assert tuned * 20 < plain


def _crowd(folder: Path, characters: int, joints: int = 40, frames: int = 600) -> Path:
    """``characters`` SkelRoots, each a reference to one synthetic walker, sharing the sample map."""
    from tests.synthetic import make_rig

    make_rig(folder / "rig.usdc", joints=joints, frames=frames, time_codes_per_second=24.0)
    shutil.copy(SHARED_MAP, folder / "gaze_map.usda")
    # The walker's unit (metres) on the stage: USD reads a reference in the stage's unit, and a stage that
    # authors none (0.01) made it a 1.6 cm crowd, which apply refuses (tests/test_reference_units.py).
    lines = ["#usda 1.0", "(", "    metersPerUnit = 1", "    timeCodesPerSecond = 24", f"    endTimeCode = {frames - 1}", ")",
             'class "CrowdMap" (prepend references = @./gaze_map.usda@</GazeMap>)', "{", "}",
             'def Xform "Crowd"', "{"]
    for i in range(characters):
        lines += [f'    def "C{i}" (prepend references = @./rig.usdc@</Character>',
                  "        prepend inherits = </CrowdMap>)", "    {", "    }"]
    path = folder / f"crowd{characters}.usda"
    path.write_text("\n".join(lines + ["}"]) + "\n")
    return path


def test_a_crowd_is_written_as_it_goes_not_held_until_the_end(tmp_path):
    """Python's peak for eight characters stays near one's: each character's float64 arrays go into
    the override layer (float32, in USD) when it is done instead of all being kept for the end."""
    import tracemalloc

    from usdgaze import api

    joints, frames = 40, 600
    one_character = joints * frames * (4 + 3 + 3) * 8  # its rotations, translations, scales in float64
    peaks = {}
    for n in (1, 8):
        folder = tmp_path / str(n)
        folder.mkdir()
        crowd = _crowd(folder, n, joints, frames)
        api.apply(crowd, ["1s:30:0"], folder / "warm.usdc")  # imports and caches outside the measure
        tracemalloc.start()
        report = api.apply(crowd, ["1s:30:0"], folder / "out.usdc")
        peaks[n] = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
        assert len(report.characters) == n and all(c.result.shift_timing for c in report.characters)
    assert peaks[8] - peaks[1] < 2 * one_character, (peaks, one_character)  # 6.8 MB before, 1.9 MB now
