# DVC's record of what a run built (pipeline/dvc_state.py): the stages a successful run made current
# go into dvc.lock and DVC's cache, as `dvc commit` would. Not for a dry run, a touch run or a job of
# a cluster run. A run that finds nothing to do runs no hook (onsuccess): Snakemake's own message
# says so, and at exit the lock is rewritten only where it is older than what it records.
import atexit
import logging

from snakemake.common import NOTHING_TO_BE_DONE_MSG


def record_for_dvc(only_if_stale=False):
    if not (workflow.dryrun or workflow.touch) and workflow.is_main_process:
        dvc_state.after_run(str(P["scale"]), workflow.dag.jobs, workflow.is_rule, workflow.get_rule, OVERRIDES,
                            only_if_stale)


class _NothingToDo(logging.Handler):
    seen = False

    def emit(self, record):
        _NothingToDo.seen |= record.getMessage() == NOTHING_TO_BE_DONE_MSG


logging.getLogger("snakemake.logging").addHandler(_NothingToDo())
atexit.register(lambda: record_for_dvc(only_if_stale=True) if _NothingToDo.seen else None)
