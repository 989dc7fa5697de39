"""What every parameter model is built from: `Group` (a mapping with exactly its declared keys),
`overlay_of` (the same keys, each optional, as `scales:` and resource rules give them), and the
JSON-schema keywords pydantic has no annotation for (`UniqueItems`, `RequiredKeys`)."""

from __future__ import annotations

from functools import cache
from typing import Annotated, Any, TypeVar

from pydantic import BaseModel, ConfigDict, Field, create_model

T = TypeVar("T")


class Group(BaseModel):
    """A mapping of named parameters: each key declared, any other refused. No number may be NaN
    or infinite (a NaN passes every bound, since each comparison with it is false); the JSON
    schema cannot say so, and config.validate refuses them before the schema is asked."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)


class UniqueItems:
    """A list whose items all differ (JSON schema `uniqueItems`)."""

    def __get_pydantic_json_schema__(self, core_schema, handler):
        json_schema = handler(core_schema)
        json_schema["uniqueItems"] = True
        return json_schema


class RequiredKeys:
    """A name-keyed mapping that must hold at least these names (JSON schema `required`)."""

    def __init__(self, *names: str):
        self.names = list(names)

    def __get_pydantic_json_schema__(self, core_schema, handler):
        json_schema = handler(core_schema)
        json_schema["required"] = self.names
        return json_schema


UniqueList = Annotated[list[T], UniqueItems()]
Pair = Annotated[list[T], Field(min_length=2, max_length=2)]      # a low-high range, or one per sensor
Triple = Annotated[list[T], Field(min_length=3, max_length=3)]    # one per axis or channel
# A session folder's name; "{scale}" in it is replaced by the scale. One plain name under
# raw/<study>/: never "." or ".." (nor any name of dots only) or a path, which would read
# recordings from outside the study's folder.
SessionName = Annotated[str, Field(pattern=r"^[A-Za-z0-9_.{}-]*[A-Za-z0-9_{}-][A-Za-z0-9_.{}-]*$",
                                   description="a plain folder name under raw/<study>/: letters, digits, '-', '_', "
                                               "'.' (not only dots), no '/'")]
# A build's folder name under results/; "{scale}" in it is replaced by the scale. No dots: a build
# is one folder, never "." or ".." or a path.
BuildName = Annotated[str, Field(pattern=r"^([A-Za-z0-9_-]|\{scale\})+$")]


_OVERLAYS: set[type[Group]] = set()


def _is_group(annotation: Any) -> bool:
    return isinstance(annotation, type) and issubclass(annotation, Group)


@cache
def overlay_of(group: type[Group]) -> type[Group]:
    """``group`` with every key optional, and each nested group (a key whose value is a `Group`)
    an overlay in turn; unknown keys stay refused, and a key given must be valid (never null).

    Items of a list and values of a name-keyed mapping stay whole: the merge (`deep_merge`)
    replaces a list outright, and a mapping's entry may name a new item (a tool, a public file)
    that nothing else completes. An overlay of an overlay is the overlay itself."""
    if group in _OVERLAYS:
        return group
    fields = {}
    for name, field in group.model_fields.items():
        # a key keeps its type with its constraints (rebuild_annotation) and its description
        value = overlay_of(field.annotation) if _is_group(field.annotation) else field.rebuild_annotation()
        fields[name] = (value, Field(default=None, description=field.description))
    overlay = create_model(f"{group.__name__}Overlay", __base__=Group, __doc__=group.__doc__,
                           __module__=group.__module__, **fields)
    _OVERLAYS.add(overlay)
    return overlay
