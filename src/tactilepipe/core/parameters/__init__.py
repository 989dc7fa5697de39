"""params.yaml as typed models (pydantic): one model per parameter group, with each key's type,
range and description. They are the source of the JSON schema that validates params.yaml
(`make schema` writes it to src/tactilepipe/core/params.schema.json; `tactilepipe.core.config`
validates with that file, so the workflow and most stages never import pydantic; the training stage
builds each run's configuration from `training.TrainingSettings`).

- `base`: `Group`, `overlay_of` (a group with every key optional: the scale overlays), shared types;
- `volume`, `tool`, `training`, `tool_sim`, `resources`: the groups, by study;
- `params_file`: the whole file (`Params`) and what a scale may overlay (`ScaleOverlay`);
- `schema`: the JSON schema generated from `Params`.

Nothing is imported here: a stage that imports one group's model (the training stage) does not
take the others into its code, whose edits would otherwise re-run it.
"""
