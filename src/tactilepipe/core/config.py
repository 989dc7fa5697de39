"""Load params.yaml, apply the chosen scale's overlay, validate against the JSON schema.

Snakemake (workflow/rules/common.smk) and the CLI both go through `resolve`, so a stage
sees the same numbers whichever way it is started. The schema is package data generated from the
parameter models in `tactilepipe.core.parameters` (`make schema`).

What the schema cannot say, because it relates keys, is each study's own check, kept with the
study (volume/checks.py, tool/checks.py, papillarray/checks.py: ``check(p, source)``, raising
ConfigError) and handed to `resolve` / `load_params` as ``checks``. Core imports nothing of the
project, and a check here would be code of every stage: editing one study's check would re-run
every stage of every study. Who runs which: a stage run by hand, its own study's (the
``checks=`` of its ``@command``, cli/registry.py); the workflow, ``tactilepipe diff`` and every
other caller that validates a whole params.yaml, every study's (`tactilepipe.studies`).
Without ``checks`` only the schema, the scale and finiteness are checked.
"""

from __future__ import annotations

import copy
import json
import math
import re
from functools import cache
from importlib.resources import files
from pathlib import Path
from typing import Any, Callable, Iterable

import jsonschema
import yaml

from tactilepipe.core.errors import ConfigError
from tactilepipe.core.yamlsafe import load_yaml_text

PARAMS_SCHEMA = files("tactilepipe.core") / "params.schema.json"
DEFAULT_PARAMS = Path("params.yaml")


@cache
def _validator() -> jsonschema.Draft202012Validator:
    return jsonschema.Draft202012Validator(json.loads(PARAMS_SCHEMA.read_text()))


def deep_merge(base: dict, overlay: dict) -> dict:
    """Return ``base`` with ``overlay`` merged in (dicts merge recursively, the rest replaces)."""
    out = copy.deepcopy(base)
    for key, value in overlay.items():
        if isinstance(value, dict) and isinstance(out.get(key), dict):
            out[key] = deep_merge(out[key], value)
        else:
            out[key] = copy.deepcopy(value)
    return out


def changed_leaves(values: dict, reference: dict) -> dict:
    """The part of ``values`` that differs from ``reference``, group by group: an override of one
    key of a group must not carry the group's other keys along (they would then override the
    scale's overlay of them too)."""
    out = {}
    for key, value in values.items():
        ref = reference.get(key) if isinstance(reference, dict) else None
        if isinstance(value, dict) and isinstance(ref, dict):
            sub = changed_leaves(value, ref)
            if sub:
                out[key] = sub
        elif key not in (reference or {}) or ref != value:
            out[key] = value
    return out


def typed_like(values: dict, reference: dict) -> dict:
    """``values`` with each text leaf read as YAML where ``reference`` (params.yaml) holds a value
    that is not text at the same place. Snakemake parses a ``--config`` value's top level but keeps
    its nested scalars as text (``folds='{"n_folds": 2}'`` arrives as {"n_folds": "2"})."""
    out = {}
    for key, value in values.items():
        ref = reference.get(key) if isinstance(reference, dict) else None
        out[key] = _typed(value, ref)
    return out


def _typed(value, ref):
    if isinstance(value, dict):
        return typed_like(value, ref if isinstance(ref, dict) else {})
    if isinstance(value, list) and isinstance(ref, list) and ref:
        return [_typed(v, ref[0]) for v in value]
    if isinstance(value, str) and isinstance(ref, str) and value.lstrip().startswith("["):
        try:                                   # a list where params.yaml has a word ("variants: all")
            parsed = load_yaml_text(value, "--config value")
        except yaml.YAMLError:
            return value
        return parsed if isinstance(parsed, list) else value
    if isinstance(value, str) and ref is not None and not isinstance(ref, str):
        try:
            parsed = load_yaml_text(value, "--config value")
        except yaml.YAMLError:
            return value                       # left as text: validation names the key and the type
        if isinstance(parsed, str) and isinstance(ref, (int, float)) and not isinstance(ref, bool):
            try:
                return float(parsed)           # 1e-4: YAML 1.1 reads an exponent without a dot as text
            except ValueError:
                return value
        return parsed
    return value


def _format_error(err: jsonschema.ValidationError, source: str) -> str:
    where = ".".join(str(p) for p in err.absolute_path) or "(top level)"
    if err.validator == "pattern" and isinstance(err.schema, dict) and err.schema.get("description"):
        return f"{source}: invalid parameter at '{where}': {err.instance!r} is not {err.schema['description']}"
    return f"{source}: invalid parameter at '{where}': {err.message}"


# YAML 1.1 (PyYAML, and Snakemake's config loading) reads 1e-4 as a string: its floats need a dot
# (1.0e-4). YAML 1.2 and every other reader take it as a number, so where the schema asks for a
# number, a string of this form is one.
_YAML12_FLOAT = re.compile(r"^[-+]?(\.[0-9]+|[0-9]+(\.[0-9]*)?)([eE][-+]?[0-9]+)?$")


def _numbers_yaml11_missed(raw: dict) -> dict:
    """``raw`` with number-looking strings turned into numbers where the schema expects one."""
    raw = copy.deepcopy(raw)
    for err in _validator().iter_errors(raw):
        expected = err.validator_value if err.validator == "type" else None
        expected = [expected] if isinstance(expected, str) else expected or []
        if "number" not in expected or not isinstance(err.instance, str) or not _YAML12_FLOAT.match(err.instance):
            continue
        *parents, key = err.absolute_path
        node = raw
        for k in parents:
            node = node[k]
        node[key] = float(err.instance)
    return raw


def _nonfinite(node, path: str = ""):
    """(dotted path, value) of the first NaN or infinite number in ``node`` (None: there is none)."""
    if isinstance(node, float) and not math.isfinite(node):
        return path or "(top level)", node
    items = node.items() if isinstance(node, dict) else enumerate(node) if isinstance(node, list) else ()
    for key, value in items:
        where = _nonfinite(value, f"{path}.{key}" if path else str(key))
        if where:
            return where
    return None


def validate(raw: dict, source: str = "params.yaml") -> None:
    """Raise ConfigError naming the first offending key (wrong key, type or range, or a number
    that is NaN or infinite: YAML's .nan and .inf pass every JSON-schema bound, as each comparison
    with NaN is false, so they are refused here, for every parameter)."""
    bad = _nonfinite(raw)
    if bad:
        raise ConfigError(f"{source}: invalid parameter at '{bad[0]}': {bad[1]} is not a finite number")
    errors = sorted(_validator().iter_errors(raw), key=lambda e: (len(e.absolute_path), str(e.absolute_path)))
    if errors:
        raise ConfigError(_format_error(errors[0], source))


Check = Callable[[dict, str], None]


def resolve(raw: dict, source: str = "params.yaml", overrides: dict | None = None,
            checks: Iterable[Check] = ()) -> dict[str, Any]:
    """Validate ``raw`` (params.yaml plus overrides) and return it with its scale applied.

    Keys given in ``overrides`` are applied again after the scale's overlay, so a value asked for
    explicitly wins over the scale's. Each of ``checks`` (a study's ``check(p, source)``) then sees
    the resolved values and raises ConfigError on a disagreement between keys.
    """
    if not isinstance(raw, dict):
        raise ConfigError(f"{source}: expected a mapping of parameter groups, got {type(raw).__name__}")
    raw = _numbers_yaml11_missed(raw)
    overrides = _numbers_yaml11_missed(overrides) if overrides else overrides
    validate(raw, source)
    scale = raw["scale"]
    if scale not in raw["scales"]:
        raise ConfigError(f"{source}: unknown scale '{scale}' (choose one of {sorted(raw['scales'])})")
    resolved = deep_merge({k: v for k, v in raw.items() if k != "scales"}, raw["scales"][scale])
    resolved = deep_merge(resolved, {k: v for k, v in (overrides or {}).items() if k != "scales"})
    validate({**resolved, "scales": raw["scales"]}, f"{source} (scale '{scale}')")
    for key in ("volume_sessions", "tool_sessions"):
        resolved[key] = [s.replace("{scale}", scale) for s in resolved[key]]
    resolved["drift_session"] = resolved["drift_session"].replace("{scale}", scale)
    resolved["build"] = resolved["build"].replace("{scale}", scale)
    for check in checks:
        check(resolved, source)
    if resolved["tool_train"]["variants"] == "all":
        # every defined variant in the file's order, spelled out: a stamp's values are written with
        # sorted keys, and a stage reading "all" from one would see them alphabetically
        resolved["tool_train"]["variants"] = list(resolved["tool_variants"])
    return resolved


def load_params(path: str | Path = DEFAULT_PARAMS, overrides: dict | None = None,
                checks: Iterable[Check] = ()) -> dict[str, Any]:
    """Read params.yaml, apply ``overrides`` (e.g. {"scale": "smoke"}), validate, resolve and run
    ``checks`` (see `resolve`)."""
    path = Path(path)
    try:
        raw = load_yaml_text(path.read_text(), str(path))
    except FileNotFoundError:
        raise ConfigError(f"{path}: parameter file not found") from None
    except UnicodeDecodeError as exc:
        raise ConfigError(f"{path}: not UTF-8 text (byte 0x{exc.object[exc.start]:02x} at offset {exc.start})") from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        raise ConfigError(f"{path}: not valid YAML{where}: {problem}") from None
    if overrides:
        raw = deep_merge(raw or {}, overrides)
    return resolve(raw, str(path), overrides, checks)


class DeclaredParams(dict):
    """A stage's parameters: only the keys it declared. Reading another key is an error naming
    the stage and the key, so a stage cannot depend on a parameter the workflow does not track."""

    where: str = "stage"

    def __missing__(self, key):
        raise ConfigError(f"{self.where}: reads parameter '{key}', which the stage does not declare "
                          f"(add it to the params= of the stage's @command declaration in tactilepipe.cli)")

    def get(self, key, default=None):
        """As ``self[key]``: an undeclared key is an error, never a silent second default."""
        return self[key]


def declared(resolved: dict, keys, where: str) -> DeclaredParams:
    """``resolved`` cut down to the dotted ``keys`` ("tool_train.lr" keeps tool_train: {lr: ...})."""
    def wrap(value, path):
        if isinstance(value, dict) and not isinstance(value, DeclaredParams):
            out = DeclaredParams({k: wrap(v, f"{path}.{k}") for k, v in value.items()})
            out.where = where
            return out
        return copy.deepcopy(value)

    out = DeclaredParams()
    out.where = where
    for key in keys:
        node, parts = resolved, key.split(".")
        for i, part in enumerate(parts):
            if not isinstance(node, dict) or part not in node:
                raise ConfigError(f"{where}: declares parameter '{key}', which params.yaml does not have")
            node = node[part]
        target = out
        for part in parts[:-1]:
            if part not in target:
                target[part] = DeclaredParams()
                target[part].where = where
            target = dict.__getitem__(target, part)
        target[parts[-1]] = wrap(node, key)
    return out
