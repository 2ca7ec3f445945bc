"""The benches: one module per measurement, grouped by the capability it measures (``addon``,
``material``, ``neural``, ``farm``, ``generator``; each group's design note cites its reports),
each run from the repository root as ``python -m bench.GROUP.NAME``; ``bench.common`` holds what
they share (report paths, provenance, chart style, child processes)."""
