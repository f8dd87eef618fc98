"""``usdgaze validate``: OpenUSD's validators and usdgaze's on a stage, one line per problem.

Exit codes: 0 nothing found (and nothing printed), 3 problems found, 2 bad input (the stage cannot be
opened), 1 internal error.
"""

from __future__ import annotations

import json

import click

EXIT_PROBLEMS = 3


@click.command()
@click.argument("stage_path", metavar="STAGE", type=click.Path(dir_okay=False))
@click.option("--layer", default=None, type=click.Path(dir_okay=False),
              help="Validate STAGE composed with this override layer as its strongest sublayer (in memory).")
@click.option("--only-usdgaze", is_flag=True, help="Run usdgaze's validators only, not OpenUSD's own.")
@click.option("--json", "as_json", is_flag=True, help="Print the problems as a JSON list.")
def validate(stage_path, layer, only_usdgaze, as_json) -> None:
    """Check STAGE with OpenUSD's validators and usdgaze's (gaze maps, animation arrays), like a
    linter: one line per problem, FILE:PRIM[.PROPERTY]: SEVERITY: message (validator.ErrorName).
    Exit 3 if any, 2 if STAGE cannot be opened."""
    from usdgaze.review.validation import run

    problems = run(stage_path, layer, only_usdgaze=only_usdgaze)
    if as_json:  # a clean stage too: [] is what a JSON reader can parse
        click.echo(json.dumps(problems, indent=2))
    else:
        for p in problems:
            click.echo(f"{p['file']}:{p['site']}: {p['severity']}: {p['message']} ({p['validator']}.{p['error']})")
    if problems:
        raise click.exceptions.Exit(EXIT_PROBLEMS)
