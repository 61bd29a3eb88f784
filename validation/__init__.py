"""Validation layer (DESIGN.md "Layers"): benchmarks (``validation.bench``, ``stridelab bench ...``), the
simulators (``validation.simulator``), the simulated-study writer (``validation.simulate``) and the provenance
of tuned constants (``validation/provenance.toml``). It may import every layer below it; nothing below imports it.
"""
