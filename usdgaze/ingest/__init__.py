"""Building gaze maps from captured or keyframed example trials (Heck 5.2.1-5.2.2).

``usdgaze build-map SHEET --markers MARKERSET --out MAP.usda`` runs, per trial of the sheet:

* :mod:`.c3dio` / :mod:`.skelclips`: read a C3D marker capture (ezc3d) or a UsdSkel clip;
* :mod:`.markers`: which markers make which landmark (lower back -> pelvis, upper back ->
  lowerSpine, neck base -> upperSpine, head square -> neck; eyes inferred);
* :mod:`.cleaning`: linear gap filling, root stabilization, cropping by rest periods;
* :mod:`.frames` / :mod:`.series`: landmark orientations per frame;
* :mod:`.extract`: P+, eye offset, overshoot peak, start times and duration;
* :mod:`.build` / :mod:`.report` / :mod:`.command`: the map, the per-trial report, the CLI.

Only :mod:`.skelclips` and map writing import pxr.
"""

from usdgaze.ingest.build import BuildError, BuildResult, TrialError, TrialReport, build, require_definition, write_map
from usdgaze.ingest.markers import MarkerSet, load_markerset
from usdgaze.ingest.settings import BuildSettings
from usdgaze.ingest.sheet import Sheet, Trial, load_sheet

__all__ = [
    "BuildError",
    "BuildResult",
    "BuildSettings",
    "MarkerSet",
    "Sheet",
    "Trial",
    "TrialError",
    "TrialReport",
    "build",
    "load_markerset",
    "load_sheet",
    "require_definition",
    "write_map",
]
