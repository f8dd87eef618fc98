"""Running OpenUSD validation (its validators and usdgaze's) on a stage, as plain records."""

from __future__ import annotations

import os

from usdgaze.errors import UsdGazeError
from usdgaze.files.kinds import require_file

_SEVERITY = {"Error": "error", "Warn": "warning", "Info": "info"}


def _open(stage_path: str, layer: str | None):
    from usdgaze.review.composed import composed_stage
    from usdgaze.usd.stage import open_stage

    require_file(stage_path)
    if layer is not None:
        return composed_stage(stage_path, layer)[0]
    return open_stage(stage_path)


def run(stage_path: str | os.PathLike, layer: str | os.PathLike | None = None, only_usdgaze: bool = False) -> list[dict]:
    """Every problem the validators find, as ``{file, site, severity, validator, error, message}``
    sorted by site, then validator."""
    from pxr import UsdValidation

    from usdgaze.review import validators
    from usdgaze.review.sample_checks import shared_samples

    stage = _open(str(stage_path), None if layer is None else str(layer))
    registry = UsdValidation.ValidationRegistry()
    chosen = ([registry.GetOrLoadValidatorByName(n) for n in validators.names()] if only_usdgaze
              else registry.GetOrLoadAllValidators())
    # Every prim, abstract classes included: a map file holds its map on a class prim.
    from pxr import Usd

    with shared_samples():
        errors = UsdValidation.ValidationContext([v for v in chosen if v is not None]).Validate(stage, Usd.PrimAllPrimsPredicate)
    if _holds_only_classes(stage):
        # A map file (dump-map, build-map) holds abstract classes alone, no geometry: the units and
        # up axis of the stage that brings it in are the ones that count, so its own are not asked for.
        errors = [e for e in errors if "StageMetadataChecker" not in (e.GetValidator().GetMetadata().name
                                                                        if e.GetValidator() else "")]
    # With --layer the root is an in-memory layer over the input: a message naming it names the input.
    anon = stage.GetRootLayer().identifier if layer is not None else None
    problems = []
    for e in errors:
        if e.HasNoError():
            continue
        sites = [s for s in e.GetSites() if s.IsValid()] or [None]
        validator = e.GetValidator()
        name = validator.GetMetadata().name if validator else ""
        for site in sites:
            path = ""
            if site is not None:
                path = str(site.GetProperty().GetPath()) if site.IsProperty() else str(site.GetPrim().GetPath()) if site.IsPrim() else ""
            problems.append({
                "file": str(stage_path), "site": path or "/", "severity": _SEVERITY.get(str(e.GetType()).rsplit(".", 1)[-1], "error"),
                "validator": name, "error": str(e.GetName()), "message": _named(" ".join(str(e.GetMessage()).split()), anon, str(stage_path)),
            })
    problems.sort(key=lambda p: (p["site"], p["validator"], p["error"], p["message"]))
    return problems


def _holds_only_classes(stage) -> bool:
    """Whether every prim of the stage is an abstract class or under one (and there is one)."""
    from pxr import Usd

    prims = list(stage.Traverse(Usd.PrimAllPrimsPredicate))
    return bool(prims) and all(p.IsAbstract() for p in prims)


def _named(message: str, anon: str | None, source: str) -> str:
    return message.replace(anon, source) if anon else message
