"""The whole of params.yaml: its parameter groups, the top-level values, and the scale overlays."""

from typing import Annotated, Literal

from pydantic import Field

from tactilepipe.core.parameters.base import BuildName, Group, RequiredKeys, SessionName, UniqueList, overlay_of
from tactilepipe.core.parameters.resources import Resources
from tactilepipe.core.parameters.tool import (Predict, PublicData, ToolIngest, ToolReport, ToolSplit, ToolSync, ToolTrain,
                                              ToolVariant, VariantName)
from tactilepipe.core.parameters.tool_sim import SimulateTool
from tactilepipe.core.parameters.volume import (Baseline, Drift, Folds, Mlp, PapillarrayAxes, PapillarrayIngest,
                                                Segment, SimulateDrift, SimulateVolume, VolumeChecks, VolumeRegimes)


class ParameterGroups(Group):
    """The groups of params.yaml, one per stage or rig: what a scale may overlay."""

    simulate_volume: SimulateVolume
    simulate_drift: SimulateDrift
    segment: Segment
    volume_checks: VolumeChecks
    papillarray_ingest: PapillarrayIngest
    folds: Folds
    mlp: Mlp
    baseline: Baseline
    drift: Drift
    papillarray_axes: PapillarrayAxes
    tool_ingest: ToolIngest
    tool_sync: ToolSync
    tool_split: ToolSplit
    simulate_tool: SimulateTool
    tool_train: ToolTrain
    tool_report: ToolReport
    predict: Predict
    resources: Resources
    volume_regimes: VolumeRegimes
    public_data: PublicData


# what each of `scales:` may give: any part of any group (config.resolve merges it over the groups)
ScaleOverlay = overlay_of(ParameterGroups)


class Params(ParameterGroups):
    """Parameters grouped by stage. `scales.<name>` holds partial overlays of the groups."""

    scenes: UniqueList[Literal["volume", "drift", "tool_normal", "tool_shear"]] = Field(min_length=1)
    scale: str
    build: BuildName = Field("{scale}", description="the build's folder under results/ (results/<build>/): \"{scale}\" in it "
                                         "is replaced by the scale, so each scale keeps its own results")
    seed: int = Field(ge=0, le=2**32 - 1, description="below 2**32: numpy's and torch's generators take it, "
                                                      "with room for the per-repeat and per-epoch offsets")
    volume_sessions: UniqueList[SessionName] = Field(min_length=1)
    volume_sensor: Literal[0, 1]
    drift_session: SessionName
    tool_sessions: UniqueList[SessionName] = Field(min_length=1)
    # the same at every scale (a scale chooses among them with tool_train.variants)
    tool_variants: dict[VariantName, ToolVariant] = Field(
        min_length=1, description="the model variants, by name, in the order figures and tables list them; full is the "
                                  "published model (the leave-one-tool-out, sweep and study-000 runs train it)")
    scales: Annotated[dict[str, ScaleOverlay], RequiredKeys("smoke", "default", "paper")]
