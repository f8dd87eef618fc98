"""Whether USD can evaluate a prim's transform: every op its ``xformOpOrder`` names exists, is an op
type USD knows, and holds a value of the type that op takes.

Why checked before reading: USD raises on an op type it does not know (``xformOp:foo``) and on a value
of the wrong type (a translate authored as one ``double``), and its Sdf-level samples fed numpy a
value of the wrong shape; both stopped ``attend`` with an internal error (exit 1). An array
(``double3[]``) was read as its first element, and an op named but never authored was skipped with
a multi-line USD warning above an exit 0.
"""

from __future__ import annotations

from pxr import Sdf, Tf, Usd, UsdGeom

from usdgaze.errors import UsdGazeError, usd_failure
from usdgaze.usd.checks import authored_type

RESET = "!resetXformStack!"
INVERT = "!invert!"
_N = Sdf.ValueTypeNames
_T = UsdGeom.XformOp
_VECTOR = (_N.Float3, _N.Double3, _N.Half3)
_SCALAR = (_N.Float, _N.Double, _N.Half)
# The value types UsdGeom.XformOp evaluates for each op type; any op type not named here (translate,
# scale and the six three-axis rotates) takes a 3-vector.
_WANTED = {**{t: _SCALAR for t in (_T.TypeRotateX, _T.TypeRotateY, _T.TypeRotateZ, _T.TypeTranslateX,
                                   _T.TypeTranslateY, _T.TypeTranslateZ, _T.TypeScaleX, _T.TypeScaleY,
                                   _T.TypeScaleZ)},
           _T.TypeOrient: (_N.Quatf, _N.Quatd, _N.Quath), _T.TypeTransform: (_N.Matrix4d,)}


def op_problem(prim: Usd.Prim) -> str | None:
    """Why USD cannot evaluate ``prim``'s own transform ops, as ``attribute: what is wrong``, or None."""
    attr = UsdGeom.Xformable(prim).GetXformOpOrderAttr()
    spelled = authored_type(attr) if attr.HasAuthoredValue() else "token[]"
    if spelled != "token[]":  # USD orders no op by it (the prim is read at identity): its letters were read as ops
        return f"xformOpOrder: is a {spelled or 'value of no type'}, expected a token[] (USD reads no op order from it)"
    order = attr.Get() or []
    for token in order:
        if token == RESET:
            continue
        name = token[len(INVERT):] if token.startswith(INVERT) else token
        attr = prim.GetAttribute(name)
        if not attr:
            return f"xformOpOrder: names {name}, which the prim does not have (USD skips it)"
        try:
            op = UsdGeom.XformOp(attr, token.startswith(INVERT))
        except Tf.ErrorException as exc:  # an op type USD does not know
            return f"xformOpOrder: '{token}' is no transform op USD evaluates ({usd_failure(exc)})"
        wanted = _WANTED.get(op.GetOpType(), _VECTOR)
        spelled = attr.GetTypeName()
        if spelled.type not in [w.type for w in wanted]:  # by value type: a vector3d is a double3
            kind = UsdGeom.XformOp.GetOpTypeToken(op.GetOpType())
            names = [str(w) for w in wanted]
            expected = names[0] if len(names) == 1 else f"{', '.join(names[:-1])} or {names[-1]}"
            return f"{name}: is a {spelled or 'value of no type'}, expected a {expected} (a {kind} op)"
    return None


def transform_problem(prim: Usd.Prim) -> tuple[Usd.Prim, str] | None:
    """The first prim, ``prim`` or one above it whose transform it inherits, whose transform USD cannot
    evaluate, with :func:`op_problem`'s line; None where USD can evaluate them all."""
    p = prim
    while p and not p.IsPseudoRoot():
        if p.IsA(UsdGeom.Xformable):
            problem = op_problem(p)
            if problem:
                return p, problem
            if UsdGeom.Xformable(p).GetResetXformStack():  # the transforms above are not used
                return None
        p = p.GetParent()
    return None


def check_transform(prim: Usd.Prim, source: str) -> None:
    """One line naming the prim and attribute unless USD can evaluate the transform of ``prim`` and of
    every prim above it whose transform it inherits."""
    found = transform_problem(prim)
    if found:
        raise UsdGazeError(f"{source}:{found[0].GetPath()}.{found[1]}")
