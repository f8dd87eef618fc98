"""What one ``apply`` is asked (:class:`ApplyRequest`) and what it reports (:class:`ApplyReport`)."""

from __future__ import annotations

import os
from dataclasses import dataclass, field

from usdgaze.passes.look import LookOptions
from usdgaze.passes.options import PassOptions, PassResult
from usdgaze.passes.requests import DirectiveRequest
from usdgaze.values import ShiftRequest


@dataclass
class ApplyRequest:
    """Everything one ``apply`` is asked to do. New options are new fields (``apply`` passes keywords on)."""

    input_path: str | os.PathLike
    shifts: list[ShiftRequest | str]
    out: str | os.PathLike
    skel_root: str | None = None
    map_spec: str | None = None
    sublayer_into: str | os.PathLike | None = None
    preview: str | os.PathLike | None = None
    plot: str | os.PathLike | None = None
    no_clobber: bool = False
    make_folders: bool = False
    """Create missing output folders (removed again if the command fails); the batch's default."""
    options: PassOptions = field(default_factory=PassOptions)
    progress: object = None
    record: dict = field(default_factory=dict)
    """Extra entries for the override's ``customLayerData["usdgaze"]`` (the batch's resume key)."""
    look_at: list[DirectiveRequest | str] = field(default_factory=list)
    """``TARGET@TIME[:weight=W][:blend=B]`` directives (see :mod:`usdgaze.passes.requests`)."""
    release: list[DirectiveRequest | str] = field(default_factory=list)
    """``TIME[:blend=B]`` directives."""
    look: LookOptions = field(default_factory=LookOptions)
    """Eye timing, pursuit and reach of the look pass."""
    guides: bool = True
    """Author guide-purpose lines of sight and the point of sight for review."""

    @property
    def source(self) -> str:
        return os.fspath(self.input_path)


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
    """The pass's result without its animation arrays (``rotations``, ``translations``, ``scales``
    are None): those are in the written layer, and a crowd's are not all held until the end."""
    guide: tuple | None = None
    """(times, eye positions (2, F, 3) and point of sight (F, 3) in skeleton space, point of sight in
    world space, line width), when guides are written."""


@dataclass
class ApplyReport:
    output: str
    input: str | None = None
    characters: list[CharacterReport] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    preview: str | None = None
    plot: str | None = None
    sublayered_into: str | None = None
    sublayer_was_there: bool = False
    """``sublayered_into`` already had the output first, at its offset: left as it was."""
    directives: dict[str, list[str]] = field(default_factory=dict)
    """Per SkelRoot, the directives applied, as flags (from the command or the SkelRoot's schedule)."""

