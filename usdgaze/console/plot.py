"""``usdgaze plot``: review plots of a gaze layer, computed from the composed result."""

from __future__ import annotations

import click


@click.command()
@click.argument("input_path", metavar="INPUT", type=click.Path(dir_okay=False))
@click.option("--layer", required=True, type=click.Path(dir_okay=False), help="The override layer usdgaze wrote for INPUT.")
@click.option("--out", "out_dir", required=True, type=click.Path(file_okay=False), metavar="DIR",
              help="Folder for the PNGs (created if missing).")
@click.option("--skel-root", default=None, help="Only this SkelRoot (default: every one the layer animates).")
def plot(input_path, layer, out_dir, skel_root) -> None:
    """Plot what LAYER does to INPUT: per-joint cascade per shift, requested vs achieved gaze, eye
    angles against the pass's limits, line-of-sight speed against the saccade main sequence; for an
    `attend --physics` layer, each simulated character's per-step measures (pelvis height, joint
    error, foot depth, heading, root drift, task distances) against their bars, problems in red.

    INPUT is opened with LAYER as its strongest sublayer in memory; neither file is changed.
    """
    from usdgaze.files.transaction import Outputs
    from usdgaze.review.composed import read_review
    from usdgaze.review.plotting import pyplot, write_plots

    pyplot()  # a missing matplotlib fails before any work
    review = read_review(input_path, layer, skel_root, playback=True)
    for w in review.warnings:  # drawn all the same: what the composed stage plays, which is not this input's gaze
        click.echo(f"usdgaze: warning: {w}", err=True)
    with Outputs() as outputs:
        outputs.read(input_path)
        outputs.read(layer, "--layer")
        outputs.make_folder(out_dir)
        written = write_plots(review, out_dir, outputs)
    for path in written:
        click.echo(f"wrote {path}")
