"""``kfcrit check`` and ``kfcrit schema``: validate files and print the JSON Schemas."""
from __future__ import annotations

import json
import sys

import click

from kfcrit.cli.common import debug_option, handle_errors, max_states_option


@click.command()
@click.argument("what", type=click.Choice(["record", "system", "sweep"]), required=False)
@click.option("--markdown", is_flag=True,
              help="Print the key reference of system and sweep files (Markdown) instead.")
@debug_option
@handle_errors
def schema(what: str | None, markdown: bool, debug: bool) -> None:
    """Print the JSON Schema (draft 2020-12) of the analysis record, or of system or sweep
    files; with --markdown, the file reference generated from them."""
    from kfcrit.analysis.sections import record_schema
    from kfcrit.io.fileschema import sweep_schema, system_schema
    from kfcrit.views.schemadoc import reference_markdown

    if markdown:
        click.echo(reference_markdown(system_schema(), sweep_schema()), nl=False)
        return
    if what is None:
        raise click.UsageError("name what to print: record, system or sweep (or --markdown)")
    build = {"record": record_schema, "system": system_schema, "sweep": sweep_schema}[what]
    click.echo(json.dumps(build(), indent=2, ensure_ascii=False))


def plain_value(value: object) -> str:
    """A catalogue value as a reader wants it: numbers to 4 significant digits, mappings as
    ``key = value`` pairs, missing values as "none"."""
    if value is None:
        return "none"
    if isinstance(value, float):
        return f"{value:.4g}"
    if isinstance(value, dict):
        return ", ".join(f"{k} = {plain_value(v)}" for k, v in value.items())
    return str(value)


@click.command()
@click.argument("file", type=click.Path(dir_okay=False))
@max_states_option
@debug_option
@handle_errors
def check(file: str, max_states: int, debug: bool) -> None:
    """Validate a system or sweep FILE without analysing it (exit 0 valid, 2 invalid).

    A sweep file is checked point by point: every swept value, and every point's whole
    assignment, is set in the base system and validated as a system file."""
    from kfcrit.analysis.spec import load_spec
    from kfcrit.io.systemfile import is_sweep_document, read_yaml

    doc, _ = read_yaml(file)
    if is_sweep_document(doc):
        from kfcrit.analysis.sweepcheck import check_sweep_file

        sweep = check_sweep_file(file, max_states=max_states)
        click.echo(f"{file}: valid sweep file: {len(sweep.points)} points over "
                   f"{', '.join(sweep.parameters)}")
    else:
        spec = load_spec(file, max_states=max_states)
        s = spec.system
        channel = spec.channel.model if spec.channel is not None else "no channel"
        click.echo(f"{file}: valid system file: n = {s.n}, m = {s.m}, {channel}")
    sys.exit(0)


@click.command()
@click.option("--json", "as_json", is_flag=True, help="Print the catalogue as JSON.")
@debug_option
@handle_errors
def radios(as_json: bool, debug: bool) -> None:
    """List the radio models a link budget may name, with their parameters."""
    from kfcrit.link.radios import radio_catalogue

    entries = [r.to_dict() for r in radio_catalogue()]
    if as_json:
        click.echo(json.dumps(entries, indent=2, ensure_ascii=False))
        return
    for e in entries:
        click.echo(f"{e['name']}  ({e['kind']})")
        click.echo(f"    {e['description']}")
        params = e.get("parameters") or {}
        for key, value in (params.items() if isinstance(params, dict) else enumerate(params)):
            click.echo(f"    {key}: {plain_value(value)}")
