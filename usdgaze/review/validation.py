"""Running OpenUSD validation (its validators and usdgaze's) on a stage, as plain records."""

from __future__ import annotations

import os

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
    named = _Namer(str(stage_path), None if layer is None else str(layer))
    problems = []
    for e in _without_duplicates(errors):
        validator = e.GetValidator()
        name = validator.GetMetadata().name if validator else ""
        for site in [s for s in e.GetSites() if s.IsValid()] or [None]:
            file, path = named.site(site)
            problems.append({
                "file": file, "site": path, "severity": _SEVERITY.get(str(e.GetType()).rsplit(".", 1)[-1], "error"),
                "validator": name, "error": str(e.GetName()), "message": _named(" ".join(str(e.GetMessage()).split()), anon, str(stage_path)),
            })
    problems.sort(key=lambda p: (p["site"], p["validator"], p["error"], p["message"]))
    return problems


_TYPE_MISMATCH = "usdValidation:AttributeTypeMismatch"
"""OpenUSD's validator of an attribute authored with another type than its schema's: usdgaze's
``WrongType`` says the same of a gaze attribute on its own line, naming the prim and attribute (USD's
line is sited on the layer, printed as ``/``), so one of the two is dropped."""


def _without_duplicates(errors) -> list:
    """The errors with something to say, less USD's type mismatch on an attribute usdgaze's
    ``WrongType`` reports too (matched by the layer spec both name, so one on another attribute stays)."""
    errors = [e for e in errors if not e.HasNoError()]
    ours = set()
    for e in errors:
        if e.GetName() == "WrongType":
            for site in e.GetSites():
                if site.IsValid() and site.IsProperty():
                    ours |= {(spec.layer.identifier, str(spec.path)) for spec in site.GetProperty().GetPropertyStack()}

    def duplicate(e) -> bool:
        validator = e.GetValidator()
        if not validator or validator.GetMetadata().name != _TYPE_MISMATCH:
            return False
        specs = [s.GetPropertySpec() for s in e.GetSites() if s.IsValid() and s.GetPropertySpec()]
        return bool(specs) and all((spec.layer.identifier, str(spec.path)) in ours for spec in specs)
    return [e for e in errors if not duplicate(e)]


class _Namer:
    """FILE and SITE of a problem's line: FILE is the layer that authored the value at fault (an
    override layer's bad sample is that layer's to fix, not the input's), named as the user named it
    (STAGE, --layer) or by its path; a prim, or a value no layer authors, is the stage's."""

    def __init__(self, stage_path: str, layer_path: str | None) -> None:
        self.stage_path, self.relative = stage_path, not os.path.isabs(stage_path)
        self.given = {os.path.realpath(stage_path): stage_path}
        if layer_path is not None:
            self.given[os.path.realpath(layer_path)] = layer_path

    def layer(self, layer) -> str:
        if layer is None or layer.anonymous or not layer.realPath:
            return self.stage_path
        path = layer.realPath
        return self.given.get(os.path.realpath(path), os.path.relpath(path) if self.relative else path)

    def site(self, site) -> tuple[str, str]:
        from pxr import Usd

        from usdgaze.usd.checks import value_spec

        if site is None:
            return self.stage_path, "/"
        if site.IsProperty():
            prop = site.GetProperty()
            stack = prop.GetPropertyStack()  # a relationship: its strongest spec authors its targets
            spec = value_spec(prop) if isinstance(prop, Usd.Attribute) else (stack[0] if stack else None)
            return self.layer(spec.layer if spec else None), str(prop.GetPath())
        if site.IsPrim():
            return self.stage_path, str(site.GetPrim().GetPath())
        spec = site.GetPropertySpec() or site.GetPrimSpec()  # a layer's spec (USD's type mismatch)
        return self.layer(site.GetLayer()), str(spec.path) if spec else "/"


def _holds_only_classes(stage) -> bool:
    """Whether every prim of the stage is an abstract class or under one (and there is one)."""
    from pxr import Usd

    prims = list(stage.Traverse(Usd.PrimAllPrimsPredicate))
    return bool(prims) and all(p.IsAbstract() for p in prims)


def _named(message: str, anon: str | None, source: str) -> str:
    return message.replace(anon, source) if anon else message
