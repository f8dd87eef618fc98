"""Eye joints with their own non-uniform scale, measured with UsdSkel FK on the composed preview.

An eye squashed or stretched by its own scale (a cartoon eye made oval, squashed as it blinks) shows
its modelled forward axis bent by that scale, wherever the scale's axes are not the eye's forward
(the synthetic rigs' eye frames are random, as a rig's joint orient may be). Aimed by its rotation
alone, the eye missed a look-at target by 16.3 deg with an animated scale (1, 1.6, 0.7), 3.4 deg
with (1, 1.1, 0.95), and 20.5 deg when only the bind pose scaled it; a shift held 5.9 deg off.
Nothing here calls usdgaze's math: eye axes come from the bind pose (tests/measure.py).
"""

from __future__ import annotations

import numpy as np
import pytest
from pxr import Sdf, Vt

import usdgaze  # noqa: F401  (registers GazeMapAPI before any stage is opened)
from usdgaze import api

from . import measure
from . import synthetic as syn

RATE, FRAMES, LOOK_S, SHIFT_S = 24.0, 120, 0.5, 2.5


def _scale_eyes(rig: syn.Rig, bind: tuple, animated: tuple) -> None:
    """Give both eyes a local scale ``bind`` in the bind and rest poses and ``animated`` in the animation
    (row vectors: a joint's scale applies in its own frame, before its rotation)."""
    layer = Sdf.Layer.FindOrOpen(str(rig.path))
    skel = layer.GetPrimAtPath(rig.skeleton)
    eyes = [rig.joint("eye_l"), rig.joint("eye_r")]
    index = [rig.joints.index(e) for e in eyes]
    for name in ("bindTransforms", "restTransforms"):
        m = np.array(skel.attributes[name].default)
        m[index, :3, :3] = np.diag(bind) @ m[index, :3, :3]
        skel.attributes[name].default = Vt.Matrix4dArray.FromNumpy(m)
    columns = [rig.anim_joints.index(e) for e in eyes]
    path = Sdf.Path(rig.animation + ".scales")
    for t in layer.ListTimeSamplesForPath(path):
        s = np.array(layer.QueryTimeSample(path, t), dtype=np.float32)
        s[columns] = animated
        layer.SetTimeSample(path, t, Vt.Vec3hArray.FromNumpy(s.astype(np.float16)))
    layer.Save()


@pytest.mark.parametrize("bind, animated", [
    ((1.0, 1.0, 1.0), (1.0, 1.6, 0.7)),   # squashed in the animation
    ((1.0, 1.0, 1.0), (1.0, 1.1, 0.95)),  # a little
    ((1.0, 1.6, 0.7), (1.0, 1.0, 1.0)),   # modelled oval, animated round
    ((1.0, 1.6, 0.7), (1.0, 1.6, 0.7)),   # oval in both (already right)
])
def test_an_eye_scaled_on_its_own_lands_on_the_target(tmp_path, bind, animated):
    rig = syn.make_rig(tmp_path / "in.usda", frames=FRAMES, time_codes_per_second=RATE, mesh=False)
    _scale_eyes(rig, bind, animated)
    base = measure.posed(str(rig.path), rig.skeleton)
    fwd = measure.character_forward_skel(base, rig.leaf["thigh_l"], rig.leaf["thigh_r"])
    eyes = rig.eye_leaves
    look = int(LOOK_S * RATE)
    up = np.array([0.0, 1.0, 0.0])
    target = base.position(rig.leaf["head"])[look] + 5.0 * (np.cos(0.5) * fwd + np.sin(0.5) * np.cross(up, fwd))
    preview = tmp_path / "preview.usda"
    api.apply(rig.path, [f"{SHIFT_S}s:40:10"], tmp_path / "gaze.usdc", preview=preview,
              look_at=[",".join(f"{v:.6f}" for v in target) + f"@{LOOK_S}s"])
    new = measure.posed(str(preview), rig.skeleton)
    seconds = (new.times - rig.start_time) / RATE
    looking = (seconds >= LOOK_S + 0.8) & (seconds < SHIFT_S)
    for eye in eyes:
        miss = measure.eye_miss_deg(new, eye, fwd, target)[looking]
        assert miss.max() < 0.5, (eye, miss.max())
    change, _, _ = measure.gaze_change(base, new, fwd, rig.leaf["head"], eyes)
    held = np.abs(change[seconds >= SHIFT_S + 1.2] - [40.0, 10.0]).max()
    assert held < 0.5, held
