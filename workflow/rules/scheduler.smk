# Snakemake's scheduler arms a plain timer on every pass, to look at the ready jobs again after the
# profile's max-jobs-per-timespan; the process then waits for the last timer before it exits (a
# minute of nothing after every run at 1000/60s, ten at the profile's 10000/10m). As daemon
# threads they end with the run, so the timespan can be long and the scheduler quiet
# (docs/decisions/0028; benchmarks/bench_scheduler.py measures both sides).
import threading


class _DaemonTimer(threading.Timer):
    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.daemon = True


threading.Timer = _DaemonTimer
