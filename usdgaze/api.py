"""The Python API of the gaze pass: read stage -> arrays -> model -> arrays -> write layer."""

from __future__ import annotations

import os
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from usdgaze import __version__
from usdgaze.core import rotations as rot
from usdgaze.usd import schema
from usdgaze.core.clip import SkelClip
from usdgaze.gaze.defaults import default_definition
from usdgaze.gaze.definition import GazeMapDefinition
from usdgaze.errors import UsdGazeError
from usdgaze.gaze.gazemap import ParametricGazeMap
from usdgaze.passes.shift import PassOptions, PassResult, Shift, apply_gaze
from usdgaze.usd.layers import (
    AnimOverride,
    LayerInfo,
    atomic_export,
    build_override,
    check_output_path,
    check_sublayer_target,
    insert_sublayer,
    write_preview,
)
from usdgaze.core.hints import BindHints
from usdgaze.core.rig import Chain, CharacterFrame, bind_chain, character_frame

_SHIFT = re.compile(r"^\s*([-+]?[0-9]*\.?[0-9]+(?:[eE][-+]?[0-9]+)?)(s?)\s*:\s*([-+]?[0-9]*\.?[0-9]+)\s*:\s*([-+]?[0-9]*\.?[0-9]+)\s*$")


@dataclass(frozen=True)
class ShiftRequest:
    """A shift as the user wrote it: at a time code, or at seconds from the stage start."""

    time: float
    seconds: bool
    yaw: float
    pitch: float

    @classmethod
    def parse(cls, text: str) -> "ShiftRequest":
        """Parse ``TIME:YAW:PITCH`` (``TIME`` a time code, or seconds with an ``s`` suffix)."""
        m = _SHIFT.match(text)
        if not m:
            raise UsdGazeError(f"--shift '{text}': expected TIME:YAW:PITCH, e.g. 48:60:-10 or 2.5s:60:-10")
        shift = cls(float(m.group(1)), m.group(2) == "s", float(m.group(3)), float(m.group(4)))
        if not all(np.isfinite([shift.time, shift.yaw, shift.pitch])):
            raise UsdGazeError(f"--shift '{text}': values must be finite")
        if abs(shift.pitch) > 90.0:
            raise UsdGazeError(f"--shift '{text}': pitch must lie in [-90, 90] deg")
        if abs(shift.yaw) > 360.0:
            raise UsdGazeError(f"--shift '{text}': yaw must lie in [-360, 360] deg (more than a full turn is no gaze shift)")
        return shift

    def to_shift(self, clip: SkelClip) -> Shift:
        seconds = self.time if self.seconds else (self.time - clip.start_time) / clip.time_codes_per_second
        return Shift(seconds, self.yaw, self.pitch)

    def __str__(self) -> str:
        return f"{self.time:g}{'s' if self.seconds else ''}:{self.yaw:g}:{self.pitch:g}"


@dataclass
class CharacterReport:
    """What the pass did to one skeleton."""

    skel_root: str
    skeleton: str
    animation: str
    map_source: str
    chain: dict[str, list[str]]
    forward: list[float]
    frames: int
    added_joints: list[str]
    result: PassResult


@dataclass
class ApplyReport:
    output: str
    characters: list[CharacterReport] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    preview: str | None = None
    sublayered_into: str | None = None


def select_roots(stage, source: str, skel_root: str | None):
    """The SkelRoots to work on: the named one, else every one with a GazeMapAPI, else the only one."""
    from pxr import Sdf, UsdSkel

    from usdgaze.usd.skelio import skel_roots

    if skel_root:
        if not Sdf.Path.IsValidPathString(skel_root) or not (Sdf.Path(skel_root).IsAbsolutePath()
                                                               and Sdf.Path(skel_root).IsPrimPath()):
            raise UsdGazeError(f"{source}: --skel-root '{skel_root}' is not an absolute prim path such as /Character")
        prim = stage.GetPrimAtPath(skel_root)
        if not prim or not prim.IsValid():
            raise UsdGazeError(f"{source}:{skel_root}: no such prim")
        if not prim.IsA(UsdSkel.Root):
            raise UsdGazeError(f"{source}:{skel_root}: is a {prim.GetTypeName() or 'typeless prim'}, not a SkelRoot")
        return [prim]
    roots = skel_roots(stage)
    if not roots:
        raise UsdGazeError(f"{source}: no SkelRoot on the stage")
    with_map = [r for r in roots if schema.has_map(r)]
    if with_map:
        return with_map
    if len(roots) > 1:
        listed = ", ".join(str(r.GetPath()) for r in roots[:6])
        raise UsdGazeError(f"{source}: {len(roots)} SkelRoots and none has a GazeMapAPI; pick one with --skel-root ({listed})")
    return roots


def _map_key(definition: GazeMapDefinition) -> bytes:
    """Content key: characters sharing one map (by composition) build it once."""
    m = definition.motions
    return b"|".join([definition.params.tobytes(), m.offsets.tobytes(), m.timing.tobytes(),
                      repr(definition.settings).encode()])


def _character_frame(clip: SkelClip, forward, label: str) -> CharacterFrame:
    sw = clip.skel_to_world[0, :3, :3]
    up_s = rot.normalize(np.linalg.solve(sw, clip.world_up))
    return character_frame(clip.joints, clip.neutral(), up_s, forward, where=f"{clip.source}:{clip.skeleton}",
                           forward_label=label)


def bind(clip: SkelClip, definition: GazeMapDefinition | None, hints: BindHints | None = None
         ) -> tuple[Chain, CharacterFrame]:
    """Chain and character frame of a clip: the user's hints first, then the map's bindings, then names."""
    hints = hints or BindHints()
    bindings = dict(definition.bindings) if definition else {}
    labels = {role: f"gaze:binding:{role}" for role in bindings}
    for role, joints in hints.bindings:
        bindings[role], labels[role] = joints, f"{hints.bind_label} {role}={'+'.join(joints)}"
    forward, label = (hints.forward, hints.forward_label) if hints.forward is not None else (
        definition.forward if definition else None, "gaze:binding:forward")
    chain = bind_chain(clip.joints, clip.parents, bindings, where=f"{clip.source}:{clip.skeleton}", labels=labels)
    return chain, _character_frame(clip, forward, label)


def apply(
    input_path: str | os.PathLike,
    shifts: list[ShiftRequest | str],
    out: str | os.PathLike,
    skel_root: str | None = None,
    map_spec: str | None = None,
    sublayer_into: str | os.PathLike | None = None,
    preview: str | os.PathLike | None = None,
    options: PassOptions = PassOptions(),
    progress=None,
) -> ApplyReport:
    """Add gaze shifts to the skeletal animation(s) of ``input_path``; write ``out`` as an override layer.

    Nothing is written unless everything succeeds; the input is never modified (``sublayer_into``
    changes only that layer's subLayers).
    """
    from usdgaze.usd.skelio import open_stage, read_clip, skeletons_under

    source = str(input_path)
    if not Path(source).is_file():
        raise UsdGazeError(f"{source}: no such file")
    out_path = check_output_path(out)
    if preview is not None:
        check_output_path(preview)
    if sublayer_into is not None and preview is not None:
        raise UsdGazeError("--sublayer-into and --preview are alternatives; pass one")
    # --sublayer-into may name the input (it is then refused for holding the animation's own
    # opinions); --out and --preview never may.
    for flag, path in (("--out", out_path), ("--preview", preview)):
        if path is not None and os.path.abspath(path) == os.path.abspath(source):
            raise UsdGazeError(f"{path}: {flag} would overwrite the input")
    requests = [s if isinstance(s, ShiftRequest) else ShiftRequest.parse(s) for s in shifts]
    if not requests:
        raise UsdGazeError("no --shift given; nothing to do")

    stage = open_stage(source)
    roots = select_roots(stage, source, skel_root)
    forced = schema.load_map(map_spec) if map_spec else None
    maps: dict[bytes, ParametricGazeMap] = {}
    report = ApplyReport(output=str(out_path))
    overrides: list[AnimOverride] = []
    seen_anims: dict[str, str] = {}
    info: LayerInfo | None = None

    for root in roots:
        own = schema.read_map(root, source) if schema.has_map(root) else None
        definition = forced or own or default_definition()
        map_source = map_spec if forced else (f"{source}:{root.GetPath()} (GazeMapAPI)" if own else f"built-in default (usdgaze {__version__})")
        key = _map_key(definition)
        gaze_map = maps.get(key)
        if gaze_map is None:
            gaze_map = maps[key] = ParametricGazeMap(definition)
        skels = skeletons_under(root)
        if not skels:
            raise UsdGazeError(f"{source}:{root.GetPath()}: no Skeleton under this SkelRoot")
        for skel in skels:
            clip = read_clip(stage, skel, root, source)
            if clip.animation in seen_anims:
                raise UsdGazeError(
                    f"{source}:{clip.animation}: drives both {seen_anims[clip.animation]} and {clip.skeleton}; "
                    "give each skeleton its own SkelAnimation or pick one with --skel-root"
                )
            seen_anims[clip.animation] = clip.skeleton
            chain, frame = bind(clip, own, options.binding)
            if clip.neutral_source.startswith("restTransforms (") and "not authored" not in clip.neutral_source:
                report.warnings.append(f"{clip.source}:{clip.skeleton}: neutral pose from {clip.neutral_source}")
            result = apply_gaze(clip, chain, frame, gaze_map, [r.to_shift(clip) for r in requests], options)
            for r in requests:
                if r.to_shift(clip).time_s > clip.seconds[-1]:
                    report.warnings.append(
                        f"{clip.where()}: shift {r} starts at {r.to_shift(clip).time_s:g} s, after the animation's "
                        f"last sample ({clip.seconds[-1]:g} s); it changes nothing"
                    )
            report.warnings.extend(result.warnings)
            override = AnimOverride(
                animation=clip.animation,
                times=clip.times,
                joints=result.anim_joints,
                rotations=result.rotations,
                translations=result.translations if (chain.leg_roots or result.added_joints
                                                     or len(result.anim_joints) > len(clip.anim_joints)) else None,
                scales=result.scales if len(result.anim_joints) > len(clip.anim_joints) else None,
                write_joints=len(result.anim_joints) > len(clip.anim_joints),
            )
            if result.added_joints:
                override.skeleton = clip.skeleton
                override.skeleton_joints = clip.joints + result.added_joints
                override.rest_transforms = np.concatenate([clip.rest_local, result.added_rest_local])
                override.bind_transforms = np.concatenate([clip.bind_world, result.added_bind_world])
                if clip.joint_names is not None:
                    override.joint_names = clip.joint_names + [j.rsplit("/", 1)[-1] for j in result.added_joints]
            overrides.append(override)
            report.characters.append(CharacterReport(
                skel_root=clip.skel_root, skeleton=clip.skeleton, animation=clip.animation,
                map_source=map_source,
                chain={r: [clip.joints[j] for j in idx] for r, idx in chain.roles.items()},
                forward=[float(v) for v in frame.forward], frames=len(clip.times),
                added_joints=result.added_joints, result=result,
            ))
            if info is None:
                info = LayerInfo(clip.time_codes_per_second, clip.frames_per_second, clip.start_time,
                                 clip.end_time, clip.up_axis, clip.meters_per_unit)
            if progress:
                progress(clip)

    info.custom = {
        "usdgaze": {
            "version": __version__,
            "input": os.path.basename(source),
            "shifts": [str(r) for r in requests],
            "maps": sorted({c.map_source for c in report.characters}),
            "characters": [c.skel_root for c in report.characters],
        }
    }
    if sublayer_into is not None:  # refuse before anything is written
        check_sublayer_target(sublayer_into, [c.animation for c in report.characters])
    layer = build_override(overrides, info, fmt=out_path.suffix.lstrip("."))
    atomic_export(layer, out_path)
    if preview is not None:
        default_prim = stage.GetRootLayer().defaultPrim or None
        write_preview(preview, out_path, source, info, default_prim)
        report.preview = str(preview)
    if sublayer_into is not None:
        insert_sublayer(sublayer_into, out_path, [c.animation for c in report.characters])
        report.sublayered_into = str(sublayer_into)
    return report
