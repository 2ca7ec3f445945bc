"""The benches: one module per measurement, each run from the repository root as
``python -m bench.NAME``; ``bench.common`` holds what they share (report paths,
provenance, chart style, child processes)."""
