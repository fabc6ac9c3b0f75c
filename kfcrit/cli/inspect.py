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
    from kfcrit.views.text.schemadoc import reference_markdown

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
        from kfcrit.analysis.sweep.check import check_sweep_file

        sweep = check_sweep_file(file, max_states=max_states)
        click.echo(f"{file}: valid sweep file: {len(sweep.points)} points over "
                   f"{', '.join(sweep.parameters)}")
    else:
        spec = load_spec(file, max_states=max_states)
        s = spec.system
        channel = spec.channel.model if spec.channel is not None else "no channel"
        if spec.mesh is not None:
            m = spec.mesh.mesh
            channel = (f"mesh of {len(m.sensors)} sensors, {len(m.relays)} relays, "
                       f"{len(m.hops)} hops, {len(m.routes)} routes")
        elif spec.network is not None:
            models = sorted({sn.channel.model for sn in spec.network.sensors
                             if sn.channel is not None})
            channel = (f"network of {spec.network.size} sensor"
                       f"{'' if spec.network.size == 1 else 's'}"
                       + (f" ({', '.join(models)})" if models else ", no channels"))
        click.echo(f"{file}: valid system file: n = {s.n}, m = {s.m}, {channel}")
    sys.exit(0)


def settable_keys(entry: dict) -> dict[str, str]:
    """The keys a ``radio:`` mapping of this model may set besides ``model``, each with what
    it takes ("required" or its default)."""
    from kfcrit.io.fileschema import RADIO_MAPPING_KEYS, RADIO_REQUIRED_KEYS

    name = entry["name"]
    params = entry.get("parameters") or {}
    required = RADIO_REQUIRED_KEYS.get(name, ())
    return {key: "required" if key in required else f"default {plain_value(params.get(key))}"
            for key in RADIO_MAPPING_KEYS.get(name, {})}


@click.command()
@click.option("--json", "as_json", is_flag=True, help="Print the catalogue as JSON.")
@debug_option
@handle_errors
def radios(as_json: bool, debug: bool) -> None:
    """List the radio models a link budget may name, with their parameters.

    For each radio, "settable keys" are what a system file's ``radio: {model: NAME, ...}``
    mapping may set; the "descriptive" lines (formula, source, frame, datasheet values) say
    what the model is and cannot be set."""
    from kfcrit.link.radios import radio_catalogue

    entries = [{**r.to_dict()} for r in radio_catalogue()]
    for e in entries:
        e["settable_keys"] = sorted(settable_keys(e))
    if as_json:
        click.echo(json.dumps(entries, indent=2, ensure_ascii=False))
        return
    for e in entries:
        click.echo(f"{e['name']}  ({e['kind']})")
        click.echo(f"    {e['description']}")
        keys = settable_keys(e)
        if keys:
            click.echo(f"    settable keys (radio: {{model: {e['name']}, KEY: VALUE}}): "
                       + ", ".join(f"{k} ({v})" for k, v in keys.items()))
        else:
            click.echo(f"    settable keys: none (radio: {e['name']})")
        params = e.get("parameters") or {}
        items = params.items() if isinstance(params, dict) else enumerate(params)
        shown = [(k, v) for k, v in items if k != "model" and k not in keys]
        if shown:
            click.echo("    descriptive (what the model is; not settable):")
        for key, value in shown:
            click.echo(f"      {key}: {plain_value(value)}")
