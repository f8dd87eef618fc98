"""Checks behind the ``AnimationArrays`` and ``SkeletonArrays`` validators for what ``apply`` refuses of
a SkelAnimation's or a Skeleton's authoring (beside their values' lengths and finiteness): an animation
array left unauthored, a joint token that is no path, a mesh skinned by joint indices UsdSkel cannot
use. Each says what apply's refusal says, one line."""

from __future__ import annotations

from pxr import Usd, UsdSkel, UsdValidation

from usdgaze.review.sample_checks import bad_samples
from usdgaze.usd.samples import NOT_AUTHORED
from usdgaze.usd.skelio import ill_formed_joint
from usdgaze.usd.skinning import influence_problems


def site_error(prim: Usd.Prim, path, name: str, message: str) -> UsdValidation.ValidationError:
    site = UsdValidation.ValidationErrorSite(prim.GetStage(), path)
    return UsdValidation.ValidationError(name, UsdValidation.ValidationErrorType.Error, [site], message)


def not_authored(anim: UsdSkel.Animation) -> list:
    """Each of rotations, translations and scales with neither a default nor time samples, on an
    animation with joints: UsdSkel poses nothing without all three (``ComputeJointLocalTransforms``
    gives an empty pose), so apply refuses it. A default alone (a constant scale) is a value."""
    joints = anim.GetJointsAttr().Get()
    if not joints:
        return []
    prim = anim.GetPrim()
    return [site_error(prim, attr.GetPath(), "NotAuthored", f"{attr.GetName()}: {NOT_AUTHORED}")
            for attr in (anim.GetRotationsAttr(), anim.GetTranslationsAttr(), anim.GetScalesAttr())
            if not attr or not attr.HasAuthoredValue()]


def animation_arrays(prim: Usd.Prim, time_range=None) -> list:
    """The ``AnimationArrays`` validator: the three arrays authored, and per array each kind of bad
    sample (a wrong length, NaN or infinite values, quaternions off unit length) one line, with its
    first time code and how many samples have it."""
    anim = UsdSkel.Animation(prim)
    joints = anim.GetJointsAttr().Get()
    if joints is None:
        return []
    n, errors = len(joints), not_authored(anim)
    for attr, width in ((anim.GetRotationsAttr(), 4), (anim.GetTranslationsAttr(), 3), (anim.GetScalesAttr(), 3)):
        if not attr or not attr.HasAuthoredValue():
            continue
        for kind, at, count, total, entries in bad_samples(attr, n, width):
            what = {"Length": f"{entries} entries at {at}, expected {n} (one per joint)",
                    "NotFinite": f"NaN or infinite values at {at}",
                    "NotUnit": f"not unit quaternions at {at}"}[kind]
            errors.append(site_error(prim, attr.GetPath(), kind, f"{attr.GetName()}: {what}; {count} of {total} samples"))
    return errors


def ill_formed_joints(skel: UsdSkel.Skeleton, joints) -> list:
    """The Skeleton's joint tokens that are no relative path (``mixamorig:Hips``, ``Hips/Spine.001``):
    UsdSkel reads such a joint as a root and apply refuses the skeleton. One line per skeleton: the
    first, with how many there are."""
    bad = [str(j) for j in (joints or []) if ill_formed_joint(str(j))]
    if not bad:
        return []
    more = f"; {len(bad)} of the skeleton's {len(joints)} joints are ill-formed" if len(bad) > 1 else ""
    attr = skel.GetJointsAttr()
    return [site_error(skel.GetPrim(), attr.GetPath(), "IllFormedJoint", f"joints: {ill_formed_joint(bad[0])}{more}")]


def skinned_influences(skel: UsdSkel.Skeleton) -> list:
    """Each mesh the Skeleton skins whose jointIndices UsdSkel cannot skin by (an index out of range,
    jointWeights of another length; see :mod:`usdgaze.usd.skinning`): one line per mesh, on the primvar.
    apply warns of the same, and refuses to add eye joints that an index out of range would land on."""
    return [site_error(p.prim, p.prim.GetPath().AppendProperty(p.attribute), "JointIndices", f"{p.attribute}: {p.problem}")
            for p in influence_problems(skel.GetPrim())]
