"""MJCF text of a :class:`~usdgaze.physics.model.BodyModel` (plain XML; MuJoCo is not imported)."""

from __future__ import annotations

from xml.sax.saxutils import quoteattr

import numpy as np

from usdgaze.physics.model import BodyModel
from usdgaze.physics.segments import children_of


# Soft contacts at a 0.04 s time constant (two 0.02 s steps) settle about 2 cm deep under body
# weight; a contact margin starts the ground's push that much earlier, so feet rest near z = 0.
GROUND_MARGIN = 0.015
# The hips' height above the ground at rest of the bodies that margin was measured on (CMU 131_01 and
# 131_02: 0.93 m, the synthetic rigs: 1.01 m). A smaller body's feet are smaller in proportion: 1.5 cm
# held the whole sole of a 0.9 m character (hips 0.52 m up) inside it, and a still stand jumped off the
# ground and fell at 0.48 s (docs/physics.md, "Integration").
ADULT_HIPS_M = 0.9
# Foot contacts stiffen with depth: MuJoCo's default impedance (0.95) for the first 3 cm of a foot's
# violation of the margin, rising to 0.99 (a fifth of the default's give) beyond it. The soft part
# lets a light toe carry the body's weight only by sinking in (5.6 cm on the CMU walk's push-offs);
# 0.99 from the first millimetre (tried) also stopped that, but then a standing foot was thrown off
# the ground at h 0.03. ``priority`` makes these the contact's parameters, not a mix with the ground's.
FOOT_SOLIMP = (0.95, 0.99, 0.03)


def _v(a) -> str:
    return " ".join(f"{float(x):.6g}" for x in np.ravel(a))


def _wxyz(q) -> str:
    q = np.asarray(q, dtype=float)
    return _v([q[3], q[0], q[1], q[2]])


def _motors(m: BodyModel, b: int) -> list[tuple[str, str]]:
    """(joint name, gear) for each motor of body ``b``: three axes on a ball, one on a hinge."""
    g = m.strength[b]
    if m.kind[b] == "hinge":
        return [(f"{m.names[b]}", _v([g]))]
    if m.kind[b] == "ball":
        return [(f"{m.names[b]}", _v(np.eye(3)[a] * g)) for a in range(3)]
    return []


def ground_margin(m: BodyModel) -> float:
    """The ground's contact margin for body ``m``: ``GROUND_MARGIN``, shrunk in proportion to the hips'
    height at rest below an adult's (a length of the feet's scale; the sink it offsets is the soft
    contact's, the same in metres for any body, so a taller body keeps it)."""
    hips = float(m.base_pos[2] + m.lift)
    return GROUND_MARGIN * min(1.0, max(hips, 0.0) / ADULT_HIPS_M)


def write(m: BodyModel, timestep: float = 0.02, name: str = "usdgaze_body") -> str:
    """The model as MJCF. Semi-implicit Euler (``integrator="Euler"``) at ``timestep``; joint damping is
    integrated implicitly by that integrator, which keeps 0.02-0.03 s steps stable; contacts are
    softened to a time constant of at least two steps, as MuJoCo requires for stability."""
    out = _header(m, timestep, name)
    _body(m, 0, 2, children_of(m.body_parent), out)
    out.append("  </worldbody>")
    out.extend(_actuators(m))
    out.append("</mujoco>")
    return "\n".join(out) + "\n"


def _header(m: BodyModel, timestep: float, name: str) -> list[str]:
    """Compiler, options, defaults and the ground: everything before the bodies."""
    tc = max(0.02, 2.0 * timestep)
    return [f'<mujoco model={quoteattr(name)}>',
            '  <compiler angle="degree" inertiafromgeom="false" autolimits="true"/>',
            # jacobian="sparse": MuJoCo's "auto" picks dense under 60 dofs, yet the CMU bodies' 54 take
            # 9-17% less CPU per simulated second sparse (docs/physics-log.md, "Sparse Jacobians").
            f'  <option timestep="{timestep:.6g}" integrator="Euler" jacobian="sparse" gravity="0 0 -9.81"/>',
            '  <size memory="8M"/>',
            '  <default>',
            f'    <geom contype="1" conaffinity="0" condim="3" friction="1.0 0.05 0.01" solref="{tc:.4g} 1" rgba="0.75 0.7 0.62 1"/>',
            '    <joint damping="2" armature="0.02" limited="true"/>',
            '    <motor ctrllimited="false"/>',
            '  </default>',
            '  <worldbody>',
            '    <light pos="0 0 4" dir="0 0 -1" directional="true"/>',
            f'    <geom name="ground" type="plane" size="0 0 0.05" contype="0" conaffinity="1" solref="{tc:.4g} 1" '
            f'margin="{ground_margin(m):.6g}" rgba="0.45 0.5 0.55 1"/>']


def _joint(m: BodyModel, b: int) -> str | None:
    """Body ``b``'s joint element (None for a weld)."""
    name = quoteattr(m.names[b])
    if m.kind[b] == "free":
        return f'<freejoint name={name}/>'
    if m.kind[b] == "ball":
        return f'<joint name={name} type="ball" range="0 {m.range_deg[b, 1]:.4g}" damping="{0.05 * m.strength[b]:.4g}"/>'
    if m.kind[b] == "hinge":
        return (f'<joint name={name} type="hinge" axis="{_v(m.axis[b])}" range="{_v(m.range_deg[b])}" '
                f'damping="{0.05 * m.strength[b]:.4g}"/>')
    return None


def _body(m: BodyModel, b: int, depth: int, children: list[list[int]], out: list[str]) -> None:
    """Body ``b`` and, nested in it, its children, appended to ``out`` indented by ``depth``."""
    pad = "  " * depth
    pos, quat = (m.base_pos + np.array([0, 0, m.lift]), m.base_quat) if b == 0 else (m.offset[b], m.rel_quat[b])
    out.append(f'{pad}<body name={quoteattr(m.names[b])} pos="{_v(pos)}" quat="{_wxyz(quat)}">')
    out.append(f'{pad}  <inertial pos="{_v(m.com[b])}" quat="{_wxyz(m.inertia_quat[b])}" '
               f'mass="{m.mass[b]:.6g}" diaginertia="{_v(m.inertia[b])}"/>')
    joint = _joint(m, b)
    if joint is not None:
        out.append(f"{pad}  {joint}")
    foot = f' priority="1" solimp="{_v(FOOT_SOLIMP)}"' if m.role[b] == "foot" else ""
    for g, (kind, v) in enumerate(m.geoms[b]):
        gname = quoteattr(f"{m.names[b]}_{g}")
        shape = f'fromto="{_v(v)}"' if kind == "capsule" else f'pos="{_v(v)}"'
        out.append(f'{pad}  <geom name={gname} type="{kind}" {shape} size="{m.radius[b]:.4g}"{foot}/>')
    for c in children[b]:
        _body(m, c, depth + 1, children, out)
    out.append(f"{pad}</body>")


def _actuators(m: BodyModel) -> list[str]:
    """One motor per rotational axis of every ball and hinge."""
    out = ["  <actuator>"]
    toes = set(m.toes)
    for b in range(len(m.bodies)):
        for a, (joint, gear) in enumerate(_motors(m, b)):
            # Toe motors stop at their strength: a light toe with an unlimited motor can press itself
            # through the soft ground, which cannot push back harder than the toe's small inertia allows.
            lim = ' ctrllimited="true" ctrlrange="-1 1"' if b in toes else ""
            out.append(f'    <motor name={quoteattr(f"{joint}_{a}")} joint={quoteattr(joint)} gear="{gear}"{lim}/>')
    out.append("  </actuator>")
    return out
