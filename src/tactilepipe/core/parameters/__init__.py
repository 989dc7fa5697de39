"""params.yaml as typed models (pydantic): one model per parameter group, with each key's type,
range and description. They are the source of the JSON schema that validates params.yaml
(`make schema` writes it to src/tactilepipe/core/params.schema.json; `tactilepipe.core.config`
validates with that file, so a stage never imports pydantic).

- `base`: `Group`, `overlay_of` (a group with every key optional: the scale overlays), shared types;
- `volume`, `tool`, `tool_sim`, `resources`: the groups, by study;
- `params_file`: the whole file (`Params`) and what a scale may overlay (`ScaleOverlay`);
- `schema`: the JSON schema generated from `Params`.
"""

from tactilepipe.core.parameters.params_file import Params, ScaleOverlay

__all__ = ["Params", "ScaleOverlay"]
