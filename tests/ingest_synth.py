"""Synthetic gaze capture sessions with known ground truth, for the build-map tests and benchmark.

A subject does Heck's 33-trial protocol (5.2.1: yaw every 36 deg from -180 to 180, pitch -12/0/+12,
60 Hz). Each trial's gaze motion is a *known* :class:`usdgaze.gaze.motion.GazeMotions` built here from
plausible head-eye-trunk numbers; the markers (or the joints of a small Mixamo-named rig) are
animated by forward kinematics of a four-segment spine chain driven by
:meth:`GazeMotions.displacement`, so every marker position follows exactly from the known motion.
Captures get marker noise, occlusion gaps, postural sway (a translation, removed by stabilization)
and rest periods of random length before and after, and are written as real C3D files (mm).

Nothing here calls :mod:`usdgaze.ingest`: the ground truth is independent of the code under test.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from usdgaze.gaze import motion
from usdgaze.core import rotations as rot
from usdgaze.gaze.motion import GazeMotions

RATE = 60.0
YAWS = np.arange(-180.0, 180.0 + 1e-9, 36.0)
PITCHES = (-12.0, 0.0, 12.0)
NOISE_RMS_MM = 0.5
"""Marker noise: root-mean-square 3D position error (the jitter measured on the vendor files in
tests/data/c3d is 0.03-0.11 mm per axis, so this is 3-10 times worse than real captures)."""
NOISE_MM = NOISE_RMS_MM / np.sqrt(3.0)
"""Standard deviation of the marker noise on each axis."""
GAPS = 4
"""Occlusion gaps per trial (2-8 frames each, on random markers)."""
START_THRESHOLD_DEG_S = 18.0

# -- the body: chain joints and markers in the canonical frame at rest (mm; X left, Y up, Z fwd) --
JOINTS = np.array([
    [0.0, 0.0, 0.0],        # pelvis (lumbosacral)
    [0.0, 130.0, -25.0],    # lower spine (L1)
    [0.0, 310.0, -40.0],    # upper spine (T6)
    [0.0, 490.0, -20.0],    # neck base (C7), the head's pivot
])
MARKERS = {  # label: (segment, rest position)
    "BOS": (0, (0.0, -60.0, -105.0)),
    "LB1": (0, (70.0, 20.0, -120.0)),
    "LB2": (0, (-70.0, 20.0, -120.0)),
    "LB3": (0, (0.0, 141.0, -110.0)),
    "UB1": (1, (70.0, 200.0, -138.0)),
    "UB2": (1, (-70.0, 200.0, -138.0)),
    "UB3": (1, (0.0, 321.0, -126.0)),
    "NB1": (2, (65.0, 380.0, -118.0)),
    "NB2": (2, (-65.0, 380.0, -118.0)),
    "NB3": (2, (0.0, 492.0, -98.0)),
    "LSHO": (2, (185.0, 430.0, -40.0)),
    "RSHO": (2, (-185.0, 430.0, -40.0)),
    "LELB": (2, (215.0, 140.0, -50.0)),
    "RELB": (2, (-215.0, 140.0, -50.0)),
    "HLF": (3, (85.0, 705.0, 90.0)),
    "HLB": (3, (85.0, 715.0, -75.0)),
    "HRB": (3, (-85.0, 715.0, -75.0)),
    "HRF": (3, (-85.0, 705.0, 90.0)),
    "HTOP": (3, (0.0, 790.0, 15.0)),
    "EYE": (3, (0.0, 640.0, 105.0)),
}
LABELS = tuple(MARKERS)
MARKERSET_TOML = """\
# Marker set of the synthetic subject (tests/ingest_synth.py); lab up axis Z as C3D labs use.
up_axis = "Z"

[markers]
lower_back = ["LB1", "LB2", "LB3"]
upper_back = ["UB1", "UB2", "UB3"]
neck_base = ["NB1", "NB2", "NB3"]
head = ["HLF", "HLB", "HRB", "HRF"]
head_top = "HTOP"
base_of_spine = "BOS"
"""

# Where the subject stands in the lab (Z up): position of the pelvis joint and heading.
LAB_ORIGIN = np.array([420.0, -310.0, 960.0])
LAB_HEADING_DEG = 27.0  # forward is the lab +X axis turned this much toward +Y
HEAD_REST_PITCH_DEG = -6.0  # the hat sits tilted; the canonical frame takes only its heading


def lab_frame(heading_deg: float = LAB_HEADING_DEG) -> np.ndarray:
    """Quaternion taking canonical vectors to the lab (Z up)."""
    h = np.radians(heading_deg)
    forward = np.array([np.cos(h), np.sin(h), 0.0])
    up = np.array([0.0, 0.0, 1.0])
    return rot.frame_rotation(np.cross(up, forward), up, forward)


# -- known gaze motions ----------------------------------------------------------------------------
def protocol() -> np.ndarray:
    """The 33 targets (yaw, pitch), row by row."""
    return np.array([(y, p) for p in PITCHES for y in YAWS])


def known_motions(params: np.ndarray, seed: int = 7) -> GazeMotions:
    """Plausible gaze motions for targets ``(E, 2)``.

    Eyes take small shifts alone and plateau near 30 deg; the head and then the trunk take shares
    rising with amplitude; this subject twists the trunk more to the right (Heck's was asymmetric
    too); pitch is split eyes/neck/upper spine. Onsets cascade eyes -> neck -> upper spine -> lower
    spine -> pelvis, all before the overshoot peak.
    """
    rng = np.random.default_rng(seed)
    yaw, pitch = params[:, 0], params[:, 1]
    a = np.abs(yaw)
    eye_yaw = np.sign(yaw) * np.minimum(0.8 * a, 28.0 + 0.02 * a)
    body_yaw = yaw - eye_yaw
    trunk_share = np.clip((np.abs(body_yaw) - 15.0) / 180.0, 0.0, 0.5) * np.where(yaw < 0, 1.2, 0.85)
    trunk_yaw = body_yaw * trunk_share
    neck_yaw = body_yaw - trunk_yaw
    seg_yaw = np.stack([0.3 * trunk_yaw, 0.25 * trunk_yaw, 0.45 * trunk_yaw, neck_yaw], axis=1)
    seg_pitch = np.stack([0 * pitch, 0.02 * pitch, 0.1 * pitch, 0.4 * pitch], axis=1)
    seg_roll = np.stack([0.02 * yaw, -0.015 * yaw, 0.01 * yaw, 0.03 * yaw], axis=1)  # small leans
    body = rot.multiply(rot.yaw_pitch_rotation(seg_yaw, seg_pitch), rot.from_axis_angle(rot.FORWARD, np.radians(seg_roll)))
    eyes = motion.aim_eyes(body, yaw, pitch)
    offsets = np.concatenate([body, eyes[:, None]], axis=1)

    n = len(params)
    amplitude = np.hypot(yaw, pitch)
    timing = np.zeros((n, len(motion.TIMING_FIELDS)))
    timing[:, motion.DURATION] = 0.55 + 0.0045 * amplitude + rng.uniform(0.0, 0.1, n)
    neck = rng.uniform(0.03, 0.07, n)
    upper = neck + rng.uniform(0.04, 0.08, n)
    lower = upper + rng.uniform(0.03, 0.06, n)
    pelvis = lower + rng.uniform(0.03, 0.06, n)
    timing[:, motion.START_SLICE] = np.stack([pelvis, lower, upper, neck], axis=1)
    timing[:, motion.PEAK] = rng.uniform(0.5, 0.62, n)
    timing[:, motion.BETA] = 0.04 + 0.0004 * a + rng.uniform(0.0, 0.04, n)
    still = amplitude == 0
    offsets[still] = rot.IDENTITY
    return GazeMotions(offsets, timing)


def chain_displacements(m: GazeMotions, t: np.ndarray) -> np.ndarray:
    """Global displacements ``(F, 4, 4)`` of pelvis, lower spine, upper spine and head (canonical frame)."""
    d = m.displacement(t)[..., :4, :]
    g = d.copy()
    for j in range(1, 4):
        g[:, j] = rot.multiply(g[:, j - 1], d[:, j])
    return g


def pose_markers(g: np.ndarray) -> np.ndarray:
    """Canonical marker positions ``(F, M, 3)`` for chain displacements ``g (F, 4, 4)``."""
    joints = np.empty((len(g), 4, 3))
    joints[:, 0] = JOINTS[0]
    for j in range(1, 4):
        joints[:, j] = joints[:, j - 1] + rot.rotate(g[:, j - 1], JOINTS[j] - JOINTS[j - 1])
    seg = np.array([MARKERS[k][0] for k in LABELS])
    rest = np.array([MARKERS[k][1] for k in LABELS], dtype=float)
    head = seg == 3
    # the hat is pitched on the head: rotate head markers about the head centre at rest
    centre = np.array([0.0, 700.0, 10.0])
    tilt = rot.from_axis_angle(-rot.LEFT, np.radians(HEAD_REST_PITCH_DEG))
    rest[head] = centre + rot.rotate(tilt, rest[head] - centre)
    return joints[:, seg] + rot.rotate(g[:, seg], rest - JOINTS[seg])


# -- one trial -------------------------------------------------------------------------------------
@dataclass
class TrialTruth:
    """A synthetic trial and its ground truth."""

    name: str
    yaw: float
    pitch: float
    motion: GazeMotions
    onset: int
    """Frame at which the gaze shift starts (normalized time 0)."""
    frames: int
    rate: float
    file: Path | None = None
    crop: tuple[int, int] | None = None

    def frame_of(self, t: np.ndarray | float) -> np.ndarray:
        """Absolute frame (fractional) of normalized time ``t``."""
        return self.onset + np.asarray(t) * self.motion.duration * self.rate

    @property
    def peak_frame(self) -> float:
        return float(self.frame_of(self.motion.peak_time))

    def local_speeds(self, samples: int = 20001) -> tuple[np.ndarray, np.ndarray]:
        """Exact local angular speed (deg/s) of the four chain segments on a dense time grid.

        Each segment turns about its fixed P+ axis relative to its parent, so its speed is the P+
        angle times the rate of its profile; returns normalized times ``(S,)`` and speeds ``(S, 4)``.
        """
        t = np.linspace(0.0, 1.0, samples)
        s = self.motion.profiles(t)[:, :4]
        ds = np.gradient(s, t, axis=0) / float(self.motion.duration)
        return t, np.degrees(rot.angle(self.motion.offsets[:4]))[None, :] * np.abs(ds)

    @property
    def head_overshoot_deg(self) -> float:
        """How far the head's global rotation goes past its final rotation at the peak (degrees)."""
        g = chain_displacements(self.motion, np.array([float(self.motion.peak_time), 1.0]))[:, 3]
        return float(np.degrees(rot.angle(g[0]) - rot.angle(g[1])))

    def threshold_start_frames(self, threshold: float = START_THRESHOLD_DEG_S) -> np.ndarray:
        """Per chain segment, the first instant its exact local angular speed exceeds ``threshold``.

        Heck's start is a threshold crossing, which an ease-in reaches after the model's t_j; this is
        that crossing on the noise-free motion (dense sampling of the known profile), in absolute
        fractional frames, or NaN where the speed never exceeds the threshold.
        """
        t, speed = self.local_speeds()
        out = np.full(4, np.nan)
        for j in range(4):
            hit = np.flatnonzero(speed[:, j] > threshold)
            if len(hit):
                out[j] = self.frame_of(t[hit[0]])
        return out


def simulate_trial(m: GazeMotions, rng: np.random.Generator, rate: float = RATE, rest_before: float | None = None,
                   rest_after: float | None = None, noise: float = NOISE_MM, gaps: int = GAPS,
                   total_s: float | None = None) -> tuple[np.ndarray, int]:
    """Lab marker trajectories ``(F, M, 3)`` in mm (NaN in gaps) and the onset frame."""
    rest_before = rng.uniform(0.8, 1.5) if rest_before is None else rest_before
    rest_after = rng.uniform(1.0, 1.6) if rest_after is None else rest_after
    onset = int(round(rest_before * rate))
    length = rest_before + float(m.duration) + rest_after
    if total_s is not None:
        length = max(length, total_s)
    frames = int(round(length * rate)) + 1
    t = (np.arange(frames) - onset) / (float(m.duration) * rate)
    canonical = pose_markers(chain_displacements(m, t))
    sway = 10.0 * np.sin(2 * np.pi * 0.3 * np.arange(frames) / rate + rng.uniform(0, 6.3))[:, None] * np.array([1.0, 0.4, 0.1])
    lab = LAB_ORIGIN + rot.rotate(lab_frame(), canonical) + sway[:, None, :]
    lab = lab + rng.normal(0.0, noise, lab.shape)
    for _ in range(gaps):
        marker = rng.integers(0, len(LABELS))
        length_gap = int(rng.integers(2, 9))
        start = int(rng.integers(1, frames - length_gap - 1))
        lab[start : start + length_gap, marker] = np.nan
    return lab, onset


def trial_name(yaw: float, pitch: float) -> str:
    return f"y{yaw:+04.0f}_p{pitch:+03.0f}"


@dataclass
class Session:
    """A written session: its sheet, marker set and per-trial truth, in sheet order."""

    directory: Path
    sheet: Path
    markerset: Path | None
    trials: list[TrialTruth]
    params: np.ndarray
    motions: GazeMotions


def write_sheet(path: Path, trials: list[TrialTruth]) -> None:
    """The CSV trial sheet of a session (manual crops where the truth has one)."""
    with path.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["trial", "file", "yaw", "pitch", "crop_start", "crop_end"])
        for tr in trials:
            crop = tr.crop or ("", "")
            w.writerow([tr.name, tr.file.name, f"{tr.yaw:g}", f"{tr.pitch:g}", *crop])


def write_c3d_session(directory: Path, seed: int = 0, rate: float = RATE, params: np.ndarray | None = None,
                      total_s: float | None = None, noise: float = NOISE_MM) -> Session:
    """Write one C3D file per protocol trial, a CSV sheet and the marker set into ``directory``."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    params = protocol() if params is None else np.asarray(params, dtype=float)
    motions = known_motions(params)
    rng = np.random.default_rng(seed)
    trials = []
    for i, (yaw, pitch) in enumerate(params):
        m = motions[i]
        points, onset = simulate_trial(m, rng, rate=rate, total_s=total_s, noise=noise)
        tr = TrialTruth(trial_name(yaw, pitch), float(yaw), float(pitch), m, onset, len(points), rate)
        tr.file = directory / f"{tr.name}.c3d"
        write_points(tr.file, LABELS, points, rate)
        if yaw == 0 and pitch == 0:  # no motion: Heck crops this one by hand
            tr.crop = (onset, len(points) - 1)
        trials.append(tr)
    sheet = directory / "sheet.csv"
    write_sheet(sheet, trials)
    markerset = directory / "markerset.toml"
    markerset.write_text(MARKERSET_TOML)
    return Session(directory, sheet, markerset, trials, params, motions)


def write_points(path: Path, labels, points: np.ndarray, rate: float, units: str = "mm") -> None:
    """A C3D file with ezc3d directly (not through usdgaze), NaN samples as gaps."""
    import ezc3d  # the test extra: real C3D files, written without the code under test

    c3d = ezc3d.c3d()
    c3d["parameters"]["POINT"]["RATE"]["value"] = [float(rate)]
    c3d["parameters"]["POINT"]["LABELS"]["value"] = tuple(labels)
    c3d["parameters"]["POINT"]["UNITS"]["value"] = [units]
    data = np.ones((4, points.shape[1], points.shape[0]))
    data[:3] = np.transpose(points, (2, 1, 0))
    c3d["data"]["points"] = data
    c3d.write(str(path))


# -- skeletal examples (UsdSkel) ---------------------------------------------------------------------
SKEL_JOINTS = (  # Mixamo names; which chain segment drives each joint and with what share of it
    ("Hips", None, 0, 1.0),
    ("Hips/Spine", 0, 1, 1.0),
    ("Hips/Spine/Spine1", 1, 2, 0.5),
    ("Hips/Spine/Spine1/Spine2", 2, 2, 0.5),
    ("Hips/Spine/Spine1/Spine2/Neck", 3, 3, 0.4),
    ("Hips/Spine/Spine1/Spine2/Neck/Head", 4, 3, 0.6),
    ("Hips/LeftUpLeg", 0, None, 0.0),
    ("Hips/RightUpLeg", 0, None, 0.0),
    ("Hips/Spine/Spine1/Spine2/LeftShoulder", 3, None, 0.0),
    ("Hips/Spine/Spine1/Spine2/RightShoulder", 3, None, 0.0),
)
SKEL_REST_CM = np.array([  # canonical rest positions (cm)
    [0.0, 100.0, 0.0], [0.0, 110.0, -2.0], [0.0, 122.0, -3.5], [0.0, 134.0, -4.0], [0.0, 149.0, -2.0],
    [0.0, 158.0, 0.0], [9.0, 95.0, 0.0], [-9.0, 95.0, 0.0], [6.0, 144.0, -3.0], [-6.0, 144.0, -3.0],
])


def skel_globals(m: GazeMotions, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Canonical global displacements ``(F, J, 4)`` and joint positions ``(F, J, 3)`` (cm) of the rig."""
    d = m.displacement(t)[..., :4, :]
    f = len(t)
    n = len(SKEL_JOINTS)
    g = np.empty((f, n, 4))
    pos = np.empty((f, n, 3))
    for i, (_, parent, seg, share) in enumerate(SKEL_JOINTS):
        own = rot.power(d[:, seg], share) if seg is not None else rot.identity((f,))
        if parent is None:
            g[:, i] = own
            pos[:, i] = SKEL_REST_CM[i]
        else:
            g[:, i] = rot.multiply(g[:, parent], own)
            pos[:, i] = pos[:, parent] + rot.rotate(g[:, parent], SKEL_REST_CM[i] - SKEL_REST_CM[parent])
    return g, pos


SKEL_FRAME_UP = np.array([0.0, 0.0, 1.0])  # Z-up stage, character facing -Y (Blender's convention)
SKEL_FRAME_FORWARD = np.array([0.0, -1.0, 0.0])


def write_skel_clip(path: Path, m: GazeMotions, onset: int, frames: int, rate: float = RATE,
                    rename: dict[str, str] | None = None) -> None:
    """A UsdSkel clip (SkelRoot, Skeleton, SkelAnimation) of the rig doing motion ``m``.

    ``rename`` maps Mixamo joint names to others (e.g. ``{"Hips": "mixamorig_Hips"}``).
    """
    from pxr import Gf, Sdf, Usd, UsdGeom, UsdSkel, Vt

    c = rot.frame_rotation(np.cross(SKEL_FRAME_UP, SKEL_FRAME_FORWARD), SKEL_FRAME_UP, SKEL_FRAME_FORWARD)
    t = (np.arange(frames) - onset) / (float(m.duration) * rate)
    g, pos = skel_globals(m, t)
    # Skeleton-space joint orientations: the displacement (canonical, carried into skeleton space)
    # applied on top of each joint's rest orientation, which is deliberately not aligned with anything.
    rest = rot.from_rotvec(np.random.default_rng(99).normal(0.0, 0.5, (len(SKEL_JOINTS), 3)))
    world_rot = rot.multiply(rot.conjugate_into(c, g), rest)
    world_pos = rot.rotate(c, pos)
    rename = rename or {}
    names = ["/".join(rename.get(part, part) for part in j[0].split("/")) for j in SKEL_JOINTS]
    parents = [j[1] for j in SKEL_JOINTS]
    local_rot = world_rot.copy()
    local_pos = world_pos.copy()
    for i, p in enumerate(parents):
        if p is not None:
            local_rot[:, i] = rot.relative(world_rot[:, p], world_rot[:, i])
            local_pos[:, i] = rot.rotate(rot.conjugate(world_rot[:, p]), world_pos[:, i] - world_pos[:, p])

    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, 0.01)
    stage.SetTimeCodesPerSecond(rate)
    stage.SetStartTimeCode(0)
    stage.SetEndTimeCode(frames - 1)
    root = UsdSkel.Root.Define(stage, "/Rig")
    stage.SetDefaultPrim(root.GetPrim())
    skel = UsdSkel.Skeleton.Define(stage, "/Rig/Skel")
    skel.CreateJointsAttr(names)
    rest = []
    for i in range(len(names)):
        mtx = rot.compose_trs(local_pos[0, i], local_rot[0, i], np.ones(3))
        rest.append(Gf.Matrix4d(*rot.matrices_to_usd(mtx).ravel().tolist()))
    skel.CreateRestTransformsAttr(rest)
    bind = []
    for i in range(len(names)):
        mtx = rot.compose_trs(world_pos[0, i], world_rot[0, i], np.ones(3))
        bind.append(Gf.Matrix4d(*rot.matrices_to_usd(mtx).ravel().tolist()))
    skel.CreateBindTransformsAttr(bind)
    anim = UsdSkel.Animation.Define(stage, "/Rig/Skel/Anim")
    anim.CreateJointsAttr(names)
    UsdSkel.BindingAPI.Apply(skel.GetPrim()).CreateAnimationSourceRel().SetTargets([anim.GetPath()])
    tr_attr = anim.CreateTranslationsAttr()
    rot_attr = anim.CreateRotationsAttr()
    anim.CreateScalesAttr().Set(Vt.Vec3hArray.FromNumpy(np.ones((len(names), 3), dtype=np.float16)))
    layer = stage.GetRootLayer()
    stage.Save()
    tr_path = tr_attr.GetPath()
    rot_path = rot_attr.GetPath()
    with Sdf.ChangeBlock():
        for f in range(frames):
            layer.SetTimeSample(tr_path, float(f), Vt.Vec3fArray.FromNumpy(local_pos[f].astype(np.float32)))
            layer.SetTimeSample(rot_path, float(f), Vt.QuatfArray.FromNumpy(local_rot[f].astype(np.float32)))
    layer.Save()


def write_skel_session(directory: Path, seed: int = 1, rate: float = RATE, params: np.ndarray | None = None) -> Session:
    """One UsdSkel clip per protocol trial (rests before and after, no noise: keyframe-like) and a TOML sheet."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    params = protocol() if params is None else np.asarray(params, dtype=float)
    motions = known_motions(params)
    rng = np.random.default_rng(seed)
    trials = []
    lines = []
    for i, (yaw, pitch) in enumerate(params):
        m = motions[i]
        onset = int(round(rng.uniform(0.5, 1.0) * rate))
        frames = onset + int(round((float(m.duration) + rng.uniform(0.6, 1.0)) * rate)) + 1
        tr = TrialTruth(trial_name(yaw, pitch), float(yaw), float(pitch), m, onset, frames, rate)
        tr.file = directory / f"{tr.name}.usda"
        write_skel_clip(tr.file, m, onset, frames, rate)
        if yaw == 0 and pitch == 0:
            tr.crop = (onset, frames - 1)
        trials.append(tr)
        crop = f"crop = [{tr.crop[0]}, {tr.crop[1]}]\n" if tr.crop else ""
        lines.append(f'[[trial]]\nname = "{tr.name}"\nfile = "{tr.file.name}"\nyaw = {yaw:g}\npitch = {pitch:g}\n{crop}')
    sheet = directory / "sheet.toml"
    sheet.write_text("\n".join(lines))
    return Session(directory, sheet, None, trials, params, motions)
