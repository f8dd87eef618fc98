"""A shot layer bringing a synthetic rig in through a reference or payload, for the tests of what
USD does not carry across such an arc (the asset's metersPerUnit and upAxis)."""

from __future__ import annotations

from pathlib import Path

from pxr import Sdf


def shot_over(tmp_path: Path, rig, arc: str = "reference", via: bool = False, metadata: dict | None = None,
              op: tuple[str, object, object] | None = None) -> Path:
    """``shot.usda`` defining ``rig``'s SkelRoot through ``arc`` of ``char.usda`` (``via``: through a
    middle layer that authors no stage metadata), with the rig's time metadata, ``metadata`` (stage
    metadata: None values left unauthored) and ``op`` (an xformOp ``(name, value type, value)``) on
    the referencing prim."""
    asset = "./char.usda"
    if via:
        middle = Sdf.Layer.CreateNew(str(tmp_path / "middle.usda"))
        prim = Sdf.CreatePrimInLayer(middle, rig.skel_root)
        prim.specifier = Sdf.SpecifierDef
        prim.referenceList.prependedItems = [Sdf.Reference(asset, rig.skel_root)]
        middle.Save()
        asset = "./middle.usda"
    shot = Sdf.Layer.CreateNew(str(tmp_path / "shot.usda"))
    for key, value in (metadata or {}).items():
        if value is not None:
            shot.pseudoRoot.SetInfo(key, value)
    for key in ("timeCodesPerSecond", "framesPerSecond", "startTimeCode", "endTimeCode"):
        setattr(shot, key, getattr(Sdf.Layer.FindOrOpen(str(rig.path)), key))
    prim = Sdf.CreatePrimInLayer(shot, rig.skel_root)
    prim.specifier = Sdf.SpecifierDef
    items = [(Sdf.Reference if arc == "reference" else Sdf.Payload)(asset, rig.skel_root)]
    (prim.referenceList if arc == "reference" else prim.payloadList).prependedItems = items
    if op is not None:
        name, type_name, value = op
        Sdf.AttributeSpec(prim, name, type_name).default = value
        Sdf.AttributeSpec(prim, "xformOpOrder", Sdf.ValueTypeNames.TokenArray,
                          variability=Sdf.VariabilityUniform).default = [name]
    shot.Save()
    return tmp_path / "shot.usda"
