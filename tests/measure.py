"""Independent measurements for tests: UsdSkel's own forward kinematics, plain numpy geometry.

Nothing here calls usdgaze's math, so a test that compares usdgaze's output with these numbers
checks the tool against USD rather than against itself.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass

import numpy as np
from pxr import Usd, UsdGeom, UsdSkel


def sha256(path) -> str:
    return hashlib.sha256(open(path, "rb").read()).hexdigest()


@dataclass
class Posed:
    joints: list[str]
    times: np.ndarray
    world: np.ndarray  # (F, J, 4, 4) row-vector world matrices, as USD gives them
    up: np.ndarray
    rest_skel: np.ndarray  # (J, 4, 4) rest pose in skeleton space (row-vector)
    skel_to_world: np.ndarray  # (4, 4) at the first time
    bind_skel: np.ndarray | None = None  # (J, 4, 4) bind pose in skeleton space (row-vector), if authored

    @property
    def neutral(self) -> np.ndarray:
        """The pose the character was modelled in, where head and eyes look ahead: the bind pose
        (UsdSkel's bindTransforms), or the rest pose where the skeleton has none."""
        return self.bind_skel if self.bind_skel is not None else self.rest_skel

    def index(self, leaf: str) -> int:
        hits = [i for i, j in enumerate(self.joints) if j.rsplit("/", 1)[-1] == leaf]
        assert hits, f"no joint {leaf}"
        return hits[0]

    def position(self, leaf: str) -> np.ndarray:
        return self.world[:, self.index(leaf), 3, :3]

    def axis(self, leaf: str, local_axis: np.ndarray) -> np.ndarray:
        """World direction of a joint-local axis (row vectors: v @ M)."""
        m = self.world[:, self.index(leaf), :3, :3]
        d = np.einsum("i,fij->fj", local_axis, m)
        return d / np.linalg.norm(d, axis=-1, keepdims=True)


def posed(stage_path: str, skeleton: str, mute: list[str] | None = None, neutral: str = "bind",
          times=None) -> Posed:
    """World transforms of every joint at every animation time sample (or at ``times``), by UsdSkel.

    ``neutral="rest"`` takes head and eye axes from the rest pose even where a bind pose exists.
    """
    stage = Usd.Stage.Open(stage_path)
    for layer in mute or []:
        stage.MuteLayer(layer)
    skel = UsdSkel.Skeleton(stage.GetPrimAtPath(skeleton))
    cache = UsdSkel.Cache()
    root = UsdSkel.Root.Find(skel.GetPrim())
    cache.Populate(root, Usd.PrimDefaultPredicate)
    query = cache.GetSkelQuery(skel)
    xf = UsdGeom.Xformable(skel.GetPrim())
    times = np.array(query.GetAnimQuery().GetJointTransformTimeSamples() if times is None else times, dtype=float)
    world = np.stack([
        np.array(query.ComputeJointSkelTransforms(Usd.TimeCode(t)))
        @ np.array(xf.ComputeLocalToWorldTransform(Usd.TimeCode(t)))
        for t in times
    ])
    up = np.array([0.0, 0.0, 1.0]) if UsdGeom.GetStageUpAxis(stage) == "Z" else np.array([0.0, 1.0, 0.0])
    rest = np.array(query.ComputeJointSkelTransforms(Usd.TimeCode.Default(), atRest=True))
    s2w = np.array(xf.ComputeLocalToWorldTransform(Usd.TimeCode(times[0])))
    bind = np.array(query.GetJointWorldBindTransforms()) if neutral == "bind" else None
    joints = [str(j) for j in query.GetJointOrder()]
    bind = bind if bind is not None and bind.shape == (len(joints), 4, 4) else None
    return Posed(joints, times, world, up, rest, s2w, bind)


def character_forward_skel(p: Posed, left_leaf: str, right_leaf: str) -> np.ndarray:
    """Forward in skeleton space from two neutral-pose joints and the stage up: left x up."""
    up_s = np.linalg.solve(p.skel_to_world[:3, :3].T, p.up)
    up_s /= np.linalg.norm(up_s)
    left = p.neutral[p.index(left_leaf), 3, :3] - p.neutral[p.index(right_leaf), 3, :3]
    left -= left.dot(up_s) * up_s
    f = np.cross(left, up_s)
    return f / np.linalg.norm(f)


def local_forward(p: Posed, leaf: str, forward_skel: np.ndarray) -> np.ndarray:
    """The joint-local axis that points along the character forward in the neutral (bind) pose."""
    m = p.neutral[p.index(leaf), :3, :3]
    v = np.linalg.solve(m.T, forward_skel)  # v @ m = forward
    return v / np.linalg.norm(v)


def az_el(d: np.ndarray, up: np.ndarray) -> np.ndarray:
    """Azimuth (counter-clockwise seen from above) and elevation, degrees."""
    if abs(up[2]) > 0.5:  # Z up: x, y horizontal
        e1, e2 = np.array([1.0, 0, 0]), np.array([0, 1.0, 0])
    else:  # Y up: (x, -z) keeps (e1, e2, up) right-handed
        e1, e2 = np.array([1.0, 0, 0]), np.array([0, 0, -1.0])
    az = np.degrees(np.arctan2(d @ e2, d @ e1))
    el = np.degrees(np.arcsin(np.clip(d @ up, -1, 1)))
    return np.stack([az, el], axis=-1)


def wrap(a: np.ndarray) -> np.ndarray:
    return (a + 180.0) % 360.0 - 180.0


def sight_line(p: Posed, left_eye: str, right_eye: str, eye_axis_l, eye_axis_r) -> np.ndarray:
    """Line of sight: from the eyes' midpoint to the midpoint of the two gaze rays' closest approach.

    Parallel rays have no closest approach (every pair of points is the perpendicular distance apart):
    they meet at infinity, so the line of sight there is their common direction (none, NaN, when
    they point opposite ways).
    """
    pl, pr = p.position(left_eye), p.position(right_eye)
    dl, dr = p.axis(left_eye, eye_axis_l), p.axis(right_eye, eye_axis_r)
    w0 = pl - pr
    a, b, c = (dl * dl).sum(-1), (dl * dr).sum(-1), (dr * dr).sum(-1)
    d, e = (dl * w0).sum(-1), (dr * w0).sum(-1)
    den = a * c - b * b  # |dl x dr|^2: sin^2 of the angle between the rays, times a * c
    parallel = den <= 1e-12 * a * c
    safe = np.where(parallel, 1.0, den)
    s = (b * e - c * d) / safe
    t = (a * e - b * d) / safe
    point = 0.5 * (pl + s[:, None] * dl + pr + t[:, None] * dr)
    v = point - 0.5 * (pl + pr)
    common = dl / np.sqrt(a)[:, None] + dr / np.sqrt(c)[:, None]
    # Opposite directions (b < 0) look nowhere in common: no line of sight.
    v = np.where(parallel[:, None], np.where(b[:, None] > 0, common, np.nan), v)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def gaze_change(base: Posed, new: Posed, fwd: np.ndarray, head: str = "Head",
                eyes: tuple[str, str] = ("LeftEye", "RightEye"), sight=sight_line):
    """The (yaw, pitch) change, degrees per frame, of ``new``'s line of sight (``sight``, from its two
    eyes' forward axes) against ``base``'s head direction; and that head direction and the sight."""
    head_dir = base.axis(head, local_forward(base, head, fwd))
    left, right = eyes
    line = sight(new, left, right, local_forward(new, left, fwd), local_forward(new, right, fwd))
    a, b = az_el(line, new.up), az_el(head_dir, base.up)
    return np.column_stack([wrap(a[:, 0] - b[:, 0]), a[:, 1] - b[:, 1]]), head_dir, line


def angle_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Degrees between unit vectors, row by row."""
    return np.degrees(np.arccos(np.clip((a * b).sum(-1), -1, 1)))


def eye_miss_deg(p: Posed, eye: str, forward_skel: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Per frame, degrees between the eye's forward (its bind-pose ``forward_skel`` carried by FK) and
    the direction from the eye to ``target`` (one point, or one per frame)."""
    to_target = target - p.position(eye)
    to_target = to_target / np.linalg.norm(to_target, axis=-1, keepdims=True)
    return angle_between(p.axis(eye, local_forward(p, eye, forward_skel)), to_target)


def rotation_angle_deg(m_a: np.ndarray, m_b: np.ndarray) -> np.ndarray:
    """Angle of the rotation between two stacks of 3x3 rotation(-ish) matrices."""
    def unit(m):
        return m / np.linalg.norm(m, axis=-1, keepdims=True)
    r = np.einsum("fij,fkj->fik", unit(m_a), unit(m_b))
    return np.degrees(np.arccos(np.clip((np.trace(r, axis1=1, axis2=2) - 1) / 2, -1, 1)))


def eye_in_head(p: Posed, head: str, eye: str, forward, left, up) -> tuple[np.ndarray, np.ndarray]:
    """Eye-in-head yaw (+ toward the left) and pitch (+ up), degrees, per frame.

    ``forward``/``left``/``up`` are the character axes in skeleton space; each joint's local axes
    are taken from the neutral (bind) pose, where the eyes look straight ahead.
    """
    f, l, u = (p.axis(head, local_forward(p, head, v)) for v in (forward, left, up))
    d = p.axis(eye, local_forward(p, eye, forward))
    yaw = np.degrees(np.arctan2((d * l).sum(-1), (d * f).sum(-1)))
    pitch = np.degrees(np.arcsin(np.clip((d * u).sum(-1), -1, 1)))
    return yaw, pitch


def lowest_capsule_point(p: Posed, leaf: str, capsules, radius: float, meters_per_unit: float) -> np.ndarray:
    """Per frame, the height in metres above the stage's ground (up = 0) of the lowest surface point of
    capsules fixed to a joint: each ``(a, b)`` a segment in metres in the joint's frame (orthonormalized:
    the frame's rotation, its scale removed), ``radius`` metres. A capsule's lowest point is the lower
    of its two end points, minus the radius."""
    m = p.world[:, p.index(leaf)]
    u, _, vt = np.linalg.svd(m[:, :3, :3])
    rot = u @ vt  # row vectors: world direction = v @ rot
    origin = m[:, 3, :3] @ p.up * meters_per_unit
    ends = np.array([[a, b] for a, b in capsules], dtype=float).reshape(-1, 3)
    return origin + np.einsum("ej,fjk,k->fe", ends, rot, p.up).min(axis=1) - radius
