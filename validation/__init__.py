"""Validation layer (DESIGN.md "Layers"): benchmarks (``stridelab.validation.bench``, ``stridelab bench ...``), the
simulators (``stridelab.validation.simulator``), the simulated-study writer (``stridelab.validation.simulate``) and the provenance
of tuned constants (``validation/provenance.toml``). It may import every layer below it; nothing below imports it.
"""
