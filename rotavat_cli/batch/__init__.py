"""Whole datasets: find every sequence under a root and run calibrate/align/eval/render on each, in parallel.

:func:`run_batch` is what ``rotavat batch`` runs. It finds the sequences (:func:`discover_sequences`),
skips those already complete (:func:`completed_marker`), cuts the rest into tasks and hands them to
an executor: the inline one (``jobs=1``), a process pool on this machine, or an existing Dask
distributed cluster. Tasks are top-level functions of :mod:`.tasks` called with plain arguments
(paths, dicts), so they pickle, and every task reads and writes the shared file system itself.

Per sequence ``<rel>`` (its path under ROOT) the outputs go to ``OUT/<rel>/``::

    camera.yaml          calibrate (the camera align used; when the sequence has none, align calibrates)
    aligned/             align: the RotAvat sequence, its camera.yaml and people.csv
    eval/metrics.*       eval: the input and the aligned prediction against GT/<rel>, side by side
    render/              render: the figure of the chosen frames (input, aligned, ground truth rows)
    input/               --from FORMAT only: the converted contract sequence the steps read
    .rotavat-complete    JSON marker written last: steps, input fingerprints, option digests, timings, row

Modules, one concern each: :mod:`.discover` (which folders are sequences, input fingerprints),
:mod:`.plan` (options, the plan, completion markers), :mod:`.tasks` (the per-sequence tasks run in
workers), :mod:`.executors` (inline, process pool, Dask), :mod:`.driver` (:func:`run_batch`) and
:mod:`.report` (the dataset aggregate, batch_report.json/.md). Any error ends that sequence only,
with a one-line reason.
"""

from ..lazy import public_names

# Each public name and the module that defines it (imported on first use: rotavat_cli/lazy.py).
_PUBLIC = {
    "..errors": ("TaskError",),
    ".discover": ("discover_sequences", "fingerprint"),
    ".driver": ("Progress", "run_batch"),
    ".plan": ("MARKER", "STEPS", "BatchOptions", "completed_marker", "parse_steps"),
    ".report": (
        "REPORT_JSON", "REPORT_MD", "BatchReport", "aggregate_rows", "markdown_batch_report", "write_batch_report"
    ),
}
__getattr__, __dir__, __all__ = public_names(__name__, _PUBLIC)
