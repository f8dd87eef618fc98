"""``usdgaze preview``: base and gaze animation drawn headless, as a GIF/MP4 and a PNG contact sheet."""

from __future__ import annotations

import time

import click

from usdgaze.console.types import FiniteRange


@click.command()
@click.argument("input_path", metavar="INPUT", type=click.Path(dir_okay=False))
@click.option("--layer", required=True, type=click.Path(dir_okay=False), help="The override layer usdgaze wrote for INPUT.")
@click.option("--out", required=True, type=click.Path(dir_okay=False), metavar="FILE",
              help="Animation (.gif, or .mp4 with imageio-ffmpeg), or a .png contact sheet.")
@click.option("--sheet", default=None, type=click.Path(dir_okay=False), metavar="FILE.png",
              help="Also write a contact sheet of --sheet-count frames.")
@click.option("--camera", default="front", show_default=True, metavar="front|side|top|PRIM",
              help="A named camera following the character, or a Camera prim of the stage.")
@click.option("--layout", default="side-by-side", show_default=True, type=click.Choice(["side-by-side", "overlay"]),
              help="side-by-side: the base and the gaze animation in two panels; overlay: both in one panel.")
@click.option("--fps", default=24.0, show_default=True, type=FiniteRange(1.0, 240.0),
              help="Frames per second of the animation.")
@click.option("--size", default=360, show_default=True, type=click.IntRange(64, 2048), help="Panel size in pixels.")
@click.option("--sheet-count", default=12, show_default=True, type=click.IntRange(1, 200),
              help="Frames on a contact sheet (--sheet, or a .png --out), spread evenly over the animation.")
@click.option("--skel-root", default=None, help="Only this SkelRoot (default: every one the layer animates).")
def preview(input_path, layer, out, sheet, camera, layout, fps, size, sheet_count, skel_root) -> None:
    """Draw INPUT without (base) and with (gaze) LAYER: shaded capsule figures, the head's direction
    (green), the lines of sight to the point of sight (blue: base, red: gaze).

    INPUT is opened with LAYER as its strongest sublayer in memory; neither file is changed.
    """
    from pathlib import Path

    from usdgaze.review import preview as pv
    from usdgaze.files.transaction import Outputs
    from usdgaze.review.composed import composed_stage, read_review

    started = time.perf_counter()
    out_path = Path(out)
    is_sheet = out_path.suffix.lower() == ".png"
    pv.check_output(out_path, "sheet" if is_sheet else "animation", fps)
    if sheet is not None:
        pv.check_output(sheet, "sheet", flag="--sheet")
    opts = pv.PreviewOptions(camera=camera, layout=layout, fps=fps, size=size, sheet_count=sheet_count)
    if is_sheet or sheet is not None:
        pv.check_sheet(opts)
    review = read_review(input_path, layer, skel_root, playback=True)
    for w in review.warnings:  # drawn all the same: what the composed stage plays, which is not this input's gaze
        click.echo(f"usdgaze: warning: {w}", err=True)
    stage, _ = composed_stage(input_path, layer)
    with Outputs() as outputs:
        outputs.read(input_path)
        outputs.read(layer, "--layer")
        outputs.claim(out_path, "--out")
        if sheet is not None:
            outputs.claim(sheet, "--sheet")
        frames = 0
        if is_sheet:
            image, _ = pv.contact_sheet(review, opts, stage)
            pv.write_png(image, out_path, outputs)
        else:
            frames = pv.write_animation(pv.build_scene(review, opts, stage), out_path, outputs)
        if sheet is not None:
            image, _ = pv.contact_sheet(review, opts, stage)
            pv.write_png(image, Path(sheet), outputs)
    elapsed = time.perf_counter() - started
    click.echo(f"wrote {out_path}" + (f"  ({frames} frames at {fps:g} fps)" if frames else "") + f"  in {elapsed:.1f} s")
    if sheet is not None:
        click.echo(f"wrote {sheet}")
