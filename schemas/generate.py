"""Regenerate generatedSchema.usda and plugInfo.json from schema.usda (codeless GazeMapAPI).

Usage: ``python schemas/generate.py [--out DIR]`` (DIR defaults to this folder). Needs usd-core
and jinja2 (``pip install -e .[test]``).

usdGenSchema runs in a fresh temporary folder in a subprocess: it merges into an existing
plugInfo.json when it finds one, and it switches the process's asset resolver, so neither the
shipped files nor the caller may leak into the output. Its plugInfo.json carries CMake
placeholders; they are replaced by the values that make a codeless plugin load straight from
the folder holding it (``Plug.Registry().RegisterPlugins(folder)`` or ``PXR_PLUGINPATH_NAME``).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
OUTPUTS = ("generatedSchema.usda", "plugInfo.json")
PLACEHOLDERS = {
    # A resource-only plugin has no library; paths are relative to plugInfo.json's folder.
    '"@PLUG_INFO_LIBRARY_PATH@"': '""',
    '"@PLUG_INFO_RESOURCE_PATH@"': '"."',
    '"@PLUG_INFO_ROOT@"': '"."',
}


# Python plugins that ride along in the same plugInfo.json, so one PXR_PLUGINPATH_NAME entry brings
# the schema, usdgaze's UsdValidation validators and its usdview Gaze menu (each module is imported
# only when USD asks for it; usdgaze must be importable there). Keep the validator docs in step with
# usdgaze/review/validators.py (tests check).
VALIDATOR_PLUGIN = "usdgaze.review.validators"
VALIDATORS = {
    "GazeMapArrays": "Every gaze:examples:* array of a GazeMapAPI is authored, uniform, of its schema type, "
                     "and holds one entry per example.",
    "GazeMapRanges": "GazeMapAPI values lie in their documented ranges: yaw [-180, 180], pitch [-90, 90], "
                     "timing, synthesis settings; no two examples share a (yaw, pitch).",
    "GazeMapUnitQuaternions": "Every GazeMapAPI offset is a finite unit quaternion.",
    "GazeMapRoleJoints": "Every joint a GazeMapAPI binds to a role is a joint of each Skeleton under its SkelRoot, "
                         "and GazeMapAPI sits on a SkelRoot.",
    "AnimationArrays": "A SkelAnimation's rotations, translations and scales are each authored (UsdSkel poses "
                       "nothing without all three) and hold one finite entry per joint at every time sample, and its "
                       "rotations are unit quaternions.",
    "SkeletonArrays": "A Skeleton's joints are valid relative paths (UsdSkel reads an ill-formed one as a root), "
                      "its bindTransforms and restTransforms, where authored, hold one finite matrix per "
                      "joint of its joints array, and its jointNames, where authored, one name per joint; "
                      "restTransforms are authored where its bound animation leaves joints out (UsdSkel takes those "
                      "from them). The meshes it skins have jointIndices UsdSkel can skin by: every index within "
                      "the joints they index, and as many as jointWeights. Its transform, and every one above it that it "
                      "inherits, is one USD can evaluate.",
    "SkeletonUnits": "A Skeleton, its SkelRoot and its bound animation, where a reference or payload brings them "
                     "in, come from layers that author the stage's metersPerUnit (or none), or the reference is "
                     "scaled to make up for it.",
    "SkeletonUpAxis": "A Skeleton, its SkelRoot and its bound animation, where a reference or payload brings them "
                      "in, come from layers that author the stage's upAxis (or none), or the reference is rotated "
                      "to take the asset's up onto the stage's.",
    "GazeSchedule": "A GazeScheduleAPI reads as a schedule (arrays one per directive, known kinds, times in order, "
                    "weights and blends in range), each target is an Xformable or Boundable prim of the stage, "
                    "and each directive lies in the stage's time range or its SkelRoot's animation samples.",
    "GazeObject": "A GazeObjectAPI sits on an Xformable whose transform USD can evaluate (on it and above it), its "
                  "importance is > 0 at every sample, its radius >= 0 and its kind one of the allowed tokens.",
    "GazeLayerSchedule": "The schedule a usdgaze layer records (customLayerData usdgaze): every shift, look-at and release parses and "
                         "starts inside the stage's time range, every character it names is a SkelRoot there, and the layer "
                         "overrides a SkelAnimation of the stage and samples it over the span the input below it does "
                         "(not another take's), and the joints it writes but its gaze chain does not drive are the "
                         "input's below it (not another version's).",
    "SkeletonInstances": "No Skeleton under a SkelRoot, nor the SkelAnimation bound to it, lies inside an instance "
                         "(an instance proxy, or an instanceable prim), where no override can reach it.",
    "PhysicsObstacles": "Every prim tagged usdgaze:physics:task = \"obstacle\" (inside instances too) authors "
                        "gaze:object:radius, its size: one value for the shot, more than 0 and at most 10 m.",
}
VALIDATOR_SCHEMA_TYPES = {"AnimationArrays": ["UsdSkelAnimation"], "SkeletonArrays": ["UsdSkelSkeleton"],
                          "SkeletonUnits": ["UsdSkelSkeleton"], "SkeletonUpAxis": ["UsdSkelSkeleton"],
                          "GazeSchedule": ["UsdGazeGazeScheduleAPI"],
                          "GazeObject": ["UsdGazeGazeObjectAPI"], "GazeLayerSchedule": [],
                          "SkeletonInstances": [], "PhysicsObstacles": []}
USDVIEW_PLUGIN = "usdgaze.review.usdview_plugin"


def extra_plugins() -> list[dict]:
    """The plugInfo entries of the validator and usdview Python plugins."""
    validators = {}
    for name, doc in VALIDATORS.items():
        types = VALIDATOR_SCHEMA_TYPES.get(name, ["UsdGazeGazeMapAPI"])
        validators[name] = {"doc": doc, **({"schemaTypes": types} if types else {})}  # none: a stage validator
    validators["keywords"] = ["UsdGazeValidators"]
    return [
        {"Info": {"Validators": validators}, "LibraryPath": "", "Name": VALIDATOR_PLUGIN,
         # Plug keys plugins by their root: each needs its own (a name only; nothing is read there).
         "ResourcePath": ".", "Root": "validators", "Type": "python"},
        {"Info": {"Types": {f"{USDVIEW_PLUGIN}.GazePluginContainer": {
            "bases": ["pxr.Usdviewq.plugin.PluginContainer"], "displayName": "usdgaze Gaze menu"}}},
         "LibraryPath": "", "Name": USDVIEW_PLUGIN, "ResourcePath": ".", "Root": "usdview", "Type": "python"},
    ]


def _with_extra_plugins(text: str) -> str:
    """usdGenSchema's plugInfo.json (comment lines, then JSON) with :func:`extra_plugins` appended."""
    import json

    lines = text.splitlines()
    head = [line for line in lines if line.startswith("#")]
    data = json.loads("\n".join(line for line in lines if not line.startswith("#")))
    data["Plugins"].extend(extra_plugins())
    return "\n".join(head + [json.dumps(data, indent=4, sort_keys=True)])


def generate(out_dir: Path, schema: Path = HERE / "schema.usda") -> list[Path]:
    """Run usdGenSchema on ``schema`` and write the codeless plugin files into ``out_dir``."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    env = dict(os.environ)
    # A registered copy of this very plugin would be folded into the output as a reflected schema.
    env.pop("PXR_PLUGINPATH_NAME", None)
    with tempfile.TemporaryDirectory(prefix="usdgaze-genschema-") as tmp:
        proc = subprocess.run(
            [sys.executable, "-m", "pxr.Usd.usdGenSchema", "--quiet", str(Path(schema).resolve()), tmp],
            env=env,
            capture_output=True,
            text=True,
        )
        if proc.returncode != 0:
            raise RuntimeError(f"usdGenSchema failed ({proc.returncode}):\n{proc.stdout}{proc.stderr}")
        texts = {name: (Path(tmp) / name).read_text(encoding="utf-8") for name in OUTPUTS}
    for placeholder, value in PLACEHOLDERS.items():
        if placeholder not in texts["plugInfo.json"]:
            raise RuntimeError(f"usdGenSchema's plugInfo.json has no {placeholder}: template changed?")
        texts["plugInfo.json"] = texts["plugInfo.json"].replace(placeholder, value)
    texts["plugInfo.json"] = _with_extra_plugins(texts["plugInfo.json"])
    written = []
    for name, text in texts.items():
        path = out_dir / name
        # Fixed newline and a final newline, so the bytes do not depend on the platform.
        path.write_bytes((text.rstrip("\n") + "\n").encode("utf-8"))
        written.append(path)
    return written


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=HERE, help="folder to write into (default: next to this script)")
    parser.add_argument("--schema", type=Path, default=HERE / "schema.usda", help="schema source")
    args = parser.parse_args(argv)
    for path in generate(args.out, args.schema):
        print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
