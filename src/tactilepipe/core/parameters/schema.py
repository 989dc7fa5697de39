"""The JSON schema of params.yaml, generated from the models: what `tactilepipe.core.config`
validates with (written by `make schema` to the package's params.schema.json)."""

from __future__ import annotations

import json

from pydantic.json_schema import GenerateJsonSchema

from tactilepipe.core.parameters.params_file import Params

TITLE = "tactilepipe params.yaml"
DIALECT = "https://json-schema.org/draft/2020-12/schema"


class ParamsJsonSchema(GenerateJsonSchema):
    """pydantic's JSON schema with only what validates or explains a value: no generated titles, no
    defaults (an overlay's key may be left out, never given as null), one-line descriptions, a
    name pattern as `propertyNames` and a nullable text as `"type": ["string", "null"]`."""

    def field_title_should_be_set(self, schema) -> bool:
        return False

    def default_schema(self, schema):
        return self.generate_inner(schema["schema"])

    def model_schema(self, schema):
        json_schema = super().model_schema(schema)
        json_schema.pop("title", None)
        if "description" in json_schema:                  # a docstring wrapped over lines
            json_schema["description"] = " ".join(json_schema["description"].split())
        return json_schema

    def dict_schema(self, schema):
        # pydantic writes a key pattern as patternProperties, which lets a key that does not match
        # through with any value; propertyNames refuses it
        json_schema = super().dict_schema(schema)
        patterns = json_schema.pop("patternProperties", None)
        if patterns:
            (pattern, values), = patterns.items()
            json_schema["propertyNames"] = {"pattern": pattern}
            json_schema["additionalProperties"] = values
        return json_schema

    def nullable_schema(self, schema):
        inner = self.generate_inner(schema["schema"])
        if set(inner) == {"type"} and isinstance(inner["type"], str):
            return {"type": [inner["type"], "null"]}
        return super().nullable_schema(schema)


def params_schema() -> dict:
    """The schema of params.yaml: the root first, the shared definitions last."""
    generated = Params.model_json_schema(schema_generator=ParamsJsonSchema)
    definitions = generated.pop("$defs")
    return {"$schema": DIALECT, "title": TITLE, **generated, "$defs": definitions}


def params_schema_text() -> str:
    """``params_schema()`` as the committed file holds it: indented by 2, and a mapping or list of
    plain values (a key's constraints, an enum) on one line when that is at most 100 characters."""
    return _json(params_schema(), 0) + "\n"


def _plain(value) -> bool:
    """A value with no mapping in it and at most a list of plain values."""
    if isinstance(value, list):
        return not any(isinstance(v, (dict, list)) for v in value)
    return not isinstance(value, dict)


def _json(value, depth: int) -> str:
    flat = json.dumps(value, ensure_ascii=False)
    if not isinstance(value, (dict, list)) or not value:
        return flat
    children = value.values() if isinstance(value, dict) else value
    if all(_plain(v) for v in children) and len(flat) <= 100:
        return flat
    if isinstance(value, dict):
        items, opening, closing = [f"{json.dumps(k)}: {_json(v, depth + 1)}" for k, v in value.items()], "{", "}"
    else:
        items, opening, closing = [_json(v, depth + 1) for v in value], "[", "]"
    inner = "  " * (depth + 1)
    return opening + "\n" + ",\n".join(inner + item for item in items) + "\n" + "  " * depth + closing
