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
