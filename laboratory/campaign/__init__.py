"""Monte Carlo campaigns: many laboratory runs over seeds and configuration sweeps, on Dask.

``station campaign SPEC.toml``: the spec (``spec.py``) names a command and its sweeps; each
task (``task.py``) runs that command on a virtual station seeded from the campaign seed and
its index, and returns one row per constant; ``store.py`` keeps each task's rows as Parquet
as it completes (so a campaign resumes), ``run.py`` runs the tasks on a Dask cluster (an
embedded LocalCluster or an existing scheduler) or in process, ``summary.py`` sets each
constant's observed rms error against its predicted sigma. See docs/campaigns.md.
"""
