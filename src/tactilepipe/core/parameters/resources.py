"""`resources`: what each rule asks a cluster scheduler for (workflow/profiles/slurm)."""

from pydantic import Field, PositiveFloat

from tactilepipe.core.parameters.base import Group, overlay_of


class JobResources(Group):
    """scheduler resources of one job: mem_mb (MB), runtime (minutes, the time limit), gpu (GPUs)"""

    mem_mb: int = Field(ge=1, le=2**24, description="at most 16 TiB, more than one node has")
    runtime: int = Field(ge=1, le=43200, description="at most 30 days, longer than any queue allows")
    gpu: int = Field(ge=0, le=64, description="at most 64, more than one node has")


class RuleResources(Group):
    """One entry per rule that runs something (a misspelt rule is refused)."""

    volume_simulate: JobResources
    drift_simulate: JobResources
    tool_simulate: JobResources
    papillarray_ingest: JobResources
    tool_ingest: JobResources
    volume_dataset: JobResources
    volume_split: JobResources
    volume_train: JobResources
    volume_gridsearch: JobResources
    volume_baseline: JobResources
    volume_report: JobResources
    drift_report: JobResources
    tool_dataset: JobResources
    tool_split: JobResources
    tool_data_report: JobResources
    tool_train: JobResources
    tool_model_report: JobResources
    volume_regimes: JobResources
    tool_clock_figure: JobResources
    study000_protocols: JobResources
    study000_evaluate_published: JobResources
    study000_published: JobResources


class CostModel(Group):
    """The compute estimate a dry run prints (pipeline/estimate.py)."""

    cpu_gflops_per_core: PositiveFloat
    gpu_tflops: PositiveFloat


class Resources(Group):
    """What each rule asks a cluster scheduler for; a local run schedules by --cores only."""

    default: JobResources
    # a rule takes `default` overlaid by its entry here, so an entry gives any of its keys
    rules: overlay_of(RuleResources)
    cost_model: CostModel
